// The model of docs/model.md on pinocchio: where the contact forces are solved.
//
//   Mc ddq - W^T f_n = drive - (h + g) - Dc dq,   W = J_c - mu J_t
//   J_c ddq = -gamma - 2 a J_c dq - a^2 C
//
// solved through the Schur complement of the held contacts: Y = Mc^-1 J_c^T,
// (Y^T W^T) f_n = b - Y^T r, Mc ddq = r + W^T f_n, with Mc factorised by pinocchio's cholesky.
#include "bracing_engine/engine.hpp"
#include "geometry.hpp"
#include "model.hpp"

#include <pinocchio/algorithm/kinematics.hpp>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <cmath>
#include <iomanip>
#include <sstream>

namespace bracing_engine {

namespace pin = pinocchio;

namespace {

// dq projected onto R dq = 0 by the impulse Mc^-1 R^T lambda, lambda = -(R Mc^-1 R^T)^+ R dq (least-norm where
// the rows are dependent; Mc factorised on `data`). Returns the kinetic energy lost, (R dq)^T (R Mc^-1 R^T)^+
// (R dq) / 2: a touchdown's inelastic impact (normal rows), a contact that starts to stick (its tangential rows).
double remove_velocity(const pin::Model& model, pin::Data& data, const Eigen::MatrixXd& r, Vector& column, Vector& dq) {
  Eigen::MatrixXd y(model.nv, r.rows());  // Mc^-1 R^T
  mass_inverse_rows(model, data, r, column, y.transpose());
  const Vector velocity = r * dq;
  const Vector impulse = -(r * y).completeOrthogonalDecomposition().solve(velocity);
  dq += y * impulse;
  return -0.5 * velocity.dot(impulse);
}

}  // namespace

struct Dynamics::Impl {
  mutable pin::Model model;  // mutable: the geometry contacts' frames move to their points at each evaluation
  LinkShapes shapes;         // the links' collision shapes (robot.collision_description)
  GeometryPoints points;     // the contacts with point: geometry
  mutable pin::Data data;
  Drive drive;
  std::vector<Contact> contacts;
  std::vector<pin::FrameIndex> frames;
  double eps2;
  // work, reused between calls (the engine is single-threaded per object)
  mutable pin::Data::Matrix6x frame_jacobian;
  mutable Vector r, y_column;
  // the constraint rows R, their rows Mc^-1 R_i^T and W_i, and the system (kept: no allocation per call
  // while the number of rows stays the same)
  mutable RowMatrix constraint, y, w;
  mutable Eigen::MatrixXd schur;
  mutable Vector bias, normal_velocity, rhs, force;
  mutable Eigen::PartialPivLU<Eigen::MatrixXd> lu;
  mutable RowMatrix accelerations, tangents, slide_e;  // p x 3, p x 6 (the sticking rows' t), p x 3
  mutable std::vector<int> tangent_count;               // per contact: its sticking rows
  // A differential drive: the wheels' joints (left, right; 0: none), their radius, and the rolling rows A
  // (3 x n) with their drift dA v at the state of the last rolling_terms.
  Wheels wheels;
  mutable RowMatrix rolling;
  mutable Vector rolling_drift;
  mutable pin::Data::Matrix6x wheel_jacobian;

  // The rolling rows and their drift at (q, dq) after rigid_body_terms, A v into `out`.
  void rolling_terms(const Eigen::Ref<const Vector>& dq, Answer& out) const;
  // Rows from i on: the rolling rows (bilateral, frictionless), A dv = -dA v - 2 a A v; returns the next row.
  int rolling_rows(int i, const Eigen::Ref<const Vector>& dq, double baumgarte) const;
  void contact_terms(int j, const Eigen::Ref<const Vector>& dq, Answer& out) const;
  void resize(Answer& out) const;
  // r = drive - Dc dq - (h + g) (after rigid_body_terms).
  void drive_balance(const Eigen::Ref<const Vector>& dq, const Eigen::Ref<const Vector>& current,
                     const Eigen::Ref<const Vector>& u) const;
  // The contacts' terms (held ones, or all if `full`) and the sticking ones' tangent directions; the number
  // of constraint rows: per held contact its normal row, per sticking one its tangential rows.
  int count_rows(const ContactModes& modes, bool full, const Eigen::Ref<const Vector>& dq, Answer& out) const;
  // The direction e a sliding contact's friction acts against in its W row (see normal_row).
  Vector3 slide_direction(int j, const ContactModes& modes, const Answer& out) const;
  // Row i: held contact j's normal row R_i = n^T J, its W_i and bias.
  void normal_row(int i, int j, const ContactModes& modes, const Eigen::Ref<const Vector>& dq, double baumgarte,
                  const Answer& out) const;
  // Rows from i on: sticking contact j's tangential rows t^T J (W = R); returns the next row.
  int tangent_rows(int i, int j, const Eigen::Ref<const Vector>& dq, double baumgarte, const Answer& out) const;
  // Every row (normal rows first, in contact order, then the sticking contacts' tangential rows) and Y.
  void assemble_rows(int rows, const ContactModes& modes, const Eigen::Ref<const Vector>& dq, double baumgarte,
                     const Answer& out) const;
  // force = (R Mc^-1 W^T)^-1 (bias - R Mc^-1 r), least-norm where the rows are dependent.
  void solve_forces(int rows) const;
  // The rows' forces into `out` per contact: normal force, friction, powers.
  void scatter_forces(const ContactModes& modes, Answer& out) const;
  // di, the effort and R(T) after ddq (voltage mode: the circuit).
  void circuit(const Eigen::Ref<const Vector>& dq, const Eigen::Ref<const Vector>& current,
               const Eigen::Ref<const Vector>& temperature, const Eigen::Ref<const Vector>& u, Answer& out) const;
};

// One contact's terms after rigid_body_terms, into row j of `out`.
void Dynamics::Impl::contact_terms(int j, const Eigen::Ref<const Vector>& dq, Answer& out) const {
  const auto frame = frames[j];
  const auto jacobian = translational_jacobian(model, data, frame, frame_jacobian);
  const Vector3 acceleration = pin::getFrameClassicalAcceleration(model, data, frame, pin::LOCAL_WORLD_ALIGNED).linear();
  accelerations.row(j) = acceleration.transpose();
  const Vector3 position = pin::updateFramePlacement(model, data, frame).translation();
  const Vector3 velocity = jacobian * dq;
  const ContactPoint point = contact_point(contacts[j].surface, position, velocity, acceleration);
  const Vector3 direction = point.slip / std::sqrt(point.slip.squaredNorm() + eps2);
  out.positions.row(j) = position.transpose();
  out.jacobians.middleRows<3>(3 * j) = jacobian;
  out.normal_jacobian.row(j).noalias() = point.normal.transpose() * jacobian;
  out.tangent_jacobian.row(j).noalias() = direction.transpose() * jacobian;
  out.slip.row(j) = point.slip.transpose();
  out.direction.row(j) = direction.transpose();
  out.normals.row(j) = point.normal.transpose();
  out.drift[j] = point.drift;
  out.residual[j] = point.residual;
}

void Dynamics::Impl::rolling_terms(const Eigen::Ref<const Vector>& dq, Answer& out) const {
  bracing_engine::rolling_rows(model, data, wheels, dq, rolling, rolling_drift, wheel_jacobian);
  out.rolling_velocity.noalias() = rolling * dq;
}

int Dynamics::Impl::rolling_rows(int i, const Eigen::Ref<const Vector>& dq, double baumgarte) const {
  for (int k = 0; k < 3; ++k, ++i) {
    constraint.row(i) = rolling.row(k);
    w.row(i) = rolling.row(k);
    normal_velocity[i] = rolling.row(k).dot(dq);
    bias[i] = -rolling_drift[k] - 2.0 * baumgarte * normal_velocity[i];
  }
  return i;
}

void Dynamics::Impl::resize(Answer& out) const {
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
  out.rolling_velocity.setZero(wheels ? 3 : 0);
  out.rolling_force.setZero(wheels ? 3 : 0);
}

void Dynamics::Impl::drive_balance(const Eigen::Ref<const Vector>& dq, const Eigen::Ref<const Vector>& current,
                                   const Eigen::Ref<const Vector>& u) const {
  if (drive.voltage)
    r.noalias() = drive.torque_constant.cwiseProduct(current) - drive.damping.cwiseProduct(dq) - data.nle;
  else
    r.noalias() = u - drive.damping.cwiseProduct(dq) - data.nle;
}

int Dynamics::Impl::count_rows(const ContactModes& modes, bool full, const Eigen::Ref<const Vector>& dq,
                               Answer& out) const {
  int rows = 0;
  for (int j = 0; j < static_cast<int>(contacts.size()); ++j) {
    if (modes.held[j] || full) contact_terms(j, dq, out);
    if (!modes.held[j]) continue;
    rows += 1;
    if (modes.sticking[j]) {
      Vector3 t[2];
      const int count = tangent_directions(out.normals.row(j).transpose(), out.jacobians.middleRows<3>(3 * j), t);
      tangent_count[j] = count;
      for (int k = 0; k < count; ++k) tangents.row(j).segment<3>(3 * k) = t[k].transpose();
      rows += count;
    }
  }
  if (wheels) {
    rolling_terms(dq, out);
    rows += 3;
  }
  return rows;
}

Vector3 Dynamics::Impl::slide_direction(int j, const ContactModes& modes, const Answer& out) const {
  if (!contacts[j].coulomb) return out.direction.row(j).transpose();
  // e = sign(f_n) d: |f_t| = mu |f_n| against the slip direction d, the live one while the slip has not
  // turned past a right angle from the held d (the interval's start): so past a reversal (an event,
  // located) the dynamics continue smoothly, with d held
  const Vector3 slip = out.slip.row(j).transpose(), held = modes.slide.row(j).transpose();
  const double speed = slip.norm();
  return modes.pushing[j] * (speed > kSlipAtRest && slip.dot(held) > 0.0 ? Vector3(slip / speed) : held);
}

void Dynamics::Impl::normal_row(int i, int j, const ContactModes& modes, const Eigen::Ref<const Vector>& dq,
                                double baumgarte, const Answer& out) const {
  // A normal row's W carries the sliding friction: W = J_c - mu e^T J (Coulomb: e the unit slide
  // direction; regularised: s / sqrt(|s|^2 + eps^2)); a sticking contact's friction is its tangential
  // rows' force instead.
  const auto row = out.normal_jacobian.row(j);
  constraint.row(i) = row;
  w.row(i) = row;
  const double mu = contacts[j].friction;
  if (!modes.sticking[j] && mu != 0.0) {
    const Vector3 e = slide_direction(j, modes, out);
    subtract_friction(w.row(i), mu, e, out.jacobians.middleRows<3>(3 * j));
    slide_e.row(j) = e.transpose();
  }
  normal_velocity[i] = row.dot(dq);
  bias[i] = -out.drift[j] - 2.0 * baumgarte * normal_velocity[i] - baumgarte * baumgarte * out.residual[j];
}

int Dynamics::Impl::tangent_rows(int i, int j, const Eigen::Ref<const Vector>& dq, double baumgarte,
                                 const Answer& out) const {
  const auto jacobian = out.jacobians.middleRows<3>(3 * j);
  const Vector3 acceleration = accelerations.row(j).transpose();
  for (int k = 0; k < tangent_count[j]; ++k, ++i) {
    const Vector3 tangent = tangents.row(j).segment<3>(3 * k).transpose();
    w.row(i).noalias() = tangent.transpose() * jacobian;
    constraint.row(i) = w.row(i);
    normal_velocity[i] = w.row(i).dot(dq);
    bias[i] = -tangent.dot(acceleration) - 2.0 * baumgarte * normal_velocity[i];
  }
  return i;
}

void Dynamics::Impl::assemble_rows(int rows, const ContactModes& modes, const Eigen::Ref<const Vector>& dq,
                                   double baumgarte, const Answer& out) const {
  // Row i: constraint R_i ddq = bias_i, its force acting through W_i (Mc ddq = r + W^T lambda).
  const int n = model.nv, p = static_cast<int>(contacts.size());
  constraint.resize(rows, n);
  y.resize(rows, n);
  w.resize(rows, n);
  bias.resize(rows);
  normal_velocity.resize(rows);
  int i = 0;
  for (int j = 0; j < p; ++j)
    if (modes.held[j]) normal_row(i++, j, modes, dq, baumgarte, out);
  for (int j = 0; j < p; ++j)
    if (modes.held[j] && modes.sticking[j]) i = tangent_rows(i, j, dq, baumgarte, out);
  if (wheels) rolling_rows(i, dq, baumgarte);
  mass_inverse_rows(model, data, constraint, y_column, y);
}

void Dynamics::Impl::solve_forces(int rows) const {
  schur.noalias() = y * w.transpose();  // R Mc^-1 W^T
  rhs = bias;
  rhs.noalias() -= y * r;
  lu.compute(schur);
  force.resize(rows);
  const auto pivots = lu.matrixLU().diagonal().cwiseAbs();
  if (pivots.minCoeff() > 1e-12 * pivots.maxCoeff()) {
    force = lu.solve(rhs);
    return;
  }
  // Dependent rows (e.g. two sticking contacts the joints cannot move apart): the forces are not
  // determined; the least-norm ones that satisfy the constraints, if any do.
  force = schur.completeOrthogonalDecomposition().solve(rhs);
  if (!force.allFinite() || (schur * force - rhs).norm() > 1e-9 * std::max(1.0, rhs.norm()))
    throw SingularError("Singular matrix: the contact constraints do not determine the forces");
}

void Dynamics::Impl::scatter_forces(const ContactModes& modes, Answer& out) const {
  const int p = static_cast<int>(contacts.size());
  int i = 0;
  for (int j = 0; j < p; ++j) {  // the normal rows, in contact order
    if (!modes.held[j]) continue;
    const Contact& contact = contacts[j];
    const double f = force[i];
    out.force[j] = f;
    out.constraint_power += f * normal_velocity[i];
    ++i;
    if (modes.sticking[j] || contact.friction == 0.0) continue;
    const Vector3 slip = out.slip.row(j).transpose();
    if (contact.coulomb) {  // -mu f_n e = -mu |f_n| d (with the sign held; see the simulator's start check)
      const Vector3 e = slide_e.row(j).transpose();
      out.tangential_force.row(j) = (-contact.friction * f * e).transpose();
      out.friction[j] = contact.friction * f * modes.pushing[j];
      out.friction_power += contact.friction * f * e.dot(slip);
    } else {
      const double slip2 = slip.squaredNorm();
      out.tangential_force.row(j) = (-contact.friction * f * out.direction.row(j)).eval();
      out.friction[j] = contact.friction * f;
      out.friction_power += contact.friction * f * slip2 / std::sqrt(slip2 + eps2);
    }
  }
  for (int j = 0; j < p; ++j) {  // the sticking contacts' tangential rows, in contact order
    if (!modes.held[j] || !modes.sticking[j]) continue;
    Vector3 tangential = Vector3::Zero();
    for (int k = 0; k < tangent_count[j]; ++k, ++i) {
      tangential += force[i] * tangents.row(j).segment<3>(3 * k).transpose();
      out.constraint_power += force[i] * normal_velocity[i];
    }
    out.tangential_force.row(j) = tangential.transpose();
    out.friction[j] = tangential.norm();
  }
  if (!wheels) return;
  for (int k = 0; k < 3; ++k, ++i) {  // the rolling rows, last
    out.rolling_force[k] = force[i];
    out.constraint_power += force[i] * normal_velocity[i];
  }
}

void Dynamics::Impl::circuit(const Eigen::Ref<const Vector>& dq, const Eigen::Ref<const Vector>& current,
                             const Eigen::Ref<const Vector>& temperature, const Eigen::Ref<const Vector>& u,
                             Answer& out) const {
  const Drive& d = drive;
  if (!d.voltage) {
    out.di.setZero(model.nv);
    out.resistance = d.resistance;
    out.effort = u;
    return;
  }
  d.resistance_at(temperature, out.resistance);
  out.di.array() =
      (u - out.resistance.cwiseProduct(current) - d.torque_constant.cwiseProduct(dq)).array() / d.inductance.array();
  out.effort.array() = d.torque_constant.cwiseProduct(current).array() - d.reflected_damping.cwiseProduct(dq).array() -
                       d.added_inertia.cwiseProduct(out.ddq).array();
}

Dynamics::Dynamics(const Robot& robot, const Drive& drive, std::vector<Contact> contacts, double slip_epsilon,
                   double baumgarte_gain)
    : baumgarte(baumgarte_gain), impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.model = build_model(robot, drive.added_inertia, &m.shapes);
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
  m.points.attach(m.model, m.shapes, contacts, m.frames);
  m.data = pin::Data(m.model);  // with the geometry contacts' frames
  m.contacts = std::move(contacts);
  m.eps2 = slip_epsilon * slip_epsilon;
  m.frame_jacobian.setZero(6, n);
  m.accelerations.setZero(m.contacts.size(), 3);
  m.tangents.setZero(m.contacts.size(), 6);
  m.slide_e.setZero(m.contacts.size(), 3);
  m.tangent_count.assign(m.contacts.size(), 0);
  m.r.setZero(n);
  m.y_column.setZero(n);
  m.wheels = wheels_of(m.model, robot);
  if (m.wheels) {
    m.rolling.setZero(3, n);
    m.rolling_drift.setZero(3);
    m.wheel_jacobian.setZero(6, n);
  }
}

int Dynamics::rolling_rows() const { return impl_->wheels ? 3 : 0; }

Dynamics::~Dynamics() = default;

int Dynamics::nv() const { return impl_->model.nv; }
int Dynamics::contact_count() const { return static_cast<int>(impl_->contacts.size()); }
const std::vector<Contact>& Dynamics::contacts() const { return impl_->contacts; }
const Drive& Dynamics::drive() const { return impl_->drive; }

std::vector<std::string> Dynamics::joint_names() const {
  const auto& names = impl_->model.names;
  return std::vector<std::string>(names.begin() + 1, names.end());
}

void Dynamics::terms(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& dq, Answer& out) const {
  const Impl& m = *impl_;
  m.resize(out);
  rigid_body_terms(m.model, m.data, q, dq);
  if (!m.points.empty()) m.points.place(m.model, m.data);
  for (int j = 0; j < contact_count(); ++j) m.contact_terms(j, dq, out);
  if (m.wheels) m.rolling_terms(dq, out);
}

void Dynamics::measure_links(const Eigen::Ref<const Vector>& q, const std::vector<Surface>& surfaces,
                             LinkMeasurement& out) const {
  const Impl& m = *impl_;
  for (const Surface& surface : surfaces) LinkShapes::check_surface(surface, "robot.collision_geometry");
  pin::forwardKinematics(m.model, m.data, q);
  bracing_engine::measure_links(m.shapes, m.data, surfaces, out);
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
  Matrix3 basis;  // rows t1, t2, n: column c of basis J is joint c's (t1, t2, n) velocity
  basis << t1.transpose(), t2.transpose(), n.transpose();
  const Eigen::Index columns = jacobian.cols();
  double along[2] = {0.0, 0.0}, normal2 = 0.0;  // the tangential rows . the normal row, |normal row|^2
  for (Eigen::Index c = 0; c < columns; ++c) {
    const Vector3 r = basis * jacobian.col(c);
    along[0] += r[0] * r[2];
    along[1] += r[1] * r[2];
    normal2 += r[2] * r[2];
  }
  const double part[2] = {normal2 > 0.0 ? along[0] / normal2 : 0.0, normal2 > 0.0 ? along[1] / normal2 : 0.0};
  // The Gram matrix of the tangential rows without their normal part; its eigenvectors are their left
  // singular vectors, the square roots of its eigenvalues their singular values, in closed form (the 2 x n
  // JacobiSVD it replaces, and its allocations, were ~11% of make bench's engine step: 123k -> 139k steps/s).
  Eigen::Matrix2d gram = Eigen::Matrix2d::Zero();
  for (Eigen::Index c = 0; c < columns; ++c) {
    const Vector3 r = basis * jacobian.col(c);
    const double a = r[0] - part[0] * r[2], b = r[1] - part[1] * r[2];
    gram(0, 0) += a * a;
    gram(1, 0) += a * b;
    gram(1, 1) += b * b;
  }
  gram(0, 1) = gram(1, 0);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen;
  eigen.computeDirect(gram);
  const double scale = std::max(jacobian.norm(), 1e-300);
  int count = 0;
  for (int k = 1; k >= 0; --k)  // eigenvalues ascending: the largest first
    if (std::sqrt(std::max(eigen.eigenvalues()[k], 0.0)) > 1e-6 * scale)
      out[count++] = eigen.eigenvectors()(0, k) * t1 + eigen.eigenvectors()(1, k) * t2;
  return count;
}

void Dynamics::evaluate(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& dq,
                        const Eigen::Ref<const Vector>& current, const Eigen::Ref<const Vector>& temperature,
                        const Eigen::Ref<const Vector>& u, const ContactModes& modes, bool full, Answer& out) const {
  const Impl& m = *impl_;
  m.resize(out);
  rigid_body_terms(m.model, m.data, q, dq);
  if (!m.points.empty()) m.points.place(m.model, m.data);
  pin::cholesky::decompose(m.model, m.data);
  m.drive_balance(dq, current, u);
  const int rows = m.count_rows(modes, full, dq, out);
  out.force.setZero();
  out.tangential_force.setZero();
  out.friction.setZero();
  out.friction_power = out.constraint_power = 0.0;
  out.ddq = m.r;
  if (rows) {
    m.assemble_rows(rows, modes, dq, baumgarte, out);
    m.solve_forces(rows);
    out.ddq.noalias() += m.w.transpose() * m.force;
    m.scatter_forces(modes, out);
  }
  pin::cholesky::solve(m.model, m.data, out.ddq);  // Mc^-1 (r + W^T lambda)
  m.circuit(dq, current, temperature, u, out);
}

void Dynamics::rerun_circuit(const Eigen::Ref<const Vector>& dq, const Eigen::Ref<const Vector>& current,
                             const Eigen::Ref<const Vector>& temperature, const Eigen::Ref<const Vector>& u,
                             Answer& out) const {
  if (!impl_->drive.voltage) throw std::logic_error("rerun_circuit: the answer depends on u in torque mode");
  impl_->circuit(dq, current, temperature, u, out);
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
  if (m.wheels)  // the wheels keep rolling through the impulse
    for (int i = 0; i < 3; ++i) rows.push_back(m.rolling.row(i).transpose());
  const int k = static_cast<int>(rows.size());
  if (!k) return 0.0;
  Eigen::MatrixXd r(k, n);
  for (int i = 0; i < k; ++i) r.row(i) = rows[i].transpose();
  return remove_velocity(m.model, m.data, r, m.y_column, dq);
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
    mass_inverse_rows(m.model, m.data, jc, m.y_column, y.transpose());
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
  const int rolling = rolling_rows();  // the wheels keep rolling through the impulse
  Eigen::MatrixXd jc(k + rolling, n);
  for (int i = 0; i < k; ++i) jc.row(i) = answer.normal_jacobian.row(rows[i]);
  if (rolling) jc.bottomRows(rolling) = m.rolling;
  return remove_velocity(m.model, m.data, jc, m.y_column, dq);
}

}  // namespace bracing_engine
