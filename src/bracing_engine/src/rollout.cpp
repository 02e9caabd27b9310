// The closed loop (law + simulator) stepped in C++: what the nodes do in lockstep, recorded per state.
#include <algorithm>
#include <stdexcept>

#include "bracing_engine/law.hpp"

namespace bracing_engine {

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

void size_recording(long rows, int n, int p, int b, bool sensed, bool thermal, bool orients, Recording& out) {
  out.time.setZero(rows);
  for (RowMatrix* a : {&out.position, &out.velocity, &out.current, &out.command}) a->setZero(rows, n);
  out.temperature.setZero(rows, thermal ? n : 0);  // as motor_state carries it: no columns without the model
  for (RowMatrix* a : {&out.measured_position, &out.measured_velocity}) a->setZero(sensed ? rows : 0, n);
  for (RowMatrix* a : {&out.hand_desired, &out.hand_actual, &out.energy}) a->setZero(rows, 3);
  for (RowMatrix* a : {&out.brace_desired, &out.brace_actual}) a->setZero(rows, 3 * b);
  for (RowMatrix* a : {&out.contact_position, &out.slip_velocity}) a->setZero(rows, 3 * p);
  for (RowMatrix* a : {&out.normal_force, &out.friction_force, &out.residual}) a->setZero(rows, p);
  out.active.setZero(rows, p);
  out.force_command.setZero(rows, b);
  out.hand_orientation_error.setZero(rows, orients ? 3 : 0);
  out.rows = 0;
  out.step_status = StepStatus::ok;
  out.refusal = Refusal::none;
}

// The law's answer to the true state (q, dq) at t, read through the sensors if any (row k then records
// what the law measured, and the true task positions: what the metrics judge).
void answer(Law& law, Sensors* sensors, double t, const Vector& q, const Vector& dq, long k, LawOutput& command,
            Recording& out) {
  if (!sensors) {
    law.update(t, q, dq, command);
    return;
  }
  Vector q_measured, dq_measured;
  sensors->joints(q, dq, q_measured, dq_measured);
  law.update(t, q_measured, dq_measured, command);
  out.measured_position.row(k) = q_measured.transpose();
  out.measured_velocity.row(k) = dq_measured.transpose();
  const RowMatrix truth = law.task_positions(q);
  command.hand_actual = truth.row(0).transpose();
  for (int j = 0; j < command.brace_actual.rows(); ++j) command.brace_actual.row(j) = truth.row(j + 1);
}

// Row k: the state y at t and the law's answer to it.
void record_state(long k, double t, const Vector& y, const LawOutput& command, Recording& out) {
  const Eigen::Index n = command.command.size(), b = command.brace_desired.rows();
  out.time[k] = t;
  out.position.row(k) = y.head(n).transpose();
  out.velocity.row(k) = y.segment(n, n).transpose();
  out.current.row(k) = y.segment(2 * n, n).transpose();
  if (out.temperature.cols()) out.temperature.row(k) = y.segment(3 * n, n).transpose();
  out.command.row(k) = command.command.transpose();
  out.hand_desired.row(k) = command.hand_desired.transpose();
  out.hand_actual.row(k) = command.hand_actual.transpose();
  out.brace_desired.row(k) = Eigen::Map<const Vector>(command.brace_desired.data(), 3 * b).transpose();
  out.brace_actual.row(k) = Eigen::Map<const Vector>(command.brace_actual.data(), 3 * b).transpose();
  if (b) out.force_command.row(k) = command.force_command.transpose();
  if (out.hand_orientation_error.cols()) out.hand_orientation_error.row(k) = command.orientation_error.transpose();
  const Eigen::Index energies = kStates * n;
  out.energy.row(k) << y[energies + energy::consumed], y[energies + energy::net], y[energies + energy::copper_loss];
}

// Row k: the simulator's report of the step from row k's state (or of the final state, no step taken).
void record_report(long k, const Simulator& simulator, Recording& out) {
  const Answer& report = simulator.report;
  const Eigen::Index p = report.force.size();
  out.contact_position.row(k) = Eigen::Map<const Vector>(report.positions.data(), 3 * p).transpose();
  out.slip_velocity.row(k) = Eigen::Map<const Vector>(report.slip.data(), 3 * p).transpose();
  for (Eigen::Index j = 0; j < p; ++j) {
    out.normal_force(k, j) = report.force[j];
    out.friction_force(k, j) = report.friction[j];
    out.residual(k, j) = report.residual[j];
    out.active(k, j) = simulator.report_modes().held[j];
  }
}

// `command` with each |value| saturated to its joint's limit (0: none), as the simulator node saturates one.
Vector saturated(const Vector& command, const Vector& limit) {
  Vector out = command;
  for (Eigen::Index i = 0; i < out.size() && i < limit.size(); ++i)
    if (limit[i] > 0.0) out[i] = std::clamp(out[i], -limit[i], limit[i]);
  return out;
}

// The recording cut to the rows the rollout filled.
void keep_filled_rows(Recording& r) {
  r.time.conservativeResize(r.rows);
  for (RowMatrix* a : {&r.position, &r.velocity, &r.current, &r.temperature, &r.command, &r.hand_desired,
                       &r.hand_actual, &r.brace_desired, &r.brace_actual, &r.contact_position, &r.slip_velocity,
                       &r.normal_force, &r.friction_force, &r.residual, &r.energy, &r.measured_position,
                       &r.measured_velocity, &r.force_command, &r.hand_orientation_error})
    a->conservativeResize(std::min<Eigen::Index>(r.rows, a->rows()), Eigen::NoChange);
  r.active.conservativeResize(r.rows, Eigen::NoChange);
}

// A differential drive's rolling residual max |A v| [m/s] at each recorded state (empty without one).
void record_rolling_residual(const Dynamics& dynamics, Recording& out) {
  out.rolling_residual.resize(dynamics.rolling_rows() ? out.rows : 0);
  Answer terms;
  for (Eigen::Index k = 0; k < out.rolling_residual.size(); ++k) {
    dynamics.terms(out.position.row(k).transpose(), out.velocity.row(k).transpose(), terms);
    out.rolling_residual[k] = terms.rolling_velocity.cwiseAbs().maxCoeff();
  }
}

// The loop of rollout(): rows filled up to where it stops.
void step_and_record(Law& law, Simulator& simulator, long steps, std::int64_t t0_ns, double divergence_speed,
                     double divergence_residual, Recording& out, Sensors* sensors, const Vector& command_limit) {
  const int n = simulator.nv();
  const long rows = steps + 1;
  const std::vector<int> braced = brace_rows(law, simulator);
  LawOutput command;
  const bool limited = command_limit.size() && command_limit.maxCoeff() > 0.0;
  Vector limited_command;
  for (long k = 0; k < rows; ++k) {
    const double t = stamp_seconds(t0_ns + simulator.steps_taken * simulator.step_ns());  // as the node reads it
    const Vector& y = simulator.state();
    const Vector temperature = y.segment(3 * n, n);  // what the law measures with the step's report
    answer(law, sensors, t, y.head(n), y.segment(n, n), k, command, out);
    record_state(k, t, y, command, out);
    // the final state gets its reports without a step, as the simulator node's finish() does
    if (limited) limited_command = saturated(command.command, command_limit);
    const Vector& sent = limited ? limited_command : command.command;  // what the simulator node applies
    const Vector& applied = sensors ? sensors->delay(sent) : sent;
    if (k < steps) {
      const StepStatus status = simulator.step(applied);
      if (status != StepStatus::ok) {
        out.rows = k;
        out.step_status = status;
        return;
      }
    } else {
      simulator.evaluate(applied);
    }
    record_report(k, simulator, out);
    out.rows = k + 1;
    measure_report(law, simulator, braced, temperature, sensors);
    // where the simulator node refuses a step (the node asks the same function)
    out.refusal = simulator.refusal(divergence_speed, divergence_residual, out.measured);
    if (out.refusal != Refusal::none) return;
  }
}

}  // namespace

void rollout(Law& law, Simulator& simulator, long steps, std::int64_t t0_ns, double divergence_speed,
             double divergence_residual, Recording& out, Sensors* sensors, const Vector& command_limit) {
  const int n = simulator.nv(), p = simulator.dynamics().contact_count(), b = law.braces();
  if (sensors && sensors->exact()) sensors = nullptr;  // the paper's exact, instant sensing: bit for bit as without
  size_recording(steps + 1, n, p, b, sensors != nullptr, simulator.dynamics().drive().thermal, law.orients(), out);
  out.desired_normal_force = law.desired_normal_force();
  out.command_limit = command_limit;
  step_and_record(law, simulator, steps, t0_ns, divergence_speed, divergence_residual, out, sensors, command_limit);
  keep_filled_rows(out);
  record_rolling_residual(simulator.dynamics(), out);
}

}  // namespace bracing_engine
