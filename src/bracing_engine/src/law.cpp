// The decoupled law on pinocchio (docs/model.md, Control law):
//
//   B = J_c Mc^-1,  A = B (J_c - mu J_t)^T,  a = B (h + g + Dc dq) - gamma
//   tau = B^+ (a - A f_nd) + (I - B^+ B) l,   v = K_V tau (voltage mode)
//   l = sum over the tasks of J^T [Kp (r_d - r) + Kd (dr_d - dr)] (+ g(q))
//
// and, with a Coulomb contact at rest, its point-constraint form (docs/model.md, Control law under stick).
#include "bracing_engine/law.hpp"

#include "geometry.hpp"
#include "model.hpp"

#include <pinocchio/algorithm/cholesky.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/spatial/explog.hpp>

#include <Eigen/Dense>
#include <Eigen/SVD>

#include <cmath>
#include <stdexcept>

namespace bracing_engine {

namespace pin = pinocchio;

// Smallest singular value of B (relative to its largest) below which B^+ is damped.
constexpr double kSingularRatio = 1e-8;

namespace {

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

// A differential drive's admissible motions: T = [0 S_b; 0 I] (n x n) from the rolling rows A = [A_b A_a]
// (`base` A_b's factor), S_b = -A_b^-1 A_a the base's velocities the actuated ones give (A T = 0).
void embed_rolling(const RowMatrix& rolling, const Eigen::PartialPivLU<Eigen::Matrix3d>& base, Eigen::MatrixXd& out) {
  const Eigen::Index n = rolling.cols(), m = n - 3;
  out.setZero(n, n);
  out.topRightCorner(3, m) = -base.solve(Eigen::MatrixXd(rolling.rightCols(m)));
  out.bottomRightCorner(m, m).setIdentity();
}

}  // namespace

// The braced contacts' rows at the law's state, per brace j: J_c, the row its force acts through,
// W = J_c - mu e^T J (sliding: e the slip direction, regularised as the paper's or Coulomb's unit one;
// sticking: W = J_c, the friction being tangential constraint forces instead, rows t^T J), gamma, f_cmd,
// and the Coulomb braces at rest (they stick, and the law keeps them stuck).
struct BraceRows {
  Eigen::MatrixXd jc, w;
  Vector gamma, f_nd;
  std::vector<Vector3> accelerations, normals;
  std::vector<int> sticking;
};

// How the arm, under the law's torque for a null-space input l, accelerates (acceleration gains): ddq at l and
// d ddq / d l, the contacts' forces as the law holds them and the sticking ones' reactions included.
struct ArmResponse {
  Vector acceleration;       // ddq [rad/s^2 or m/s^2]
  Eigen::MatrixXd mobility;  // n x n
};

struct Law::Impl {
  LawSpec spec;
  pin::Model model;
  mutable pin::Data data;
  LinkShapes shapes;      // the links' collision shapes (robot.collision_description)
  GeometryPoints points;  // the braces with point: geometry (the simulator's very points)
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
  // per task (0 the hand, 1 + j brace j): the integral of its position error [m s] on the axes with a ki
  std::vector<Vector3> task_integral;
  // the hand frame's orientation task: its target R_d (the first measured orientation unless configured) and
  // the integral of its error [rad s]
  bool orientation = false;
  Matrix3 orientation_target = Matrix3::Identity();
  Vector3 orientation_integral = Vector3::Zero();
  bool orientation_overridden = false;  // set_orientation_reference: R_d moves, at this angular velocity
  Vector3 orientation_velocity = Vector3::Zero();
  Vector temperature;  // the windings' measured temperatures [degC]
  Vector rest;         // the posture task's rest position (the first measured one unless configured)
  bool posture = false;
  // A differential drive (docs/model.md, Control law on a differential drive): the law runs on the admissible
  // motions dq = T dq, T = [0 S_b; 0 I] (the base's velocities those the wheels' rolling gives the actuated
  // ones), every Jacobian J T, Mc as T^T Mc T (the base block I, decoupled), the drifts plus J (dT dq).
  Wheels wheels;
  RowMatrix rolling;
  Vector rolling_drift, base_acceleration;  // dA dq; the base's acceleration at zero actuated acceleration
  Eigen::MatrixXd embed;                    // T (n x n)
  Eigen::LLT<Eigen::MatrixXd> reduced_mass;
  std::vector<Vector3> base_drifts;  // per task frame: J_base times the base's acceleration

  // T and the base's acceleration (`mass` false) or T^T Mc T's factor (`mass` true) at the state of the last
  // rigid_body_terms (rolling only).
  void reduce(const Vector& dq, bool mass);
  // Mc^-1 (or (T^T Mc T)^-1 when rolling) applied to the rows of R: row i of `out` becomes (Mc^-1 R_i^T)^T.
  template <typename Rows, typename Out>
  void inverse_rows(const Eigen::MatrixBase<Rows>& rows, Out&& out) {
    if (wheels)
      out = reduced_mass.solve(Eigen::MatrixXd(rows.transpose())).transpose();
    else
      mass_inverse_rows(model, data, rows, y_column, out);
  }
  // Mc's factor (pinocchio's Cholesky, or T^T Mc T's when rolling).
  void decompose() {
    if (wheels)
      reduce(Vector::Zero(0), true);
    else
      pin::cholesky::decompose(model, data);
  }

  // The rows of `jacobian` along `axes`, appended to `rows`.
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
    if (wheels) w.head<3>().setZero();  // the base has no motor
    if (rows.rows() == 0) return w;
    decompose();
    Eigen::MatrixXd y(n, rows.rows());  // Mc^-1 J^T
    inverse_rows(rows, y.transpose());
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

  // The stages of Law::update.
  // The first state's positions start the paths; returns the time since the last update.
  double advance_clock(double t, const Vector& q);
  // l: the PID tasks along their axes (eq. 39), each task's desired and actual positions into `out`; the
  // braces' Jacobians into `brace_jacobians` (3b x n) and, with a posture task or acceleration gains, the
  // configured rows into `task_rows`. With acceleration gains l is zero and the tasks' accelerations along
  // those rows go to `task_accelerations` instead (task_space_torque turns them into torques).
  Vector task_torque(double t, double dt, const Vector& dq, LawOutput& out, Eigen::MatrixXd& brace_jacobians,
                     Eigen::MatrixXd& task_rows, Vector& task_accelerations);
  // Appends task k's PID acceleration less its drift dJ dq along its axes to `accelerations` (acceleration gains).
  void stack_acceleration(int k, const Vector3& acceleration, Vector& accelerations) const;
  // F = kp e + kd de + ki * integral e of task k; its integral advanced by dt first (held while saturated).
  Vector3 task_output(int k, const Vector3& error, const Vector3& velocity_error, double dt);
  // kp e + kd de + ki z, z += e dt first on the axes with a ki (held while saturated; zeroed where ki is 0).
  Vector3 pid(const Vector3& kp, const Vector3& kd, const Vector3& ki, const Vector3& error,
              const Vector3& velocity_error, double dt, Vector3& integral) const;
  // The hand frame's orientation task (its angular rows): the moment into l, or with acceleration gains its
  // rows and angular accelerations (less dJ dq) appended; the error into `out`.
  void orientation_torque(const Vector& dq, double dt, LawOutput& out, Vector& l, Eigen::MatrixXd& task_rows,
                          Vector& task_accelerations);
  // J_s^T Lambda (a - J_s ddq): the input that gives the stacked task rows J_s the accelerations a (less their
  // drift dJ dq, already in a), Lambda^-1 = J_s X J_s^T with X = d ddq / d l, ddq the arm's acceleration without it.
  Vector task_space_torque(const Eigen::MatrixXd& task_rows, const Vector& accelerations,
                           const ArmResponse& response) const;
  // Mc^-1 x, from the Cholesky factor of the last decompose.
  Vector mass_solve(Vector x) const;
  // Mc^-1 (n x n), from the Cholesky factor of the last decompose.
  Eigen::MatrixXd mass_inverse();
  // The braced contacts' rows at the state of the last rigid_body_terms (f_cmd into `out`).
  BraceRows brace_rows(const Eigen::MatrixXd& brace_jacobians, const Vector& dq, double dt, LawOutput& out);
  // tau while no brace sticks: B^+ (a - A f_nd) + (I - B^+ B) l. `response` (if given): how the arm answers it.
  Vector sliding_torque(const BraceRows& rows, const Vector& bias, const Vector& l, bool& damped,
                        ArmResponse* response = nullptr);
  // tau with sticking braces: their point constraints' normal forces f_nd, their tangential forces in the cone.
  Vector sticking_torque(const BraceRows& rows, const Eigen::MatrixXd& brace_jacobians, const Vector& bias,
                         const Vector& l, bool& damped, ArmResponse* response = nullptr);
  // tau for l: the contacts' law (or l itself without braces).
  Vector contact_torque(const BraceRows* rows, const Eigen::MatrixXd& brace_jacobians, const Vector& bias,
                        const Vector& l, bool& damped, ArmResponse* response = nullptr);
};

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

double Law::null_space_speed(const Vector& dq) {
  Impl& m = *impl_;
  Eigen::MatrixXd rows(0, m.model.nv);
  for (std::size_t k = 0; k < m.frames.size(); ++k) {  // the Jacobians of the last update's pass
    m.jacobian = translational_jacobian(m.model, m.data, m.frames[k], m.frame_jacobian);
    if (m.wheels) m.jacobian = m.jacobian * m.embed;
    m.stack(rows, k ? m.spec.braces[k - 1].task.axes : m.spec.hand.axes);
    if (k == 0 && m.orientation) {  // the hand's angular rows
      m.jacobian = m.frame_jacobian.bottomRows<3>();
      if (m.wheels) m.jacobian = m.jacobian * m.embed;
      m.stack(rows, m.spec.orientation.axes);
    }
  }
  if (!m.wheels) return bracing_engine::null_space_speed(rows, dq);
  Vector moving = dq;  // the base moves as the wheels roll: not a joint of its own
  moving.head<3>().setZero();
  return bracing_engine::null_space_speed(rows, moving);
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
  rigid_body_terms(m.model, m.data, q0, zero);
  if (!m.points.empty()) m.points.place(m.model, m.data);
  if (m.wheels) m.reduce(zero, false);  // the admissible motions (the base's as the wheels roll)
  auto translational = [&](std::size_t k) {
    const Eigen::MatrixXd jacobian = translational_jacobian(m.model, m.data, m.frames[k], m.frame_jacobian);
    return m.wheels ? Eigen::MatrixXd(jacobian * m.embed) : jacobian;
  };
  auto task_row = [&](std::size_t k, int axis) -> Eigen::RowVectorXd {  // axis 3-5: the angular rows
    translational_jacobian(m.model, m.data, m.frames[k], m.frame_jacobian);
    return m.wheels ? Eigen::RowVectorXd(m.frame_jacobian.row(axis) * m.embed) : m.frame_jacobian.row(axis);
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
    if (task < 0 || task > p || axis < 0 || axis > (task == 0 ? 5 : 2))
      throw std::invalid_argument("allowed_task_rows: no such row");
    out.row(static_cast<Eigen::Index>(i)) = task_row(static_cast<std::size_t>(task), axis) * allowed;
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
    if (k == 0 && m.orientation)
      for (int axis : m.spec.orientation.axes) configured.emplace_back(0, 3 + axis);
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
                 const std::vector<Vector3>& brace_kd, const Vector& desired_normal_force, const Vector& voltage_gain,
                 const Vector3& hand_ki, const std::vector<Vector3>& brace_ki) {
  LawSpec& s = impl_->spec;
  const std::size_t b = s.braces.size();
  if (brace_kp.size() != b || brace_kd.size() != b || brace_ki.size() != b ||
      static_cast<std::size_t>(desired_normal_force.size()) != b || voltage_gain.size() != s.voltage_gain.size())
    throw std::invalid_argument("retune: sizes differ from the law's");
  s.hand.kp = hand_kp;
  s.hand.kd = hand_kd;
  s.hand.ki = hand_ki;
  for (std::size_t j = 0; j < b; ++j) {
    s.braces[j].task.kp = brace_kp[j];
    s.braces[j].task.kd = brace_kd[j];
    s.braces[j].task.ki = brace_ki[j];
    s.braces[j].desired_normal_force = desired_normal_force[j];
  }
  s.voltage_gain = voltage_gain;
}

Vector3 Law::task_integral(int task) const {
  if (task < 0 || task > braces()) throw std::out_of_range("task_integral: no such task");
  return impl_->task_integral[static_cast<std::size_t>(task)];
}

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

Vector3 Law::Impl::pid(const Vector3& kp, const Vector3& kd, const Vector3& ki, const Vector3& error,
                       const Vector3& velocity_error, double dt, Vector3& integral) const {
  const Vector3 force = kp.cwiseProduct(error) + kd.cwiseProduct(velocity_error);
  if (ki.isZero()) {  // the paper's PD, bit for bit; an integral whose gain went to zero is forgotten
    integral.setZero();
    return force;
  }
  for (int axis = 0; axis < 3; ++axis) {
    if (ki[axis] == 0.0)
      integral[axis] = 0.0;
    else if (!saturated)  // conditional integration: the anti-windup
      integral[axis] += error[axis] * dt;
  }
  return force + ki.cwiseProduct(integral);
}

Vector3 Law::Impl::task_output(int k, const Vector3& error, const Vector3& velocity_error, double dt) {
  const Task& task = k ? spec.braces[k - 1].task : spec.hand;
  return pid(task.kp, task.kd, task.ki, error, velocity_error, dt, task_integral[k]);
}

void Law::Impl::orientation_torque(const Vector& dq, double dt, LawOutput& out, Vector& l, Eigen::MatrixXd& task_rows,
                                   Vector& task_accelerations) {
  const OrientationTask& task = spec.orientation;
  frame_jacobian.setZero();
  pin::getFrameJacobian(model, data, frames[0], pin::LOCAL_WORLD_ALIGNED, frame_jacobian);
  Eigen::MatrixXd angular = frame_jacobian.bottomRows<3>();  // w = angular dq, world axes
  const Matrix3 rotation = pin::updateFramePlacement(model, data, frames[0]).rotation();
  out.orientation_error = pin::log3(Matrix3(orientation_target * rotation.transpose()));  // world axes
  // a moving reference's angular velocity in the damping (none otherwise: the configured law, bit for bit)
  const Vector3 velocity_error =
      orientation_overridden ? Vector3(orientation_velocity - angular * dq) : Vector3(-(angular * dq));
  const Vector3 moment =
      pid(task.kp, task.kd, task.ki, out.orientation_error, velocity_error, dt, orientation_integral);
  Vector3 drift =  // dJ dq: the frame's angular acceleration at ddq = 0
      pin::getFrameClassicalAcceleration(model, data, frames[0], pin::LOCAL_WORLD_ALIGNED).angular();
  if (wheels) {
    drift += angular.leftCols<3>() * base_acceleration;
    angular = angular * embed;
  }
  if (spec.acceleration_gains) {
    for (int axis : task.axes) {
      task_accelerations.conservativeResize(task_accelerations.size() + 1);
      task_accelerations[task_accelerations.size() - 1] = moment[axis] - drift[axis];
    }
  } else {
    l.noalias() += angular.transpose() * moment;
  }
  if (spec.acceleration_gains || posture) {
    for (int axis : task.axes) {
      task_rows.conservativeResize(task_rows.rows() + 1, Eigen::NoChange);
      task_rows.row(task_rows.rows() - 1) = angular.row(axis);
    }
  }
}

void Law::Impl::stack_acceleration(int k, const Vector3& acceleration, Vector& accelerations) const {
  const Task& task = k ? spec.braces[k - 1].task : spec.hand;
  // dJ dq: the frame's classical acceleration at ddq = 0 (rigid_body_terms' pass)
  Vector3 drift = pin::getFrameClassicalAcceleration(model, data, frames[k], pin::LOCAL_WORLD_ALIGNED).linear();
  if (wheels) drift += base_drifts[k];
  const Eigen::Index before = accelerations.size();
  accelerations.conservativeResize(before + static_cast<Eigen::Index>(task.axes.size()));
  for (std::size_t i = 0; i < task.axes.size(); ++i)
    accelerations[before + static_cast<Eigen::Index>(i)] = acceleration[task.axes[i]] - drift[task.axes[i]];
}

Vector Law::Impl::task_torque(double t, double dt, const Vector& dq, LawOutput& out, Eigen::MatrixXd& brace_jacobians,
                              Eigen::MatrixXd& task_rows, Vector& task_accelerations) {
  Vector l = Vector::Zero(model.nv);
  for (int k = 0; k < static_cast<int>(frames.size()); ++k) {
    const Task& task = k ? spec.braces[k - 1].task : spec.hand;
    jacobian = translational_jacobian(model, data, frames[k], frame_jacobian);
    const Vector3 position = pin::updateFramePlacement(model, data, frames[k]).translation();
    const Vector3 velocity = jacobian * dq;
    if (wheels) {  // the admissible motions' columns, the base's share of the drift
      base_drifts[k] = jacobian.leftCols<3>() * base_acceleration;
      jacobian = jacobian * embed;
    }
    Vector3 desired, desired_velocity;
    if (overridden[k]) {
      desired = reference_position[k];
      desired_velocity = reference_velocity[k];
    } else {
      task.path.sample(starts[k], t, desired, desired_velocity);
    }
    const Vector3 force = task_output(k, desired - position, desired_velocity - velocity, dt);
    if (spec.acceleration_gains) {
      stack_acceleration(k, force, task_accelerations);
      stack(task_rows, task.axes);
    } else {
      l.noalias() += jacobian.transpose() * force;
      if (posture) stack(task_rows, task.axes);
    }
    if (k == 0) {
      out.hand_desired = desired;
      out.hand_actual = position;
    } else {
      out.brace_desired.row(k - 1) = desired.transpose();
      out.brace_actual.row(k - 1) = position.transpose();
      brace_jacobians.middleRows<3>(3 * (k - 1)) = jacobian;
    }
  }
  return l;
}

BraceRows Law::Impl::brace_rows(const Eigen::MatrixXd& brace_jacobians, const Vector& dq, double dt, LawOutput& out) {
  const int n = model.nv, p = static_cast<int>(spec.braces.size());
  BraceRows rows{Eigen::MatrixXd(p, n), Eigen::MatrixXd(p, n), Vector(p), Vector(p), std::vector<Vector3>(p),
                 std::vector<Vector3>(p), {}};
  for (int j = 0; j < p; ++j) {
    const Contact& contact = spec.braces[j].contact;
    const auto jacobian = brace_jacobians.middleRows<3>(3 * j);
    const Vector3 position = out.brace_actual.row(j).transpose();
    rows.accelerations[j] =
        pin::getFrameClassicalAcceleration(model, data, frames[j + 1], pin::LOCAL_WORLD_ALIGNED).linear();
    if (wheels) rows.accelerations[j] += base_drifts[j + 1];
    const Vector3 velocity = jacobian * dq;
    const ContactPoint point = contact_point(contact.surface, position, velocity, rows.accelerations[j]);
    rows.normals[j] = point.normal;
    rows.gamma[j] = point.drift;
    const double speed = point.slip.norm();
    rows.f_nd[j] = out.force_command[j] = force_command(j, point.normal, dt);
    rows.jc.row(j).noalias() = point.normal.transpose() * jacobian;
    rows.w.row(j) = rows.jc.row(j);
    if (contact.friction == 0.0) continue;
    if (!contact.coulomb) {
      const Vector3 direction = point.slip / std::sqrt(speed * speed + spec.slip_epsilon * spec.slip_epsilon);
      subtract_friction(rows.w.row(j), contact.friction, direction, jacobian);  // J_c - mu J_t
    } else if (speed > kSlipAtRest) {  // sliding: |f_t| = mu |f_nd| against the slip d
      const Vector3 e = (rows.f_nd[j] < 0.0 ? -1.0 : 1.0) * point.slip / speed;
      subtract_friction(rows.w.row(j), contact.friction, e, jacobian);
    } else {
      rows.sticking.push_back(j);
    }
  }
  return rows;
}

Vector Law::Impl::sliding_torque(const BraceRows& rows, const Vector& bias, const Vector& l, bool& damped,
                                 ArmResponse* response) {
  const int n = model.nv, p = static_cast<int>(rows.jc.rows());
  Eigen::MatrixXd b(p, n);  // B = J_c Mc^-1 (Mc symmetric)
  inverse_rows(rows.jc, b);
  const Eigen::MatrixXd a_matrix = b * rows.w.transpose();
  const Vector a_vector = b * bias - rows.gamma;
  const Eigen::MatrixXd b_pinv =
      spec.dynamically_consistent
          ? Eigen::MatrixXd((b * rows.jc.transpose()).partialPivLu().solve(rows.jc).transpose())
          : pseudo_inverse(b, spec.damping_lambda, damped);
  // tau = B^+ (a - A f_nd) + (I - B^+ B) l = l + B^+ ((a - A f_nd) - B l)
  Vector torque = l + b_pinv * (a_vector - a_matrix * rows.f_nd - b * l);
  if (response) {  // f_n = f_cmd: Mc ddq = tau - bias + W^T f_cmd; B (I - B^+ B) = 0, so l leaves f_n alone
    response->acceleration = mass_solve(torque - bias + rows.w.transpose() * rows.f_nd);
    response->mobility = mass_inverse() * (Eigen::MatrixXd::Identity(n, n) - b_pinv * b);
  }
  return torque;
}

namespace {

// A sticking brace's point constraint: the normal rows of every brace (R = W as BraceRows has them),
// then each sticking brace's tangential rows t^T J (W = R), with their gamma.
struct StickRows {
  Eigen::MatrixXd r, wr;
  Vector gamma;
  std::vector<Vector3> tangents;
  std::vector<int> owner;  // the brace of each tangential row
};

StickRows stick_rows(const BraceRows& braces, const Eigen::MatrixXd& brace_jacobians) {
  const Eigen::Index p = braces.jc.rows(), n = braces.jc.cols();
  StickRows s;
  for (int j : braces.sticking) {
    Vector3 t[2];
    const int count = Dynamics::tangent_directions(braces.normals[j], brace_jacobians.middleRows<3>(3 * j), t);
    for (int k = 0; k < count; ++k) {
      s.tangents.push_back(t[k]);
      s.owner.push_back(j);
    }
  }
  const Eigen::Index rows = p + static_cast<Eigen::Index>(s.tangents.size());
  s.r.resize(rows, n);
  s.wr.resize(rows, n);
  s.gamma.resize(rows);
  s.r.topRows(p) = braces.jc;
  s.wr.topRows(p) = braces.w;
  s.gamma.head(p) = braces.gamma;
  for (std::size_t k = 0; k < s.tangents.size(); ++k) {
    const Eigen::Index i = p + static_cast<Eigen::Index>(k);
    s.r.row(i).noalias() = s.tangents[k].transpose() * brace_jacobians.middleRows<3>(3 * s.owner[k]);
    s.wr.row(i) = s.r.row(i);
    s.gamma[i] = s.tangents[k].dot(braces.accelerations[s.owner[k]]);
  }
  return s;
}

// The change of the tangential forces `lambda` (rows after the p normal ones) that brings each sticking
// brace whose |f_t| leaves the cone |f_t| <= mu |f_nd| back onto its surface, just inside (the simulator
// then holds the stick, as modelled); false if every one is inside.
bool cone_correction(const StickRows& s, const BraceRows& braces, const LawSpec& spec, const Vector& lambda,
                     Eigen::Index p, Vector& change) {
  change = Vector::Zero(lambda.size());
  bool outside = false;
  for (int j : braces.sticking) {
    Vector3 force = Vector3::Zero();
    for (std::size_t k = 0; k < s.tangents.size(); ++k)
      if (s.owner[k] == j) force += lambda[p + static_cast<int>(k)] * s.tangents[k];
    const double limit = (1.0 - 1e-9) * spec.braces[j].contact.friction * std::abs(braces.f_nd[j]);
    if (force.norm() <= limit) continue;
    outside = true;
    const double scale = limit / force.norm() - 1.0;
    for (std::size_t k = 0; k < s.tangents.size(); ++k)
      if (s.owner[k] == j) change[p + static_cast<int>(k)] = scale * lambda[p + static_cast<int>(k)];
  }
  return outside;
}

}  // namespace

Vector Law::Impl::sticking_torque(const BraceRows& rows, const Eigen::MatrixXd& brace_jacobians, const Vector& bias,
                                  const Vector& l, bool& damped, ArmResponse* response) {
  // A sticking contact is a point constraint (its normal and tangential rows R, forces through
  // W): lambda = G^-1 (R Mc^-1 (h + g + Dc dq - tau) - gamma_R), G = R Mc^-1 W^T. The law asks
  // only the normal forces S lambda to be f_nd: C tau = e with C = S G^-1 R Mc^-1 and
  // e = S G^-1 (R Mc^-1 (h + g + Dc dq) - gamma_R) - f_nd; the null space of C leaves the
  // tangential forces free (docs/model.md, Control law under stick).
  const Eigen::Index p = rows.jc.rows();
  const StickRows s = stick_rows(rows, brace_jacobians);
  Eigen::MatrixXd y(model.nv, s.r.rows());  // Mc^-1 R^T
  inverse_rows(s.r, y.transpose());
  const Eigen::MatrixXd g = y.transpose() * s.wr.transpose();  // R Mc^-1 W^T
  // (least-norm where the rows are dependent, as the simulator solves them)
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> g_lu(g);
  const Eigen::MatrixXd g_inv_rows = g_lu.solve(y.transpose());  // G^-1 R Mc^-1 (d lambda = -this d tau)
  const Eigen::MatrixXd c_matrix = g_inv_rows.topRows(p);        // C = S G^-1 R Mc^-1
  const Vector e = g_inv_rows.topRows(p) * bias - g_lu.solve(s.gamma).head(p) - rows.f_nd;
  Eigen::MatrixXd c_pinv;
  if (spec.dynamically_consistent) {  // C^# = K^T (K Mc^-1 K^T)^-1 with K = S G^-1 R (C = K Mc^-1)
    const Eigen::MatrixXd k_rows = g_lu.solve(s.r).topRows(p);
    c_pinv = (c_matrix * k_rows.transpose()).partialPivLu().solve(k_rows).transpose();
  } else {
    c_pinv = pseudo_inverse(c_matrix, spec.damping_lambda, damped);
  }
  // tau for l: l + C^+ (e - C l); where a sticking contact's tangential force would leave the cone, the
  // least torque in the null space of C (f_n stays f_nd) brings it back onto it.
  auto torque_for = [&](const Vector& task_input) {
    Vector torque = task_input + c_pinv * (e - c_matrix * task_input);
    const Vector lambda = g_lu.solve(y.transpose() * (bias - torque) - s.gamma);
    Vector change;
    if (cone_correction(s, rows, spec, lambda, p, change))  // -G^-1 R Mc^-1 d tau = change (its normal part zero)
      torque -= g_inv_rows.completeOrthogonalDecomposition().solve(change);
    return torque;
  };
  const Vector torque = torque_for(l);
  if (response) {  // ddq = Mc^-1 (tau - bias + W^T lambda), lambda = G^-1 (R Mc^-1 (bias - tau) - gamma_R): the held rows
    const Vector lambda = g_lu.solve(y.transpose() * (bias - torque) - s.gamma);
    response->acceleration = mass_solve(torque - bias + s.wr.transpose() * lambda);
    const int n = model.nv;
    Eigen::MatrixXd w_inverse(s.wr.rows(), n);  // W Mc^-1
    inverse_rows(s.wr, w_inverse);
    // d tau / d l: (I - C^+ C) and the cone's correction (piecewise affine in l: a difference is exact in its piece)
    Eigen::MatrixXd torque_rate(n, n);
    const double h = 1e-6 * std::max(1.0, l.cwiseAbs().maxCoeff());
    for (int i = 0; i < n; ++i) {
      Vector nudged = l;
      nudged[i] += h;
      torque_rate.col(i) = (torque_for(nudged) - torque) / h;
    }
    response->mobility = (mass_inverse() - w_inverse.transpose() * g_inv_rows) * torque_rate;
  }
  return torque;
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

Vector Law::Impl::task_space_torque(const Eigen::MatrixXd& task_rows, const Vector& accelerations,
                                    const ArmResponse& response) const {
  if (task_rows.rows() == 0) return Vector::Zero(model.nv);
  const Eigen::MatrixXd inverse_inertia = task_rows * response.mobility * task_rows.transpose();  // Lambda^-1
  // least squares where the rows are dependent (a singular posture): no force along a direction nothing moves
  const Vector forces =
      inverse_inertia.completeOrthogonalDecomposition().solve(accelerations - task_rows * response.acceleration);
  return task_rows.transpose() * forces;
}

Vector Law::Impl::contact_torque(const BraceRows* rows, const Eigen::MatrixXd& brace_jacobians, const Vector& bias,
                                 const Vector& l, bool& damped, ArmResponse* response) {
  if (!rows) {
    if (response) {
      response->acceleration = mass_solve(l - bias);
      response->mobility = mass_inverse();
    }
    return l;
  }
  return rows->sticking.empty() ? sliding_torque(*rows, bias, l, damped, response)
                                : sticking_torque(*rows, brace_jacobians, bias, l, damped, response);
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
