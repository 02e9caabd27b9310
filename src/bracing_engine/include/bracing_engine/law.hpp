// The decoupled force/position law (docs/model.md, Control law; paper eqs. 36-41), the task
// trajectories, and the closed-loop rollout (law + simulator stepped in C++).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "bracing_engine/engine.hpp"

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

  // Desired position and velocity at t, given the first measured position `start`.
  void sample(const Vector3& start, double t, Vector3& position, Vector3& velocity) const;
};

// A PD task on a frame's origin along world axes: the gains are per world axis (zero: unused).
struct Task {
  std::string frame;
  Vector3 kp = Vector3::Zero(), kd = Vector3::Zero();
  Path path;
  std::vector<int> axes;  // the world axes it uses, as configured (the rank check names them)
};

struct BracedContact {
  Contact contact;  // frame, surface, mu (the law's contact model: f_t = mu f_n along the slip)
  double desired_normal_force = 0.0;  // f_nd [N]
  Task task;                          // the brace task (its frame is the contact's)
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
};

struct LawOutput {
  Vector command, torque;
  Vector3 hand_desired, hand_actual;
  RowMatrix brace_desired, brace_actual;  // b x 3
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
  // Forget the paths' starts (a new run begins).
  void reset();
  // The tunable values: task gains (per world axis), f_nd and K_V.
  void retune(const Vector3& hand_kp, const Vector3& hand_kd, const std::vector<Vector3>& brace_kp,
              const std::vector<Vector3>& brace_kd, const Vector& desired_normal_force, const Vector& voltage_gain);
  // The first configured task axis (hand axes, then each brace's) that adds no rank to the stacked
  // task Jacobian at q0 within the motions the braced contacts allow (the null space of J_c):
  // (task index: 0 the hand, 1 + j brace j; world axis), or (-1, -1) if every axis adds one.
  std::pair<int, int> first_rankless_axis(const Vector& q0);
  int nv() const;
  int braces() const;
  Vector desired_normal_force() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// What a closed-loop rollout records per state k = 0..steps (as the nodes publish it in lockstep).
struct Recording {
  Vector time;                                   // (N+1)
  RowMatrix position, velocity, current;         // (N+1) x n
  RowMatrix temperature;                         // (N+1) x n: the windings' T [degC]
  RowMatrix command;                             // (N+1) x n
  RowMatrix hand_desired, hand_actual;           // (N+1) x 3
  RowMatrix brace_desired, brace_actual;         // (N+1) x 3b
  RowMatrix contact_position, slip_velocity;     // (N+1) x 3p
  RowMatrix normal_force, friction_force;        // (N+1) x p
  RowMatrix residual, active;                    // (N+1) x p (active: 1/0)
  RowMatrix energy;                              // (N+1) x 3: consumed, net, copper loss up to the step's start
  long rows = 0;                                 // rows filled
  int status = 0;  // 0 ok; 1 diverged, 2 joint limit (in the step of the last row); 3 non-finite forces,
                   // 4 too fast, 5 residual (after the last row's step)
  double measured = 0.0;  // the speed [rad/s] or residual [m] of status 4 / 5
};

// The closed loop (law + simulator) for `steps` steps from the simulator's state at time t0 +
// steps_taken * h; the last row is the final state, answered and evaluated without a step. Stops
// early where the simulator node would refuse a step (status).
void rollout(Law& law, Simulator& simulator, long steps, double t0, double divergence_speed,
             double divergence_residual, Recording& out);

}  // namespace bracing_engine
