// The law's state and its stages (private to the engine): law.cpp holds the law's set-up and update,
// law_tasks.cpp its tasks' terms, law_contacts.cpp the braces' rows and the torque that holds their forces.
#pragma once

#include "bracing_engine/law.hpp"

#include "geometry.hpp"
#include "model.hpp"

#include <pinocchio/algorithm/cholesky.hpp>

#include <Eigen/Dense>

#include <vector>

namespace bracing_engine {

namespace pin = pinocchio;

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

}  // namespace bracing_engine
