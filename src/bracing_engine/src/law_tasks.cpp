// The law's tasks (docs/model.md, Control law): l = sum over the tasks of J^T [Kp (r_d - r) + Kd (dr_d - dr)],
// their acceleration-gain form, and the checks of their rows' rank.
#include "law_impl.hpp"

#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/spatial/explog.hpp>

#include <Eigen/Dense>
#include <Eigen/SVD>

#include <stdexcept>

namespace bracing_engine {

namespace {

// max |(I - J^+ J) dq|: the joints' motion that no task row sees [rad/s or m/s].
double null_space_speed(const Eigen::MatrixXd& rows, const Vector& dq) {
  if (dq.size() == 0) return 0.0;
  if (rows.rows() == 0) return dq.cwiseAbs().maxCoeff();
  const Vector seen = rows.completeOrthogonalDecomposition().solve(rows * dq);  // J^+ J dq
  return (dq - seen).cwiseAbs().maxCoeff();
}

// Whether the smallest singular value of `rows` is negligible (the rank check's tolerance).
bool rank_deficient(const Eigen::MatrixXd& rows) {
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(rows);
  const auto& sigma = svd.singularValues();
  return sigma[sigma.size() - 1] <= 1e-6 * std::max(sigma[0], 1.0);
}

}  // namespace

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

Vector Law::Impl::task_space_torque(const Eigen::MatrixXd& task_rows, const Vector& accelerations,
                                    const ArmResponse& response) const {
  if (task_rows.rows() == 0) return Vector::Zero(model.nv);
  const Eigen::MatrixXd inverse_inertia = task_rows * response.mobility * task_rows.transpose();  // Lambda^-1
  // least squares where the rows are dependent (a singular posture): no force along a direction nothing moves
  const Vector forces =
      inverse_inertia.completeOrthogonalDecomposition().solve(accelerations - task_rows * response.acceleration);
  return task_rows.transpose() * forces;
}

}  // namespace bracing_engine
