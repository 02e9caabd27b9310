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

  // One contact's terms after computeAllTerms, into row j of `out`.
  void contact_terms(int j, const Eigen::Ref<const Vector>& dq, Answer& out) const {
    const auto frame = frames[j];
    frame_jacobian.setZero();
    pin::getFrameJacobian(model, data, frame, pin::LOCAL_WORLD_ALIGNED, frame_jacobian);
    const auto jacobian = frame_jacobian.topRows<3>();
    const Vector3 acceleration = pin::getFrameClassicalAcceleration(model, data, frame, pin::LOCAL_WORLD_ALIGNED).linear();
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
  for (const auto& contact : contacts) {
    if (!m.model.existFrame(contact.frame)) throw std::invalid_argument("unknown frame " + contact.frame);
    m.frames.push_back(m.model.getFrameId(contact.frame));
  }
  m.contacts = std::move(contacts);
  m.eps2 = slip_epsilon * slip_epsilon;
  m.frame_jacobian.setZero(6, n);
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

void Dynamics::evaluate(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& dq,
                        const Eigen::Ref<const Vector>& current, const Eigen::Ref<const Vector>& u, const Mask& held,
                        bool full, Answer& out) const {
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
  int k = 0;
  for (int j = 0; j < p; ++j) {
    if (held[j]) ++k;
    if (held[j] || full) m.contact_terms(j, dq, out);
  }
  out.force.setZero();
  out.friction_power = out.constraint_power = 0.0;
  Vector& ddq = out.ddq;
  ddq = m.r;
  if (k) {
    // Per held contact: Y_j = Mc^-1 J_c,j^T and W_j = J_c,j + scale_j slip_j^T J_j, scale_j = -mu / |slip|_eps.
    m.y.resize(k, n);
    m.w.resize(k, n);
    m.bias.resize(k);
    m.normal_velocity.resize(k);
    Vector& bias = m.bias;
    Vector& normal_velocity = m.normal_velocity;
    std::vector<int>& index = m.index;
    index.clear();
    for (int j = 0; j < p; ++j) {
      if (!held[j]) continue;
      const int i = static_cast<int>(index.size());
      index.push_back(j);
      m.y_column = out.normal_jacobian.row(j).transpose();
      pin::cholesky::solve(m.model, m.data, m.y_column);
      m.y.row(i) = m.y_column.transpose();
      const double slip2 = out.slip.row(j).squaredNorm();
      const double scale = -m.contacts[j].friction / std::sqrt(slip2 + m.eps2);
      m.w.row(i) = out.normal_jacobian.row(j);
      m.w.row(i).noalias() += scale * (out.slip.row(j) * out.jacobians.middleRows<3>(3 * j));
      normal_velocity[i] = out.normal_jacobian.row(j).dot(dq);
      bias[i] = -out.drift[j] - 2.0 * baumgarte * normal_velocity[i] - baumgarte * baumgarte * out.residual[j];
    }
    m.schur.noalias() = m.y * m.w.transpose();  // J_c Mc^-1 W^T
    m.rhs = bias;
    m.rhs.noalias() -= m.y * m.r;
    m.lu.compute(m.schur);
    if ((m.lu.matrixLU().diagonal().array() == 0.0).any())
      throw SingularError("Singular matrix: the contact constraints do not determine the forces");
    m.force.resize(k);
    m.force = m.lu.solve(m.rhs);
    const Vector& force = m.force;
    ddq.noalias() += m.w.transpose() * force;
    for (int i = 0; i < k; ++i) {
      const int j = index[i];
      out.force[j] = force[i];
      const double slip2 = out.slip.row(j).squaredNorm();
      out.friction_power += m.contacts[j].friction * force[i] * slip2 / std::sqrt(slip2 + m.eps2);
      out.constraint_power += force[i] * normal_velocity[i];
    }
  }
  pin::cholesky::solve(m.model, m.data, ddq);  // Mc^-1 (r + W^T f_n)
  if (d.voltage) {
    out.di.array() = (u - d.resistance.cwiseProduct(current) - d.torque_constant.cwiseProduct(dq)).array() /
                     d.inductance.array();
    out.effort.array() = d.torque_constant.cwiseProduct(current).array() -
                         d.reflected_damping.cwiseProduct(dq).array() - d.added_inertia.cwiseProduct(ddq).array();
  } else {
    out.di.setZero(n);
    out.effort = u;
  }
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
