// The decoupled law on pinocchio (docs/model.md, Control law):
//
//   B = J_c Mc^-1,  A = B (J_c - mu J_t)^T,  a = B (h + g + Dc dq) - gamma
//   tau = B^+ (a - A f_nd) + (I - B^+ B) l,   v = K_V tau (voltage mode)
//   l = sum over the tasks of J^T [Kp (r_d - r) + Kd (dr_d - dr)] (+ g(q))
//
// and, with a Coulomb contact at rest, its point-constraint form (docs/model.md, Control law under stick).
#include "law_impl.hpp"

#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <stdexcept>

namespace bracing_engine {

namespace {

// A differential drive's admissible motions: T = [0 S_b; 0 I] (n x n) from the rolling rows A = [A_b A_a]
// (`base` A_b's factor), S_b = -A_b^-1 A_a the base's velocities the actuated ones give (A T = 0).
void embed_rolling(const RowMatrix& rolling, const Eigen::PartialPivLU<Eigen::Matrix3d>& base, Eigen::MatrixXd& out) {
  const Eigen::Index n = rolling.cols(), m = n - 3;
  out.setZero(n, n);
  out.topRightCorner(3, m) = -base.solve(Eigen::MatrixXd(rolling.rightCols(m)));
  out.bottomRightCorner(m, m).setIdentity();
}

}  // namespace

Law::Law(const LawSpec& spec) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.spec = spec;
  m.model = build_model(spec.robot, spec.drive.added_inertia, &m.shapes);
  const int n = m.model.nv;
  if (spec.drive.added_inertia.size() != n || spec.drive.damping.size() != n || spec.voltage_gain.size() != n)
    throw std::invalid_argument("law: one value per joint expected");
  auto frame = [&](const std::string& name) {
    if (!m.model.existFrame(name)) throw std::invalid_argument("unknown frame " + name);
    return m.model.getFrameId(name);
  };
  m.frames.push_back(frame(spec.hand.frame));
  for (const auto& brace : spec.braces) m.frames.push_back(frame(brace.contact.frame));
  std::vector<Contact> brace_contacts;
  for (const auto& brace : spec.braces) brace_contacts.push_back(brace.contact);
  std::vector<pin::FrameIndex> brace_frames(m.frames.begin() + 1, m.frames.end());
  m.points.attach(m.model, m.shapes, brace_contacts, brace_frames);
  std::copy(brace_frames.begin(), brace_frames.end(), m.frames.begin() + 1);
  m.data = pin::Data(m.model);  // with the geometry braces' frames
  m.starts.assign(m.frames.size(), Vector3::Zero());
  m.overridden.assign(m.frames.size(), false);
  m.reference_position.assign(m.frames.size(), Vector3::Zero());
  m.reference_velocity.assign(m.frames.size(), Vector3::Zero());
  m.jacobian.setZero(3, n);
  m.frame_jacobian.setZero(6, n);
  m.y_column.setZero(n);
  m.measured_force.setZero(braces(), 3);
  m.wheels = wheels_of(m.model, spec.robot);
  m.base_drifts.assign(m.frames.size(), Vector3::Zero());
  if (m.wheels && (m.model.nv <= 3 || !m.model.existJointName("base_yaw") ||
                   m.model.idx_vs[m.model.getJointId("base_yaw")] != 2))
    throw std::invalid_argument("law: a differential drive's base_x, base_y, base_yaw must be the first joints");
  for (const Vector* v : {&spec.posture_kp, &spec.posture_kd, &spec.posture_rest})
    if (v->size() != 0 && v->size() != n) throw std::invalid_argument("law: one posture value per joint expected");
  if (spec.command_limit.size() != 0 && spec.command_limit.size() != n)
    throw std::invalid_argument("law: one command limit per joint expected");
  for (int axis : spec.orientation.axes)
    if (axis < 0 || axis > 2) throw std::invalid_argument("law: orientation axes are world axes 0-2");
  m.orientation = !spec.orientation.axes.empty();
  m.posture = (spec.posture_kp.size() && spec.posture_kp.cwiseAbs().maxCoeff() > 0.0) ||
              (spec.posture_kd.size() && spec.posture_kd.cwiseAbs().maxCoeff() > 0.0);
  reset();
}

Law::~Law() = default;

int Law::nv() const { return impl_->model.nv; }
int Law::braces() const { return static_cast<int>(impl_->spec.braces.size()); }

bool Law::orients() const { return !impl_->spec.orientation.axes.empty(); }

Vector Law::desired_normal_force() const {
  Vector f(braces());
  for (int j = 0; j < braces(); ++j) f[j] = impl_->spec.braces[j].desired_normal_force;
  return f;
}

void Law::reset() {
  Impl& m = *impl_;
  m.started = false;
  m.overridden.assign(m.frames.size(), false);
  m.measured.assign(m.spec.braces.size(), false);
  m.integral.setZero(braces());
  m.task_integral.assign(m.frames.size(), Vector3::Zero());
  m.orientation_integral.setZero();
  m.orientation_overridden = false;
  m.orientation_velocity.setZero();
  m.saturated = false;
  m.temperature = Vector::Constant(m.model.nv, m.spec.drive.ambient);
}

void Law::set_reference(int task, const Vector3& position, const Vector3& velocity) {
  Impl& m = *impl_;
  if (task < 0 || task > braces()) throw std::out_of_range("set_reference: no such task");
  m.overridden[task] = true;
  m.reference_position[task] = position;
  m.reference_velocity[task] = velocity;
}

void Law::set_orientation_reference(const Matrix3& rotation, const Vector3& angular_velocity) {
  Impl& m = *impl_;
  if (!m.orientation) throw std::logic_error("set_orientation_reference: no orientation task");
  if (!m.started) throw std::logic_error("set_orientation_reference: the law has not seen a state yet");
  m.orientation_overridden = true;
  m.orientation_target = rotation;
  m.orientation_velocity = angular_velocity;
}

Matrix3 Law::orientation_reference() const {
  const Impl& m = *impl_;
  if (!m.started) throw std::logic_error("orientation_reference: the law has not seen a state yet");
  return m.orientation_target;
}

void Law::clear_reference(int task) {
  Impl& m = *impl_;
  if (task < 0 || task > braces()) throw std::out_of_range("clear_reference: no such task");
  m.overridden[task] = false;
}

std::pair<Vector3, Vector3> Law::path_sample(int task, double t) const {
  const Impl& m = *impl_;
  if (task < 0 || task > braces()) throw std::out_of_range("path_sample: no such task");
  if (!m.started) throw std::logic_error("path_sample: the law has not seen a state yet");
  const Task& spec = task ? m.spec.braces[task - 1].task : m.spec.hand;
  Vector3 position, velocity;
  spec.path.sample(m.starts[task], t, position, velocity);
  return {position, velocity};
}

void Law::measure_force(int brace, const Vector3& force) {
  Impl& m = *impl_;
  if (brace < 0 || brace >= braces()) throw std::out_of_range("measure_force: no such brace");
  m.measured_force.row(brace) = force.transpose();
  m.measured[brace] = true;
}

void Law::measure_temperature(const Vector& temperature) {
  if (temperature.size() != impl_->model.nv) throw std::invalid_argument("measure_temperature: one per joint");
  impl_->temperature = temperature;
}

bool Law::uses_force_feedback() const {
  for (const auto& brace : impl_->spec.braces)
    if (brace.feedback_kp != 0.0 || brace.feedback_ki != 0.0) return true;
  return false;
}

Vector Law::voltage_command(const Vector& torque, const Vector& dq) const {
  const LawSpec& s = impl_->spec;
  if (!s.drive.voltage) return torque;
  // R(T) / R_20 = 1 + alpha (T - 20 degC), from the measured temperatures (thermal compensation)
  const bool warm = uses_temperature();
  if (!warm && !s.back_emf_compensation) return s.voltage_gain.cwiseProduct(torque);  // eq. 41
  const Eigen::ArrayXd heating = 1.0 + s.drive.temperature_coefficient * (impl_->temperature.array() - 20.0);
  if (s.back_emf_compensation) {  // the motor inverted: v = R i + K_m dq with K_m i = tau
    const Eigen::ArrayXd resistance = warm ? Eigen::ArrayXd(s.drive.resistance.array() * heating)
                                           : Eigen::ArrayXd(s.drive.resistance.array());
    return (resistance * torque.array() / s.drive.torque_constant.array() +
            s.drive.torque_constant.array() * dq.array())
        .matrix();
  }
  Vector command = s.voltage_gain.cwiseProduct(torque);  // eq. 41
  if (warm) command.array() *= heating;
  return command;
}

bool Law::uses_temperature() const {
  const LawSpec& s = impl_->spec;
  return s.thermal_compensation && s.drive.voltage && s.drive.thermal;
}

const std::string& Law::brace_name(int brace) const { return impl_->spec.braces.at(brace).contact.name; }

double Law::Impl::advance_clock(double t, const Vector& q) {
  if (!started) {
    for (std::size_t k = 0; k < frames.size(); ++k)
      starts[k] = pin::updateFramePlacement(model, data, frames[k]).translation();
    started = true;
    last_time = t;
    rest = spec.posture_rest.size() ? spec.posture_rest : q;
    orientation_target = spec.orientation.has_target
                             ? spec.orientation.target
                             : Matrix3(pin::updateFramePlacement(model, data, frames[0]).rotation());
  }
  const double dt = t - last_time;  // since the last update (force feedback's integral)
  last_time = t;
  return dt;
}

Eigen::MatrixXd Law::Impl::mass_inverse() {
  const int n = model.nv;
  Eigen::MatrixXd out(n, n);
  inverse_rows(Eigen::MatrixXd::Identity(n, n), out);  // Mc^-1 symmetric
  return out;
}

Vector Law::Impl::mass_solve(Vector x) const {
  if (wheels) return reduced_mass.solve(x);
  pin::cholesky::solve(model, data, x);
  return x;
}

void Law::Impl::reduce(const Vector& dq, bool mass) {
  if (!mass) {
    rolling_rows(model, data, wheels, dq, rolling, rolling_drift, frame_jacobian);
    const Eigen::PartialPivLU<Eigen::Matrix3d> base(Eigen::Matrix3d(rolling.leftCols<3>()));
    embed_rolling(rolling, base, embed);
    base_acceleration = -base.solve(Eigen::Vector3d(rolling_drift));
    return;
  }
  Eigen::MatrixXd reduced = embed.transpose() * Eigen::MatrixXd(data.M.selfadjointView<Eigen::Upper>()) * embed;
  reduced.topLeftCorner<3, 3>() += Eigen::Matrix3d::Identity();  // the base's block: no motor, decoupled
  reduced_mass.compute(reduced);
}

Eigen::MatrixXd Law::motion_map(const Vector& q) const {
  const Impl& m = *impl_;
  const int n = m.model.nv;
  if (!m.wheels) return Eigen::MatrixXd::Identity(n, n);
  pin::Data data(m.model);  // the law's own data keeps the last update's terms
  const Vector zero = Vector::Zero(n);
  rigid_body_terms(m.model, data, q, zero);
  RowMatrix rolling;
  Vector drift;
  pin::Data::Matrix6x work = pin::Data::Matrix6x::Zero(6, n);
  rolling_rows(m.model, data, m.wheels, zero, rolling, drift, work);
  Eigen::MatrixXd out;
  embed_rolling(rolling, Eigen::PartialPivLU<Eigen::Matrix3d>(Eigen::Matrix3d(rolling.leftCols<3>())), out);
  return out;
}

void Law::update(double t, const Vector& q, const Vector& dq, LawOutput& out) {
  Impl& m = *impl_;
  const LawSpec& s = m.spec;
  const int n = m.model.nv, p = braces();
  rigid_body_terms(m.model, m.data, q, dq);
  if (!m.points.empty()) m.points.place(m.model, m.data);
  if (m.wheels) m.reduce(dq, false);
  const double dt = m.advance_clock(t, q);
  out.force_command.resize(p);
  out.brace_desired.resize(p, 3);
  out.brace_actual.resize(p, 3);
  Eigen::MatrixXd brace_jacobians(3 * p, n);
  Eigen::MatrixXd task_rows(0, n);  // the configured axes' Jacobian rows, stacked (the posture's null space)
  Vector task_accelerations(0);     // acceleration gains: the tasks' PID accelerations along those rows
  Vector l = m.task_torque(t, dt, dq, out, brace_jacobians, task_rows, task_accelerations);
  out.orientation_error.setZero();
  if (m.orientation) m.orientation_torque(dq, dt, out, l, task_rows, task_accelerations);
  if (s.gravity_compensation) {
    const Vector gravity = pin::computeGeneralizedGravity(m.model, m.data, q);
    l += m.wheels ? Vector(m.embed.transpose() * gravity) : gravity;
  }
  if (m.posture) l += m.posture_torque(task_rows, q, dq);
  out.damped = false;
  if (p == 0 && !s.acceleration_gains) {
    out.torque = l;
  } else {
    m.decompose();
    BraceRows rows;
    if (p) rows = m.brace_rows(brace_jacobians, dq, dt, out);
    const BraceRows* braced = p ? &rows : nullptr;
    Vector bias = m.data.nle + s.drive.damping.cwiseProduct(dq);  // h + g + Dc dq
    if (m.wheels) {  // T^T (h + g + Dc dq + Mc dT dq): the admissible motions' share
      const Eigen::MatrixXd mass = m.data.M.selfadjointView<Eigen::Upper>();
      bias = m.embed.transpose() * (bias + mass.leftCols<3>() * m.base_acceleration);
    }
    if (s.acceleration_gains) {  // ddq is affine in l: the task part from how the constrained arm answers l
      ArmResponse response;
      bool ignored = false;
      m.contact_torque(braced, brace_jacobians, bias, l, ignored, &response);
      l += m.task_space_torque(task_rows, task_accelerations, response);
    }
    out.torque = m.contact_torque(braced, brace_jacobians, bias, l, out.damped);
  }
  if (m.wheels) out.torque.head<3>().setZero();  // the base has no motor: the wheels move it
  out.command = voltage_command(out.torque, dq);
  m.saturated = false;
  for (Eigen::Index i = 0; i < s.command_limit.size() && i < out.command.size(); ++i)
    if (s.command_limit[i] > 0.0 && std::abs(out.command[i]) >= s.command_limit[i]) m.saturated = true;
}

}  // namespace bracing_engine
