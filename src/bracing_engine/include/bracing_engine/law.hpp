// The decoupled force/position law (docs/model.md, Control law; paper eqs. 36-41), the task
// trajectories, and the closed-loop rollout (law + simulator stepped in C++).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "bracing_engine/engine.hpp"
#include "bracing_engine/sensors.hpp"

namespace bracing_engine {

enum class PathKind { hold = 0, circle = 1, waypoints = 2 };

// A task point's desired path (bracing_core.trajectory.TrajectoryConfig).
struct Path {
  PathKind kind = PathKind::hold;
  Vector3 center = Vector3::Zero();
  double radius = 0.0, period = 1.0, direction = 1.0, phase = 0.0;
  int u = 1, v = 2;  // circle plane: world axis indices
  bool has_point = false;
  Vector3 point = Vector3::Zero();  // hold; without a point: the first measured position
  std::vector<Vector3> waypoints;
  double segment_time = 1.0;
  double start_ramp = 0.0;  // [s] > 0: the path starts at the first measured position, at rest (paths.cpp)

  // Desired position and velocity at t, given the first measured position `start`.
  void sample(const Vector3& start, double t, Vector3& position, Vector3& velocity) const;

 private:
  // The path at its own time tau (no start ramp).
  void sample_at(const Vector3& start, double tau, Vector3& position, Vector3& velocity) const;
};

// A PID task on a frame's origin along world axes: the gains are per world axis (zero: unused).
// F = kp e + kd de + ki * integral of e dt, e = r_d - r: a force [N] (stiffness gains) or, with
// LawSpec::acceleration_gains, the task acceleration [m/s^2] the task-space inertia turns into one.
struct Task {
  std::string frame;
  Vector3 kp = Vector3::Zero(), kd = Vector3::Zero();
  Path path;
  std::vector<int> axes;  // the world axes it uses, as configured (the rank check names them)
  Vector3 ki = Vector3::Zero();  // integral gains (zero: no integral on that axis)
};

// The hand frame's orientation held about world axes (not in the paper): the error is the rotation's log map
// in world axes, e = log(R_d R^T), and the moment kp e - kd w + ki * integral of e dt (w the frame's angular
// velocity, world axes; kd (w_d - w) while a reference turns R_d: Law::set_orientation_reference); with
// acceleration gains an angular acceleration, as Task's.
struct OrientationTask {
  std::vector<int> axes;  // world axes it uses (empty: no orientation task)
  Vector3 kp = Vector3::Zero(), kd = Vector3::Zero(), ki = Vector3::Zero();  // per world axis
  bool has_target = false;
  Matrix3 target = Matrix3::Identity();  // R_d; without a target: the hand frame's first measured orientation
};

struct BracedContact {
  Contact contact;  // frame, surface, mu (the law's contact model: f_t = mu f_n along the slip)
  double desired_normal_force = 0.0;  // f_nd [N]
  Task task;                          // the brace task (its frame is the contact's)
  // Force feedback (not in the paper; 0 0: its feed-forward law): the force fed to eqs. (38)/(40) is
  // f_cmd = f_nd + kp (f_nd - f_meas) + ki * integral of (f_nd - f_meas) dt, f_meas the measured normal force.
  double feedback_kp = 0.0;  // dimensionless
  double feedback_ki = 0.0;  // [1/s]
};

struct LawSpec {
  Robot robot;
  Drive drive;          // added_inertia (J_m in voltage mode) and damping Dc; voltage: v = K_V tau
  Vector voltage_gain;  // K_V (diagonal), model order
  Task hand;
  std::vector<BracedContact> braces;
  bool gravity_compensation = false;  // add g(q) to l (not in the paper)
  double damping_lambda = 1e-6;       // damped inverse for a near-singular B
  bool dynamically_consistent = false;  // B^# = J_c^T (J_c Mc^-1 J_c^T)^-1 instead of B^+
  double slip_epsilon = 1e-4;
  // v = K_V tau R(T) / R_20 from the measured winding temperatures (voltage mode, thermal drive): the
  // current, and so the torque, the law asks for stays as the windings warm (not in the paper).
  bool thermal_compensation = false;
  // |command| per joint (model order) where the motors saturate (0 or empty: none): the integrals' anti-windup
  Vector command_limit;
  // The motor model inverted (voltage mode; not in the paper): v = R tau / K_m + K_m dq, R = R(T) with thermal
  // compensation, else R_20: the motor delivers the law's torque in steady state, back-EMF and all (K_V unused).
  bool back_emf_compensation = false;
  // A posture task in the null space of the tasks (not in the paper; zeros: none): l += N^T (kp (rest - q) - kd dq),
  // N^T = I - J^T (J Mc^-1 J^T)^-1 J Mc^-1 for the stacked task rows J, so it leaves the tasks' accelerations alone.
  Vector posture_kp, posture_kd;  // per joint (empty: zeros) [N m/rad or N/m], [N m s/rad or N s/m]
  Vector posture_rest;            // per joint [rad or m]; empty: the first measured position
  // Gains in acceleration units (not in the paper): the stacked task forces are Lambda a, a the tasks' PID
  // accelerations and Lambda^-1 = J_s Mc^-1 N J_s^T (J_s the configured axes' rows, N the law's null-space
  // projector, with the sticking contacts' reactions), so each task axis accelerates as its gains say on any arm.
  bool acceleration_gains = false;
  OrientationTask orientation;  // the hand frame's (no axes: none)
};

struct LawOutput {
  Vector command, torque;
  Vector3 hand_desired, hand_actual;
  RowMatrix brace_desired, brace_actual;  // b x 3
  Vector force_command;                   // b: f_cmd [N], the force the law asked for (f_nd without feedback)
  Vector3 orientation_error = Vector3::Zero();  // log(R_d R^T) of the hand frame [rad], world axes (an orientation task)
  bool damped = false;
};

class Law {
 public:
  explicit Law(const LawSpec& spec);
  ~Law();
  Law(const Law&) = delete;
  Law& operator=(const Law&) = delete;

  // The command for the measured state (q, dq) at time t [s]. The task paths start from the
  // first state's positions.
  void update(double t, const Vector& q, const Vector& dq, LawOutput& out);
  // Forget the paths' starts, the force feedback's integral and the measurements (a new run begins).
  void reset();
  // Brace j's measured force on the robot [N], world axes (its contact sensor): the feedback's f_meas is
  // its component along the law's surface normal at the next update.
  void measure_force(int brace, const Vector3& force);
  // The windings' measured temperatures [degC] (thermal compensation; ambient until the first).
  void measure_temperature(const Vector& temperature);
  // Targets while running: task k (0 the hand, 1 + j brace j) follows this desired position and velocity
  // instead of its path from the next update on, until clear_reference(k) or reset().
  void set_reference(int task, const Vector3& position, const Vector3& velocity);
  void clear_reference(int task);
  // Targets while running: the orientation task holds R_d = `rotation` (world) turning at `angular_velocity`
  // [rad/s] (world axes: the damping's desired angular velocity) from the next update on, until reset().
  void set_orientation_reference(const Matrix3& rotation, const Vector3& angular_velocity);
  // The orientation task's R_d now (after the first update: the configured target or the first measured one).
  Matrix3 orientation_reference() const;
  // Task k's configured path at t (desired position, velocity), from its first measured position.
  std::pair<Vector3, Vector3> path_sample(int task, double t) const;
  bool uses_force_feedback() const;  // a brace has a feedback gain
  bool uses_temperature() const;     // thermal compensation applies (voltage mode, thermal drive)
  // The command of the law's torque at the measured velocity dq: tau (torque mode), K_V tau (eq. 41), or the
  // motor inverted (back_emf_compensation); times R(T) / R_20 with thermal compensation.
  Vector voltage_command(const Vector& torque, const Vector& dq) const;
  const std::string& brace_name(int brace) const;
  // max |(I - J^+ J) dq| over the joints [rad/s or m/s], J the task rows at the last update's q: joint motion
  // that no task sees (the controller asks now and then, not every update: 1 us each).
  double null_space_speed(const Vector& dq);
  // The admissible motions' map T at q (n x n, dq = T dq; docs/model.md, Control law on a differential drive):
  // [0 S_b; 0 I] from the law's rolling rows with a differential drive, else the identity.
  Eigen::MatrixXd motion_map(const Vector& q) const;
  // The hand's and each brace point's positions at q (the law's kinematics): b + 1 rows.
  RowMatrix task_positions(const Vector& q);
  // The tunable values: task gains (per world axis), f_nd and K_V. An integral gain set to zero clears its
  // integral; one set from zero starts its integral at zero (no kick).
  void retune(const Vector3& hand_kp, const Vector3& hand_kd, const std::vector<Vector3>& brace_kp,
              const std::vector<Vector3>& brace_kd, const Vector& desired_normal_force, const Vector& voltage_gain,
              const Vector3& hand_ki, const std::vector<Vector3>& brace_ki);
  // Task k's integral of the position error [m s] (0 the hand, 1 + j brace j), world axes.
  Vector3 task_integral(int task) const;
  // The first configured task axis (hand axes, the hand's orientation axes, then each brace's) that adds no
  // rank to the stacked task Jacobian at q0 within the motions the braced contacts allow (the null space of
  // J_c): (task index: 0 the hand, 1 + j brace j; world axis 0-2, or 3-5 for the hand's rotation about
  // axis - 3), or (-1, -1) if every axis adds one.
  std::pair<int, int> first_rankless_axis(const Vector& q0);
  // The rank of those rows (task index, axis as above: any, configured or not) at q0 within the
  // motions the braced contacts allow, with first_rankless_axis's tolerance: how many free directions
  // they have (what its messages count).
  int task_rank(const Vector& q0, const std::vector<std::pair<int, int>>& rows);
  int nv() const;
  int braces() const;
  bool orients() const;  // an orientation task (its axes not empty)
  Vector desired_normal_force() const;

 private:
  // Rows (task index: 0 the hand, 1 + j brace j; world axis, 3-5 the hand's angular rows) of the task
  // Jacobians at q0, times I - J_c^+ J_c (the motions the braced contacts allow).
  Eigen::MatrixXd allowed_task_rows(const Vector& q0, const std::vector<std::pair<int, int>>& rows);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// What a closed-loop rollout records per state k = 0..steps (as the nodes publish it in lockstep), cut to the
// rows filled.
struct Recording {
  using BoolRowMatrix = Eigen::Matrix<bool, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  Vector time;                                   // (N+1)
  RowMatrix position, velocity, current;         // (N+1) x n
  RowMatrix temperature;                         // (N+1) x n: the windings' T [degC]; 0 columns without a thermal drive
  RowMatrix command;                             // (N+1) x n
  RowMatrix hand_desired, hand_actual;           // (N+1) x 3
  RowMatrix brace_desired, brace_actual;         // (N+1) x 3b
  RowMatrix contact_position, slip_velocity;     // (N+1) x 3p
  RowMatrix normal_force, friction_force;        // (N+1) x p
  RowMatrix residual;                            // (N+1) x p
  BoolRowMatrix active;                          // (N+1) x p: held
  RowMatrix energy;                              // (N+1) x 3: consumed, net, copper loss up to the step's start
  // With sensors: what the controller received, (N+1) x n (0 rows without); hand_actual and brace_actual
  // then hold the true positions (the law's kinematics at the true q), not the law's measured ones.
  RowMatrix measured_position, measured_velocity;
  RowMatrix force_command;                       // (N+1) x b: f_cmd of each brace [N]
  RowMatrix hand_orientation_error;              // (N+1) x 3: the hand frame's log(R_d R^T) [rad]; 0 columns without the task
  Vector rolling_residual;                       // (N+1): a differential drive's max |A v| [m/s]; empty without one
  Vector desired_normal_force;                   // b: the law's f_nd [N]
  Vector command_limit;                          // the |command| saturation the rollout applied (per joint, 0: none)
  long rows = 0;                                 // rows filled
  StepStatus step_status = StepStatus::ok;       // not ok: the step from the last row's state was not taken
  Refusal refusal = Refusal::none;               // not none: the node refuses the step after the last row
  double measured = 0.0;                         // the refusal's speed, temperature or residual
};

// The closed loop (law + simulator) for `steps` steps from the simulator's state stamped t0_ns +
// steps_taken * step_ns [ns] (its time: stamp_seconds of that, as the controller node reads it); the last row is the final state, answered and evaluated without a step. Stops
// early where the simulator node would refuse a step (step_status, refusal). `sensors` (may be null: exact and
// instant): what the law reads of each state and when its commands land. The law's force feedback
// reads each braced contact's force of the previous step's report, its thermal compensation the
// previous state's temperatures: what the nodes have when they answer a state in lockstep. `command_limit`
// (per joint, model order; 0 or empty: none): each applied |command| is saturated to it, as the simulator node
// saturates a motor_command (the recording keeps the law's command, as the bag does).
void rollout(Law& law, Simulator& simulator, long steps, std::int64_t t0_ns, double divergence_speed,
             double divergence_residual, Recording& out, Sensors* sensors = nullptr,
             const Vector& command_limit = Vector());

}  // namespace bracing_engine
