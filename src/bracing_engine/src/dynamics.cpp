// The model of docs/model.md on pinocchio: every pinocchio call of the engine is in this file.
//
//   Mc ddq - W^T f_n = drive - (h + g) - Dc dq,   W = J_c - mu J_t
//   J_c ddq = -gamma - 2 a J_c dq - a^2 C
//
// solved through the Schur complement of the held contacts: Y = Mc^-1 J_c^T,
// (Y^T W^T) f_n = b - Y^T r, Mc ddq = r + W^T f_n, with Mc factorised by pinocchio's cholesky.
#include "bracing_engine/engine.hpp"
#include "model.hpp"

#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <Eigen/Dense>
#include <Eigen/SVD>

#include <cmath>
#include <iomanip>
#include <sstream>

namespace bracing_engine {

namespace pin = pinocchio;

void Surface::evaluate(const Vector3& r, double& c, Vector3& n, Matrix3& h) const {
  if (kind == SurfaceKind::plane) {
    c = normal.dot(r) - offset;
    n = normal;
    h.setZero();
    return;
  }
  // A sphere (projector I) or a cylinder (I - a a^T): with d the distance to the centre (axis),
  // n = offset / d and H = (projector - n n^T) / d; inside, all three change sign.
  Matrix3 projector = Matrix3::Identity();
  if (kind == SurfaceKind::cylinder) projector -= axis * axis.transpose();
  const Vector3 away = projector * (r - center);
  const double distance = away.norm();
  if (distance < 1e-12)
    throw std::domain_error("a contact point is at the centre of its sphere or on the axis of its cylinder");
  n = away / distance;
  h = (projector - n * n.transpose()) / distance;
  c = distance - radius;
  if (inside) {
    c = -c;
    n = -n;
    h = -h;
  }
}

struct Dynamics::Impl {
  pin::Model model;
  mutable pin::Data data;
  Drive drive;
  std::vector<Contact> contacts;
  std::vector<pin::FrameIndex> frames;
  double eps2;
  // work, reused between calls (the engine is single-threaded per object)
  mutable pin::Data::Matrix6x frame_jacobian;
  mutable Vector r, y_column;
  // the held contacts' rows Mc^-1 J_c,j^T and W_j, and the p x p system (kept: no allocation per call
  // while the set of held contacts stays the same size)
  mutable RowMatrix y, w;
  mutable Eigen::MatrixXd schur;
  mutable Vector bias, normal_velocity, rhs, force;
  mutable std::vector<int> index;
  mutable Eigen::PartialPivLU<Eigen::MatrixXd> lu;
  mutable RowMatrix accelerations, tangents, slide_e;  // p x 3, p x 6 (the sticking rows' t), p x 3
  mutable std::vector<int> tangent_count;               // per contact: its sticking rows

  // One contact's terms after computeAllTerms, into row j of `out`.
  void contact_terms(int j, const Eigen::Ref<const Vector>& dq, Answer& out) const {
    const auto frame = frames[j];
    frame_jacobian.setZero();
    pin::getFrameJacobian(model, data, frame, pin::LOCAL_WORLD_ALIGNED, frame_jacobian);
    const auto jacobian = frame_jacobian.topRows<3>();
    const Vector3 acceleration = pin::getFrameClassicalAcceleration(model, data, frame, pin::LOCAL_WORLD_ALIGNED).linear();
    accelerations.row(j) = acceleration.transpose();
    const Vector3 position = pin::updateFramePlacement(model, data, frame).translation();
    double c;
    Vector3 normal;
    Matrix3 hessian;
    contacts[j].surface.evaluate(position, c, normal, hessian);
    const Vector3 velocity = jacobian * dq;
    double gamma = normal.dot(acceleration);
    if (contacts[j].surface.kind != SurfaceKind::plane) gamma += velocity.dot(hessian * velocity);
    const Vector3 slip = velocity - normal * normal.dot(velocity);
    const Vector3 direction = slip / std::sqrt(slip.squaredNorm() + eps2);
    out.positions.row(j) = position.transpose();
    out.jacobians.middleRows<3>(3 * j) = jacobian;
    out.normal_jacobian.row(j).noalias() = normal.transpose() * jacobian;
    out.tangent_jacobian.row(j).noalias() = direction.transpose() * jacobian;
    out.slip.row(j) = slip.transpose();
    out.direction.row(j) = direction.transpose();
    out.normals.row(j) = normal.transpose();
    out.drift[j] = gamma;
    out.residual[j] = c;
  }

  void resize(Answer& out) const {
    const int n = model.nv, p = static_cast<int>(contacts.size());
    if (out.ddq.size() == n && out.force.size() == p) return;
    out.ddq.setZero(n);
    out.di.setZero(n);
    out.effort.setZero(n);
    out.force.setZero(p);
    out.positions.setZero(p, 3);
    out.jacobians.setZero(3 * p, n);
    out.normal_jacobian.setZero(p, n);
    out.tangent_jacobian.setZero(p, n);
    out.slip.setZero(p, 3);
    out.direction.setZero(p, 3);
    out.normals.setZero(p, 3);
    out.drift.setZero(p);
    out.residual.setZero(p);
    out.tangential_force.setZero(p, 3);
    out.friction.setZero(p);
  }
};

pin::Model build_model(const Robot& robot, const Vector& armature) {
  pin::Model full;
  pin::urdf::buildModel(robot.urdf_path, full);
  full.gravity.linear(robot.gravity);
  pin::Model model;
  if (robot.locked_joints.empty()) {
    model = full;
  } else {
    Eigen::VectorXd reference = pin::neutral(full);
    std::vector<pin::JointIndex> locked;
    for (std::size_t k = 0; k < robot.locked_joints.size(); ++k) {
      const auto& name = robot.locked_joints[k];
      if (!full.existJointName(name)) throw std::invalid_argument("robot.locked_joints: no joint " + name);
      const auto joint = full.getJointId(name);
      reference[full.idx_qs[joint]] = k < robot.locked_positions.size() ? robot.locked_positions[k] : 0.0;
      locked.push_back(joint);
    }
    model = pin::buildReducedModel(full, locked, reference);
  }
  if (model.nq != model.nv) throw std::invalid_argument("only 1-dof revolute/prismatic joints are supported");
  if (armature.size() != model.nv) throw std::invalid_argument("drive: one value per joint expected");
  model.armature += armature;
  if (robot.mass_scale != 1.0) {
    for (auto& inertia : model.inertias) {
      pin::Inertia::Symmetric3 rotational = inertia.inertia();
      rotational.data() *= robot.mass_scale;
      inertia = pin::Inertia(robot.mass_scale * inertia.mass(), inertia.lever(), rotational);
    }
  }
  return model;
}

Dynamics::Dynamics(const Robot& robot, const Drive& drive, std::vector<Contact> contacts, double slip_epsilon,
                   double baumgarte_gain)
    : baumgarte(baumgarte_gain), impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.model = build_model(robot, drive.added_inertia);
  m.data = pin::Data(m.model);
  m.drive = drive;
  const int n = m.model.nv;
  for (const Vector* v : {&drive.damping, &drive.torque_constant, &drive.resistance, &drive.inductance,
                          &drive.reflected_damping})
    if (v->size() != n) throw std::invalid_argument("drive: one value per joint expected");
  if (drive.thermal && (drive.thermal_resistance.size() != n || drive.heat_capacity.size() != n))
    throw std::invalid_argument("drive: one thermal resistance and heat capacity per joint expected");
  for (const auto& contact : contacts) {
    if (!m.model.existFrame(contact.frame)) throw std::invalid_argument("unknown frame " + contact.frame);
    m.frames.push_back(m.model.getFrameId(contact.frame));
  }
  m.contacts = std::move(contacts);
  m.eps2 = slip_epsilon * slip_epsilon;
  m.frame_jacobian.setZero(6, n);
  m.accelerations.setZero(m.contacts.size(), 3);
  m.tangents.setZero(m.contacts.size(), 6);
  m.slide_e.setZero(m.contacts.size(), 3);
  m.tangent_count.assign(m.contacts.size(), 0);
  m.r.setZero(n);
  m.y_column.setZero(n);
}

Dynamics::~Dynamics() = default;

int Dynamics::nv() const { return impl_->model.nv; }
int Dynamics::contact_count() const { return static_cast<int>(impl_->contacts.size()); }
const std::vector<Contact>& Dynamics::contacts() const { return impl_->contacts; }
const Drive& Dynamics::drive() const { return impl_->drive; }
std::string compiled_pinocchio_version() { return PINOCCHIO_VERSION; }

std::vector<std::string> Dynamics::joint_names() const {
  const auto& names = impl_->model.names;
  return std::vector<std::string>(names.begin() + 1, names.end());
}

void Dynamics::terms(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& dq, Answer& out) const {
  const Impl& m = *impl_;
  m.resize(out);
  pin::computeAllTerms(m.model, m.data, q, dq);
  for (int j = 0; j < contact_count(); ++j) m.contact_terms(j, dq, out);
}

int Dynamics::tangent_directions(const Vector3& n, const Eigen::Ref<const RowMatrix>& jacobian, Vector3 out[2]) {
  // A basis of the tangent plane (from the world axis least aligned with n), turned to the principal
  // directions of the frame's tangential mobility independent of its normal one (joint motions that
  // do not also move it off the surface); the directions without such mobility are dropped: the
  // joints cannot slide the frame along them (a planar arm's contact out of its plane; an elbow whose
  // two links are aligned), and their rows would make the constraints dependent.
  Eigen::Index axis;
  n.cwiseAbs().minCoeff(&axis);
  const Vector3 t1 = Vector3::Unit(axis).cross(n).normalized(), t2 = n.cross(t1);
  const Eigen::RowVectorXd normal_row = n.transpose() * jacobian;
  const double normal2 = normal_row.squaredNorm();
  Eigen::Matrix<double, 2, Eigen::Dynamic> rows(2, jacobian.cols());
  rows.row(0).noalias() = t1.transpose() * jacobian;
  rows.row(1).noalias() = t2.transpose() * jacobian;
  if (normal2 > 0.0)
    for (int k = 0; k < 2; ++k) rows.row(k) -= (rows.row(k).dot(normal_row) / normal2) * normal_row;
  const Eigen::JacobiSVD<Eigen::Matrix<double, 2, Eigen::Dynamic>> svd(rows, Eigen::ComputeFullU);
  const auto& sigma = svd.singularValues();
  const double scale = std::max(jacobian.norm(), 1e-300);
  int count = 0;
  for (int k = 0; k < 2; ++k)
    if (sigma[k] > 1e-6 * scale) out[count++] = svd.matrixU()(0, k) * t1 + svd.matrixU()(1, k) * t2;
  return count;
}

void Dynamics::evaluate(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& dq,
                        const Eigen::Ref<const Vector>& current, const Eigen::Ref<const Vector>& temperature,
                        const Eigen::Ref<const Vector>& u, const ContactModes& modes, bool full, Answer& out) const {
  const Impl& m = *impl_;
  const Drive& d = m.drive;
  const int n = m.model.nv, p = contact_count();
  m.resize(out);
  pin::computeAllTerms(m.model, m.data, q, dq);
  pin::cholesky::decompose(m.model, m.data);
  // r = drive - Dc dq - (h + g)
  if (d.voltage)
    m.r.noalias() = d.torque_constant.cwiseProduct(current) - d.damping.cwiseProduct(dq) - m.data.nle;
  else
    m.r.noalias() = u - d.damping.cwiseProduct(dq) - m.data.nle;
  // The constraint rows: per held contact its normal row, per sticking one its tangential rows.
  int rows = 0;
  for (int j = 0; j < p; ++j) {
    if (modes.held[j] || full) m.contact_terms(j, dq, out);
    if (!modes.held[j]) continue;
    rows += 1;
    if (modes.sticking[j]) {
      Vector3 t[2];
      const int count = tangent_directions(out.normals.row(j).transpose(), out.jacobians.middleRows<3>(3 * j), t);
      m.tangent_count[j] = count;
      for (int k = 0; k < count; ++k) m.tangents.row(j).segment<3>(3 * k) = t[k].transpose();
      rows += count;
    }
  }
  out.force.setZero();
  out.tangential_force.setZero();
  out.friction.setZero();
  out.friction_power = out.constraint_power = 0.0;
  Vector& ddq = out.ddq;
  ddq = m.r;
  if (rows) {
    // Row i: constraint R_i ddq = bias_i, its force acting through W_i (Mc ddq = r + W^T lambda).
    // A normal row's W carries the sliding friction: W = J_c - mu e^T J (Coulomb: e the unit slide
    // direction; regularised: s / sqrt(|s|^2 + eps^2)); a sticking contact's friction is its two
    // tangential rows' force instead.
    m.y.resize(rows, n);
    m.w.resize(rows, n);
    m.bias.resize(rows);
    m.normal_velocity.resize(rows);
    std::vector<int>& index = m.index;  // the contact of each row
    index.clear();
    for (int j = 0; j < p; ++j) {
      if (!modes.held[j]) continue;
      const Contact& contact = m.contacts[j];
      const auto jacobian = out.jacobians.middleRows<3>(3 * j);
      const int i = static_cast<int>(index.size());
      index.push_back(j);
      auto row = out.normal_jacobian.row(j);
      m.w.row(i) = row;
      const double mu = contact.friction;
      if (!modes.sticking[j] && mu != 0.0) {
        Vector3 e;
        if (!contact.coulomb) {
          e = out.direction.row(j).transpose();
        } else {
          // e = sign(f_n) d: |f_t| = mu |f_n| against the slip direction d, the live one while the slip
          // has not turned past a right angle from the held d (the interval's start): so past a
          // reversal (an event, located) the dynamics continue smoothly, with d held
          const Vector3 slip = out.slip.row(j).transpose(), held = modes.slide.row(j).transpose();
          const double speed = slip.norm();
          e = modes.pushing[j] * (speed > kSlipAtRest && slip.dot(held) > 0.0 ? Vector3(slip / speed) : held);
        }
        m.w.row(i).noalias() -= mu * (e.transpose() * jacobian);
        m.slide_e.row(j) = e.transpose();
      }
      m.normal_velocity[i] = row.dot(dq);
      m.bias[i] = -out.drift[j] - 2.0 * baumgarte * m.normal_velocity[i] - baumgarte * baumgarte * out.residual[j];
      m.y_column = row.transpose();
      pin::cholesky::solve(m.model, m.data, m.y_column);
      m.y.row(i) = m.y_column.transpose();
    }
    for (int j = 0; j < p; ++j) {
      if (!modes.held[j] || !modes.sticking[j]) continue;
      const auto jacobian = out.jacobians.middleRows<3>(3 * j);
      const Vector3 acceleration = m.accelerations.row(j).transpose();
      for (int k = 0; k < m.tangent_count[j]; ++k) {
        const Vector3 tangent = m.tangents.row(j).segment<3>(3 * k).transpose();
        const int i = static_cast<int>(index.size());
        index.push_back(j);
        m.w.row(i).noalias() = tangent.transpose() * jacobian;
        m.normal_velocity[i] = m.w.row(i).dot(dq);
        m.bias[i] = -tangent.dot(acceleration) - 2.0 * baumgarte * m.normal_velocity[i];
        m.y_column = m.w.row(i).transpose();
        pin::cholesky::solve(m.model, m.data, m.y_column);
        m.y.row(i) = m.y_column.transpose();
      }
    }
    m.schur.noalias() = m.y * m.w.transpose();  // R Mc^-1 W^T (R: the constraint rows)
    m.rhs = m.bias;
    m.rhs.noalias() -= m.y * m.r;
    m.lu.compute(m.schur);
    m.force.resize(rows);
    const auto pivots = m.lu.matrixLU().diagonal().cwiseAbs();
    if (pivots.minCoeff() > 1e-12 * pivots.maxCoeff()) {
      m.force = m.lu.solve(m.rhs);
    } else {
      // Dependent rows (e.g. two sticking contacts the joints cannot move apart): the forces are not
      // determined; the least-norm ones that satisfy the constraints, if any do.
      m.force = m.schur.completeOrthogonalDecomposition().solve(m.rhs);
      if (!m.force.allFinite() || (m.schur * m.force - m.rhs).norm() > 1e-9 * std::max(1.0, m.rhs.norm()))
        throw SingularError("Singular matrix: the contact constraints do not determine the forces");
    }
    const Vector& lambda = m.force;
    ddq.noalias() += m.w.transpose() * lambda;
    // forces, friction and powers per contact (the normal rows come first, in contact order)
    int i = 0;
    for (int j = 0; j < p; ++j) {
      if (!modes.held[j]) continue;
      const Contact& contact = m.contacts[j];
      const double f = lambda[i];
      out.force[j] = f;
      out.constraint_power += f * m.normal_velocity[i];
      ++i;
      if (modes.sticking[j] || contact.friction == 0.0) continue;
      const Vector3 slip = out.slip.row(j).transpose();
      if (contact.coulomb) {  // -mu f_n e = -mu |f_n| d (with the sign held; see the simulator's start check)
        const Vector3 e = m.slide_e.row(j).transpose();
        out.tangential_force.row(j) = (-contact.friction * f * e).transpose();
        out.friction[j] = contact.friction * f * modes.pushing[j];
        out.friction_power += contact.friction * f * e.dot(slip);
      } else {
        const double slip2 = slip.squaredNorm();
        out.tangential_force.row(j) = (-contact.friction * f * out.direction.row(j)).eval();
        out.friction[j] = contact.friction * f;
        out.friction_power += contact.friction * f * slip2 / std::sqrt(slip2 + m.eps2);
      }
    }
    for (int j = 0; j < p; ++j) {  // the sticking contacts' tangential rows, in contact order
      if (!modes.held[j] || !modes.sticking[j]) continue;
      Vector3 force = Vector3::Zero();
      for (int k = 0; k < m.tangent_count[j]; ++k, ++i) {
        force += lambda[i] * m.tangents.row(j).segment<3>(3 * k).transpose();
        out.constraint_power += lambda[i] * m.normal_velocity[i];
      }
      out.tangential_force.row(j) = force.transpose();
      out.friction[j] = force.norm();
    }
  }
  pin::cholesky::solve(m.model, m.data, ddq);  // Mc^-1 (r + W^T lambda)
  if (d.voltage) {
    d.resistance_at(temperature, out.resistance);
    out.di.array() = (u - out.resistance.cwiseProduct(current) - d.torque_constant.cwiseProduct(dq)).array() /
                     d.inductance.array();
    out.effort.array() = d.torque_constant.cwiseProduct(current).array() -
                         d.reflected_damping.cwiseProduct(dq).array() - d.added_inertia.cwiseProduct(ddq).array();
  } else {
    out.di.setZero(n);
    out.resistance = d.resistance;
    out.effort = u;
  }
}

double Dynamics::hold_velocity(const Vector& q, Vector& dq, const ContactModes& modes) const {
  const Impl& m = *impl_;
  const int n = m.model.nv, p = contact_count();
  Answer answer;
  terms(q, dq, answer);
  pin::cholesky::decompose(m.model, m.data);
  std::vector<Vector> rows;
  for (int j = 0; j < p; ++j) {
    if (!modes.held[j]) continue;
    rows.push_back(answer.normal_jacobian.row(j).transpose());
    if (!modes.sticking[j]) continue;
    Vector3 t[2];
    const int count = tangent_directions(answer.normals.row(j).transpose(), answer.jacobians.middleRows<3>(3 * j), t);
    for (int k = 0; k < count; ++k) rows.push_back((t[k].transpose() * answer.jacobians.middleRows<3>(3 * j)).transpose());
  }
  const int k = static_cast<int>(rows.size());
  if (!k) return 0.0;
  Eigen::MatrixXd r(k, n), y(n, k);
  for (int i = 0; i < k; ++i) {
    r.row(i) = rows[i].transpose();
    m.y_column = rows[i];
    pin::cholesky::solve(m.model, m.data, m.y_column);
    y.col(i) = m.y_column;
  }
  const Vector velocity = r * dq;
  const Vector impulse = -(r * y).completeOrthogonalDecomposition().solve(velocity);
  dq += y * impulse;
  return -0.5 * velocity.dot(impulse);
}

Vector Dynamics::project(const Vector& q0, const std::vector<int>& rows, double tolerance) const {
  const Impl& m = *impl_;
  const int n = m.model.nv, k = static_cast<int>(rows.size());
  Vector q = q0;
  const Vector zero = Vector::Zero(n);
  Answer answer;
  Vector residual(k);
  for (int iteration = 0; iteration < 50; ++iteration) {
    terms(q, zero, answer);
    Eigen::MatrixXd jc(k, n);
    for (int i = 0; i < k; ++i) {
      residual[i] = answer.residual[rows[i]];
      jc.row(i) = answer.normal_jacobian.row(rows[i]);
    }
    if (k == 0 || residual.cwiseAbs().maxCoeff() < tolerance) return q;
    pin::cholesky::decompose(m.model, m.data);
    Eigen::MatrixXd y(n, k);  // Mc^-1 J_c^T
    for (int i = 0; i < k; ++i) {
      m.y_column = jc.row(i).transpose();
      pin::cholesky::solve(m.model, m.data, m.y_column);
      y.col(i) = m.y_column;
    }
    // the least-squares, least-norm step (as numpy's lstsq)
    q += y * (jc * y).completeOrthogonalDecomposition().solve(-residual);
  }
  std::ostringstream names;
  for (int i = 0; i < k; ++i)
    names << (i ? ", " : "") << m.contacts[rows[i]].name << " (" << std::showpos << std::setprecision(3)
          << residual[i] << std::noshowpos << " m)";
  throw std::domain_error("no posture near the given one holds every contact: after 50 steps " + names.str());
}

double Dynamics::impact(Vector& q, Vector& dq, const std::vector<int>& rows) const {
  const Impl& m = *impl_;
  const int n = m.model.nv, k = static_cast<int>(rows.size());
  q = project(q, rows);
  Answer answer;
  terms(q, dq, answer);
  pin::cholesky::decompose(m.model, m.data);
  Eigen::MatrixXd jc(k, n), y(n, k);
  for (int i = 0; i < k; ++i) {
    jc.row(i) = answer.normal_jacobian.row(rows[i]);
    m.y_column = jc.row(i).transpose();
    pin::cholesky::solve(m.model, m.data, m.y_column);
    y.col(i) = m.y_column;
  }
  const Vector normal_velocity = jc * dq;
  const Vector impulse = -(jc * y).partialPivLu().solve(normal_velocity);
  dq += y * impulse;
  return -0.5 * normal_velocity.dot(impulse);  // (J_c dq)^T (J_c Mc^-1 J_c^T)^-1 (J_c dq) / 2
}

}  // namespace bracing_engine
