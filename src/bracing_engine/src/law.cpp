// The decoupled law on pinocchio (docs/model.md, Control law):
//
//   B = J_c Mc^-1,  A = B (J_c - mu J_t)^T,  a = B (h + g + Dc dq) - gamma
//   tau = B^+ (a - A f_nd) + (I - B^+ B) l,   v = K_V tau (voltage mode)
//   l = sum over the tasks of J^T [Kp (r_d - r) + Kd (dr_d - dr)] (+ g(q))
#include "bracing_engine/law.hpp"

#include "model.hpp"

#include <pinocchio/algorithm/cholesky.hpp>
#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <Eigen/Dense>
#include <Eigen/SVD>

#include <cmath>
#include <stdexcept>

namespace bracing_engine {

namespace pin = pinocchio;

// Smallest singular value of B (relative to its largest) below which B^+ is damped.
constexpr double kSingularRatio = 1e-8;

namespace {

// Python's float floor division (t // step), so a segment switches at the same sample.
double floor_div(double t, double step) {
  double mod = std::fmod(t, step);
  double div = (t - mod) / step;
  if (mod != 0.0 && ((step < 0.0) != (mod < 0.0))) div -= 1.0;
  double floor_value = std::floor(div);
  if (div - floor_value > 0.5) floor_value += 1.0;
  return floor_value;
}

// B^+ = B^T (B B^T)^-1, damped (B^T (B B^T + lambda I)^-1, `damped` set) when B's smallest singular
// value is below kSingularRatio of its largest.
Eigen::MatrixXd pseudo_inverse(const Eigen::MatrixXd& b, double damping_lambda, bool& damped) {
  const Eigen::Index p = b.rows();
  const Eigen::MatrixXd gram = b * b.transpose();
  double largest, smallest;
  if (p == 1) {
    largest = smallest = std::sqrt(gram(0, 0));
  } else {
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(b);
    largest = svd.singularValues()[0];
    smallest = svd.singularValues()[p - 1];
  }
  if (smallest > kSingularRatio * std::max(largest, 1e-300)) return gram.partialPivLu().solve(b).transpose();
  damped = true;
  const double lambda = damping_lambda * std::max(largest * largest, 1.0);
  return (gram + lambda * Eigen::MatrixXd::Identity(p, p)).partialPivLu().solve(b).transpose();
}

// max |(I - J^+ J) dq|: the joints' motion that no task row sees [rad/s or m/s].
double null_space_speed(const Eigen::MatrixXd& rows, const Vector& dq) {
  if (dq.size() == 0) return 0.0;
  if (rows.rows() == 0) return dq.cwiseAbs().maxCoeff();
  const Vector seen = rows.completeOrthogonalDecomposition().solve(rows * dq);  // J^+ J dq
  return (dq - seen).cwiseAbs().maxCoeff();
}

}  // namespace

void Path::sample(const Vector3& start, double t, Vector3& position, Vector3& velocity) const {
  velocity.setZero();
  switch (kind) {
    case PathKind::hold:
      position = has_point ? point : start;
      return;
    case PathKind::circle: {
      const double rate = direction * 2.0 * M_PI / period;
      const double angle = rate * t + phase;
      position = center;
      position[u] += radius * std::cos(angle);
      position[v] += radius * std::sin(angle);
      velocity[u] = -radius * rate * std::sin(angle);
      velocity[v] = radius * rate * std::cos(angle);
      return;
    }
    case PathKind::waypoints: {
      // rest to rest through each waypoint, minimum jerk s(x) = 10 x^3 - 15 x^4 + 6 x^5 per segment
      const long segment = t > 0.0 ? static_cast<long>(floor_div(t, segment_time)) : 0;
      const long count = static_cast<long>(waypoints.size());
      if (segment >= count) {
        position = count ? waypoints.back() : start;
        return;
      }
      const double x = t / segment_time - static_cast<double>(segment);
      const double s = x * x * x * (10.0 + x * (-15.0 + 6.0 * x));
      const double ds = 30.0 * x * x * (1.0 - x) * (1.0 - x) / segment_time;
      const Vector3& a = segment ? waypoints[segment - 1] : start;
      const Vector3& b = waypoints[segment];
      position = a + s * (b - a);
      velocity = ds * (b - a);
      return;
    }
  }
}

struct Law::Impl {
  LawSpec spec;
  pin::Model model;
  mutable pin::Data data;
  std::vector<pin::FrameIndex> frames;  // hand, then each brace
  std::vector<Vector3> starts;          // the tasks' first measured positions
  bool started = false;
  // A reference given from outside (targets while running, set_reference): per task, used instead of its path.
  std::vector<bool> overridden;
  std::vector<Vector3> reference_position, reference_velocity;
  Eigen::Matrix<double, 3, Eigen::Dynamic> jacobian;
  pin::Data::Matrix6x frame_jacobian;
  Vector y_column;
  // force feedback: the last measured force per brace, its integral of (f_nd - f_meas) dt, the time of
  // the last update and whether its command saturated (the integral then holds: anti-windup)
  RowMatrix measured_force;
  std::vector<bool> measured;
  Vector integral;
  double last_time = 0.0;
  bool saturated = false;
  Vector temperature;  // the windings' measured temperatures [degC]
  Vector rest;         // the posture task's rest position (the first measured one unless configured)
  bool posture = false;

  // The rows of m.jacobian along `axes`, appended to `rows`.
  void stack(Eigen::MatrixXd& rows, const std::vector<int>& axes) const {
    for (int axis : axes) {
      rows.conservativeResize(rows.rows() + 1, Eigen::NoChange);
      rows.row(rows.rows() - 1) = jacobian.row(axis);
    }
  }

  // N^T (kp (rest - q) - kd dq), N^T = I - J^T (J Mc^-1 J^T)^-1 J Mc^-1 (Mc's Cholesky factor computed here).
  Vector posture_torque(const Eigen::MatrixXd& rows, const Vector& q, const Vector& dq) {
    const int n = model.nv;
    Vector w = Vector::Zero(n);
    if (spec.posture_kp.size()) w += spec.posture_kp.cwiseProduct(rest - q);
    if (spec.posture_kd.size()) w -= spec.posture_kd.cwiseProduct(dq);
    if (rows.rows() == 0) return w;
    pin::cholesky::decompose(model, data);
    Eigen::MatrixXd y(n, rows.rows());  // Mc^-1 J^T
    for (Eigen::Index k = 0; k < rows.rows(); ++k) {
      y_column = rows.row(k).transpose();
      pin::cholesky::solve(model, data, y_column);
      y.col(k) = y_column;
    }
    const Eigen::MatrixXd inverse_inertia = rows * y;  // J Mc^-1 J^T
    return w - rows.transpose() * inverse_inertia.completeOrthogonalDecomposition().solve(y.transpose() * w);
  }

  // f_cmd of brace j at the normal `normal` (f_nd without feedback gains or a measurement).
  double force_command(int j, const Vector3& normal, double dt) {
    const BracedContact& brace = spec.braces[j];
    const double f_nd = brace.desired_normal_force;
    if ((brace.feedback_kp == 0.0 && brace.feedback_ki == 0.0) || !measured[j]) return f_nd;
    const double error = f_nd - normal.dot(measured_force.row(j).transpose());
    if (!saturated) integral[j] += error * dt;
    return f_nd + brace.feedback_kp * error + brace.feedback_ki * integral[j];
  }
};

Law::Law(const LawSpec& spec) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.spec = spec;
  m.model = build_model(spec.robot, spec.drive.added_inertia);
  const int n = m.model.nv;
  if (spec.drive.added_inertia.size() != n || spec.drive.damping.size() != n || spec.voltage_gain.size() != n)
    throw std::invalid_argument("law: one value per joint expected");
  m.data = pin::Data(m.model);
  auto frame = [&](const std::string& name) {
    if (!m.model.existFrame(name)) throw std::invalid_argument("unknown frame " + name);
    return m.model.getFrameId(name);
  };
  m.frames.push_back(frame(spec.hand.frame));
  for (const auto& brace : spec.braces) m.frames.push_back(frame(brace.contact.frame));
  m.starts.assign(m.frames.size(), Vector3::Zero());
  m.overridden.assign(m.frames.size(), false);
  m.reference_position.assign(m.frames.size(), Vector3::Zero());
  m.reference_velocity.assign(m.frames.size(), Vector3::Zero());
  m.jacobian.setZero(3, n);
  m.frame_jacobian.setZero(6, n);
  m.y_column.setZero(n);
  m.measured_force.setZero(braces(), 3);
  for (const Vector* v : {&spec.posture_kp, &spec.posture_kd, &spec.posture_rest})
    if (v->size() != 0 && v->size() != n) throw std::invalid_argument("law: one posture value per joint expected");
  m.posture = (spec.posture_kp.size() && spec.posture_kp.cwiseAbs().maxCoeff() > 0.0) ||
              (spec.posture_kd.size() && spec.posture_kd.cwiseAbs().maxCoeff() > 0.0);
  reset();
}

Law::~Law() = default;

int Law::nv() const { return impl_->model.nv; }
int Law::braces() const { return static_cast<int>(impl_->spec.braces.size()); }

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

double Law::null_space_speed(const Vector& dq) {
  Impl& m = *impl_;
  Eigen::MatrixXd rows(0, m.model.nv);
  for (std::size_t k = 0; k < m.frames.size(); ++k) {  // the Jacobians of the last update's pass
    m.frame_jacobian.setZero();
    pin::getFrameJacobian(m.model, m.data, m.frames[k], pin::LOCAL_WORLD_ALIGNED, m.frame_jacobian);
    m.jacobian = m.frame_jacobian.topRows<3>();
    m.stack(rows, k ? m.spec.braces[k - 1].task.axes : m.spec.hand.axes);
  }
  return bracing_engine::null_space_speed(rows, dq);
}

const std::string& Law::brace_name(int brace) const { return impl_->spec.braces.at(brace).contact.name; }

RowMatrix Law::task_positions(const Vector& q) {
  Impl& m = *impl_;
  pin::forwardKinematics(m.model, m.data, q);
  RowMatrix out(m.frames.size(), 3);
  for (std::size_t k = 0; k < m.frames.size(); ++k)
    out.row(k) = pin::updateFramePlacement(m.model, m.data, m.frames[k]).translation().transpose();
  return out;
}

Eigen::MatrixXd Law::allowed_task_rows(const Vector& q0, const std::vector<std::pair<int, int>>& rows) {
  Impl& m = *impl_;
  const int n = m.model.nv, p = braces();
  const Vector zero = Vector::Zero(n);
  pin::computeAllTerms(m.model, m.data, q0, zero);
  auto translational = [&](std::size_t k) {
    m.frame_jacobian.setZero();
    pin::getFrameJacobian(m.model, m.data, m.frames[k], pin::LOCAL_WORLD_ALIGNED, m.frame_jacobian);
    return Eigen::MatrixXd(m.frame_jacobian.topRows<3>());
  };
  // the motions the braced contacts allow: I - J_c^+ J_c
  Eigen::MatrixXd allowed = Eigen::MatrixXd::Identity(n, n);
  if (p) {
    Eigen::MatrixXd jc(p, n);
    for (int j = 0; j < p; ++j) {
      const Vector3 position = pin::updateFramePlacement(m.model, m.data, m.frames[j + 1]).translation();
      double c;
      Vector3 normal;
      Matrix3 hessian;
      m.spec.braces[j].contact.surface.evaluate(position, c, normal, hessian);
      jc.row(j) = normal.transpose() * translational(j + 1);
    }
    allowed -= jc.completeOrthogonalDecomposition().pseudoInverse() * jc;
  }
  Eigen::MatrixXd out(static_cast<Eigen::Index>(rows.size()), n);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto [task, axis] = rows[i];
    if (task < 0 || task > p || axis < 0 || axis > 2) throw std::invalid_argument("allowed_task_rows: no such row");
    out.row(static_cast<Eigen::Index>(i)) = translational(static_cast<std::size_t>(task)).row(axis) * allowed;
  }
  return out;
}

namespace {
// Whether the smallest singular value of `rows` is negligible (the rank check's tolerance).
bool rank_deficient(const Eigen::MatrixXd& rows) {
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(rows);
  const auto& sigma = svd.singularValues();
  return sigma[sigma.size() - 1] <= 1e-6 * std::max(sigma[0], 1.0);
}
}  // namespace

std::pair<int, int> Law::first_rankless_axis(const Vector& q0) {
  const Impl& m = *impl_;
  std::vector<std::pair<int, int>> configured;
  for (std::size_t k = 0; k < m.frames.size(); ++k) {
    const Task& task = k ? m.spec.braces[k - 1].task : m.spec.hand;
    for (int axis : task.axes) configured.emplace_back(static_cast<int>(k), axis);
  }
  const Eigen::MatrixXd rows = allowed_task_rows(q0, configured);
  for (Eigen::Index i = 0; i < rows.rows(); ++i)
    if (rank_deficient(rows.topRows(i + 1))) return configured[static_cast<std::size_t>(i)];
  return {-1, -1};
}

int Law::task_rank(const Vector& q0, const std::vector<std::pair<int, int>>& rows) {
  if (rows.empty()) return 0;
  const Eigen::MatrixXd stacked = allowed_task_rows(q0, rows);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(stacked);
  const auto& sigma = svd.singularValues();
  const double tolerance = 1e-6 * std::max(sigma[0], 1.0);
  return static_cast<int>((sigma.array() > tolerance).count());
}

void Law::retune(const Vector3& hand_kp, const Vector3& hand_kd, const std::vector<Vector3>& brace_kp,
                 const std::vector<Vector3>& brace_kd, const Vector& desired_normal_force, const Vector& voltage_gain) {
  LawSpec& s = impl_->spec;
  const std::size_t b = s.braces.size();
  if (brace_kp.size() != b || brace_kd.size() != b || static_cast<std::size_t>(desired_normal_force.size()) != b ||
      voltage_gain.size() != s.voltage_gain.size())
    throw std::invalid_argument("retune: sizes differ from the law's");
  s.hand.kp = hand_kp;
  s.hand.kd = hand_kd;
  for (std::size_t j = 0; j < b; ++j) {
    s.braces[j].task.kp = brace_kp[j];
    s.braces[j].task.kd = brace_kd[j];
    s.braces[j].desired_normal_force = desired_normal_force[j];
  }
  s.voltage_gain = voltage_gain;
}

void Law::update(double t, const Vector& q, const Vector& dq, LawOutput& out) {
  Impl& m = *impl_;
  const LawSpec& s = m.spec;
  const int n = m.model.nv, p = braces();
  pin::computeAllTerms(m.model, m.data, q, dq);
  if (!m.started) {
    for (std::size_t k = 0; k < m.frames.size(); ++k)
      m.starts[k] = pin::updateFramePlacement(m.model, m.data, m.frames[k]).translation();
    m.started = true;
    m.last_time = t;
    m.rest = s.posture_rest.size() ? s.posture_rest : q;
  }
  const double dt = t - m.last_time;  // since the last update (force feedback's integral)
  m.last_time = t;
  out.force_command.resize(p);
  out.brace_desired.resize(p, 3);
  out.brace_actual.resize(p, 3);
  // l: the PD tasks along their axes (eq. 39)
  Vector l = Vector::Zero(n);
  Eigen::MatrixXd brace_jacobians(3 * p, n);
  Eigen::MatrixXd task_rows(0, n);  // the configured axes' Jacobian rows, stacked (the posture's null space)
  const bool stack_rows = m.posture;
  for (int k = 0; k <= p; ++k) {
    const Task& task = k ? s.braces[k - 1].task : s.hand;
    m.frame_jacobian.setZero();
    pin::getFrameJacobian(m.model, m.data, m.frames[k], pin::LOCAL_WORLD_ALIGNED, m.frame_jacobian);
    m.jacobian = m.frame_jacobian.topRows<3>();
    const Vector3 position = pin::updateFramePlacement(m.model, m.data, m.frames[k]).translation();
    const Vector3 velocity = m.jacobian * dq;
    Vector3 desired, desired_velocity;
    if (m.overridden[k]) {
      desired = m.reference_position[k];
      desired_velocity = m.reference_velocity[k];
    } else {
      task.path.sample(m.starts[k], t, desired, desired_velocity);
    }
    const Vector3 force = task.kp.cwiseProduct(desired - position) + task.kd.cwiseProduct(desired_velocity - velocity);
    l.noalias() += m.jacobian.transpose() * force;
    if (stack_rows) m.stack(task_rows, task.axes);
    if (k == 0) {
      out.hand_desired = desired;
      out.hand_actual = position;
    } else {
      out.brace_desired.row(k - 1) = desired.transpose();
      out.brace_actual.row(k - 1) = position.transpose();
      brace_jacobians.middleRows<3>(3 * (k - 1)) = m.jacobian;
    }
  }
  if (s.gravity_compensation) l += pin::computeGeneralizedGravity(m.model, m.data, q);
  if (m.posture) l += m.posture_torque(task_rows, q, dq);
  out.damped = false;
  if (p == 0) {
    out.torque = l;
  } else {
    pin::cholesky::decompose(m.model, m.data);
    // Per braced contact its normal row J_c and the row its force acts through, W = J_c - mu e^T J
    // (sliding: e the slip direction, regularised as the paper's or Coulomb's unit one; sticking:
    // W = J_c, the friction being tangential constraint forces instead, rows t^T J).
    Eigen::MatrixXd jc(p, n), w(p, n);
    Vector gamma(p), f_nd(p);
    std::vector<Vector3> accelerations(p), normals(p);
    std::vector<int> sticking;  // Coulomb contacts at rest: they stick (and the law keeps them stuck)
    for (int j = 0; j < p; ++j) {
      const BracedContact& brace = s.braces[j];
      const Contact& contact = brace.contact;
      const auto jacobian = brace_jacobians.middleRows<3>(3 * j);
      const Vector3 position = out.brace_actual.row(j).transpose();
      accelerations[j] =
          pin::getFrameClassicalAcceleration(m.model, m.data, m.frames[j + 1], pin::LOCAL_WORLD_ALIGNED).linear();
      double c;
      Matrix3 hessian;
      contact.surface.evaluate(position, c, normals[j], hessian);
      const Vector3& normal = normals[j];
      const Vector3 velocity = jacobian * dq;
      gamma[j] = normal.dot(accelerations[j]);
      if (contact.surface.kind != SurfaceKind::plane) gamma[j] += velocity.dot(hessian * velocity);
      const Vector3 slip = velocity - normal * normal.dot(velocity);
      const double speed = slip.norm();
      f_nd[j] = out.force_command[j] = m.force_command(j, normals[j], dt);
      jc.row(j).noalias() = normal.transpose() * jacobian;
      w.row(j) = jc.row(j);
      if (contact.friction == 0.0) continue;
      if (!contact.coulomb) {
        const Vector3 direction = slip / std::sqrt(speed * speed + s.slip_epsilon * s.slip_epsilon);
        w.row(j).noalias() -= contact.friction * (direction.transpose() * jacobian);  // J_c - mu J_t
      } else if (speed > kSlipAtRest) {  // sliding: |f_t| = mu |f_nd| against the slip d
        const Vector3 e = (f_nd[j] < 0.0 ? -1.0 : 1.0) * slip / speed;
        w.row(j).noalias() -= contact.friction * (e.transpose() * jacobian);
      } else {
        sticking.push_back(j);
      }
    }
    const Vector bias = m.data.nle + s.drive.damping.cwiseProduct(dq);  // h + g + Dc dq
    if (sticking.empty()) {
      Eigen::MatrixXd b(p, n);  // B = J_c Mc^-1 (Mc symmetric)
      for (int j = 0; j < p; ++j) {
        m.y_column = jc.row(j).transpose();
        pin::cholesky::solve(m.model, m.data, m.y_column);
        b.row(j) = m.y_column.transpose();
      }
      const Eigen::MatrixXd a_matrix = b * w.transpose();
      const Vector a_vector = b * bias - gamma;
      const Eigen::MatrixXd b_pinv =
          s.dynamically_consistent ? Eigen::MatrixXd((b * jc.transpose()).partialPivLu().solve(jc).transpose())
                                   : pseudo_inverse(b, s.damping_lambda, out.damped);
      // tau = B^+ (a - A f_nd) + (I - B^+ B) l = l + B^+ ((a - A f_nd) - B l)
      out.torque = l + b_pinv * (a_vector - a_matrix * f_nd - b * l);
    } else {
      // A sticking contact is a point constraint (its normal and tangential rows R, forces through
      // W): lambda = G^-1 (R Mc^-1 (h + g + Dc dq - tau) - gamma_R), G = R Mc^-1 W^T. The law asks
      // only the normal forces S lambda to be f_nd: C tau = e with C = S G^-1 R Mc^-1 and
      // e = S G^-1 (R Mc^-1 (h + g + Dc dq) - gamma_R) - f_nd; the null space of C leaves the
      // tangential forces free (docs/model.md, Control law under stick).
      std::vector<Vector3> tangents;
      std::vector<int> owner;
      for (int j : sticking) {
        Vector3 t[2];
        const int count = Dynamics::tangent_directions(normals[j], brace_jacobians.middleRows<3>(3 * j), t);
        for (int k = 0; k < count; ++k) {
          tangents.push_back(t[k]);
          owner.push_back(j);
        }
      }
      const int rows = p + static_cast<int>(tangents.size());
      Eigen::MatrixXd r(rows, n), wr(rows, n), y(n, rows);
      Vector gamma_r(rows);
      r.topRows(p) = jc;
      wr.topRows(p) = w;
      gamma_r.head(p) = gamma;
      for (std::size_t k = 0; k < tangents.size(); ++k) {
        const int i = p + static_cast<int>(k);
        r.row(i).noalias() = tangents[k].transpose() * brace_jacobians.middleRows<3>(3 * owner[k]);
        wr.row(i) = r.row(i);
        gamma_r[i] = tangents[k].dot(accelerations[owner[k]]);
      }
      for (int k = 0; k < rows; ++k) {
        m.y_column = r.row(k).transpose();
        pin::cholesky::solve(m.model, m.data, m.y_column);
        y.col(k) = m.y_column;  // Mc^-1 R^T
      }
      const Eigen::MatrixXd g = y.transpose() * wr.transpose();  // R Mc^-1 W^T
      // (least-norm where the rows are dependent, as the simulator solves them)
      const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> g_lu(g);
      const Eigen::MatrixXd g_inv_rows = g_lu.solve(y.transpose());  // G^-1 R Mc^-1 (d lambda = -this d tau)
      const Eigen::MatrixXd c_matrix = g_inv_rows.topRows(p);        // C = S G^-1 R Mc^-1
      const Vector e = g_inv_rows.topRows(p) * bias - g_lu.solve(gamma_r).head(p) - f_nd;
      Eigen::MatrixXd c_pinv;
      if (s.dynamically_consistent) {  // C^# = K^T (K Mc^-1 K^T)^-1 with K = S G^-1 R (C = K Mc^-1)
        const Eigen::MatrixXd k_rows = g_lu.solve(r).topRows(p);
        c_pinv = (c_matrix * k_rows.transpose()).partialPivLu().solve(k_rows).transpose();
      } else {
        c_pinv = pseudo_inverse(c_matrix, s.damping_lambda, out.damped);
      }
      out.torque = l + c_pinv * (e - c_matrix * l);
      // The tangential forces this torque asks of the sticking contacts; where one leaves the cone
      // |f_t| <= mu |f_nd|, the least torque in the null space of C (f_n stays f_nd) brings it back
      // onto the cone's surface (just inside: the simulator then holds the stick, as modelled).
      const Vector lambda = g_lu.solve(y.transpose() * (bias - out.torque) - gamma_r);
      Vector change = Vector::Zero(rows);
      bool outside = false;
      for (int j : sticking) {
        Vector3 force = Vector3::Zero();
        for (std::size_t k = 0; k < tangents.size(); ++k)
          if (owner[k] == j) force += lambda[p + static_cast<int>(k)] * tangents[k];
        const double limit = (1.0 - 1e-9) * s.braces[j].contact.friction * std::abs(f_nd[j]);
        if (force.norm() <= limit) continue;
        outside = true;
        const double scale = limit / force.norm() - 1.0;
        for (std::size_t k = 0; k < tangents.size(); ++k)
          if (owner[k] == j) change[p + static_cast<int>(k)] = scale * lambda[p + static_cast<int>(k)];
      }
      if (outside)  // -G^-1 R Mc^-1 d tau = change (its normal part zero): the least-norm d tau
        out.torque -= g_inv_rows.completeOrthogonalDecomposition().solve(change);
    }
  }
  out.command = voltage_command(out.torque, dq);
  m.saturated = s.command_limit > 0.0 && out.command.cwiseAbs().maxCoeff() >= s.command_limit;
}

namespace {

// Per braced contact of the law, its row in the simulator's contact list (matched by name).
std::vector<int> brace_rows(const Law& law, const Simulator& simulator) {
  std::vector<int> rows;
  const auto& contacts = simulator.dynamics().contacts();
  for (int j = 0; j < law.braces(); ++j) {
    int row = -1;
    for (std::size_t i = 0; i < contacts.size(); ++i)
      if (contacts[i].name == law.brace_name(j)) row = static_cast<int>(i);
    if (row < 0) throw std::invalid_argument("rollout: the simulator has no contact " + law.brace_name(j));
    rows.push_back(row);
  }
  return rows;
}

// What the law measures of the step just reported: each braced contact's force on the robot (through
// its sensor, if any); the temperatures at the state the step started from.
void measure_report(Law& law, const Simulator& simulator, const std::vector<int>& rows, const Vector& temperature,
                    Sensors* sensors) {
  const Answer& report = simulator.report;
  if (law.uses_force_feedback()) {
    for (std::size_t j = 0; j < rows.size(); ++j) {
      const int i = rows[j];
      const Vector3 normal = report.normals.row(i).transpose();
      const Vector3 force = report.force[i] * normal + report.tangential_force.row(i).transpose();
      law.measure_force(static_cast<int>(j), sensors ? sensors->force(force, normal) : force);
    }
  }
  if (law.uses_temperature()) law.measure_temperature(temperature);
}

void size_recording(long rows, int n, int p, int b, bool sensed, Recording& out) {
  out.time.setZero(rows);
  for (RowMatrix* a : {&out.position, &out.velocity, &out.current, &out.temperature, &out.command})
    a->setZero(rows, n);
  for (RowMatrix* a : {&out.measured_position, &out.measured_velocity}) a->setZero(sensed ? rows : 0, n);
  for (RowMatrix* a : {&out.hand_desired, &out.hand_actual, &out.energy}) a->setZero(rows, 3);
  for (RowMatrix* a : {&out.brace_desired, &out.brace_actual}) a->setZero(rows, 3 * b);
  for (RowMatrix* a : {&out.contact_position, &out.slip_velocity}) a->setZero(rows, 3 * p);
  for (RowMatrix* a : {&out.normal_force, &out.friction_force, &out.residual, &out.active}) a->setZero(rows, p);
  out.force_command.setZero(rows, b);
  out.rows = 0;
  out.status = 0;
}

}  // namespace

void rollout(Law& law, Simulator& simulator, long steps, double t0, double divergence_speed,
             double divergence_residual, Recording& out, Sensors* sensors) {
  const int n = simulator.nv(), p = simulator.dynamics().contact_count(), b = law.braces();
  const long rows = steps + 1;
  if (sensors && sensors->exact()) sensors = nullptr;  // the paper's exact, instant sensing: bit for bit as without
  size_recording(rows, n, p, b, sensors != nullptr, out);
  const std::vector<int> braced = brace_rows(law, simulator);
  LawOutput command;
  Vector q_measured, dq_measured;
  for (long k = 0; k < rows; ++k) {
    const double t = t0 + static_cast<double>(simulator.steps_taken) * simulator.step_size();
    const Vector& y = simulator.state();
    const Vector q = y.head(n), dq = y.segment(n, n);
    if (sensors) {
      sensors->joints(q, dq, q_measured, dq_measured);
      law.update(t, q_measured, dq_measured, command);
      out.measured_position.row(k) = q_measured.transpose();
      out.measured_velocity.row(k) = dq_measured.transpose();
      const RowMatrix truth = law.task_positions(q);  // what the metrics judge: where the arm really is
      command.hand_actual = truth.row(0).transpose();
      for (int j = 0; j < b; ++j) command.brace_actual.row(j) = truth.row(j + 1);
    } else {
      law.update(t, q, dq, command);
    }
    out.time[k] = t;
    out.position.row(k) = q.transpose();
    out.velocity.row(k) = dq.transpose();
    out.current.row(k) = y.segment(2 * n, n).transpose();
    const Vector temperature = y.segment(3 * n, n);
    out.temperature.row(k) = temperature.transpose();
    out.command.row(k) = command.command.transpose();
    out.hand_desired.row(k) = command.hand_desired.transpose();
    out.hand_actual.row(k) = command.hand_actual.transpose();
    out.brace_desired.row(k) = Eigen::Map<const Vector>(command.brace_desired.data(), 3 * b).transpose();
    out.brace_actual.row(k) = Eigen::Map<const Vector>(command.brace_actual.data(), 3 * b).transpose();
    if (b) out.force_command.row(k) = command.force_command.transpose();
    out.energy.row(k) << y[kStates * n], y[kStates * n + 1], y[kStates * n + 2];
    // the final state gets its reports without a step, as the simulator node's finish() does
    const Vector& applied = sensors ? sensors->delay(command.command) : command.command;
    if (k < steps) {
      const StepStatus status = simulator.step(applied);
      if (status != StepStatus::ok) {
        out.rows = k;
        out.status = static_cast<int>(status);
        return;
      }
    } else {
      simulator.evaluate(applied);
    }
    const Answer& report = simulator.report;
    out.contact_position.row(k) = Eigen::Map<const Vector>(report.positions.data(), 3 * p).transpose();
    out.slip_velocity.row(k) = Eigen::Map<const Vector>(report.slip.data(), 3 * p).transpose();
    for (int j = 0; j < p; ++j) {
      out.normal_force(k, j) = report.force[j];
      out.friction_force(k, j) = report.friction[j];
      out.residual(k, j) = report.residual[j];
      out.active(k, j) = simulator.report_modes().held[j] ? 1.0 : 0.0;
    }
    out.rows = k + 1;
    measure_report(law, simulator, braced, temperature, sensors);
    // where the simulator node refuses a step (the node asks the same function)
    out.status = simulator.refusal(divergence_speed, divergence_residual, out.measured);
    if (out.status) return;
  }
}

}  // namespace bracing_engine
