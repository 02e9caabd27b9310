// Python bindings of the control side: task paths, tasks and braced contacts, the law and what it is built
// from, the sensors, and the closed loop with its recording (the model and the simulator: bindings.cpp).
#include "bindings.hpp"

namespace bracing_engine::bindings {

namespace {

using ReadOnlyPoints = nb::ndarray<nb::numpy, const double, nb::ndim<3>>;
using ReadOnlyColumn = nb::ndarray<nb::numpy, const double, nb::ndim<1>>;

// A recording's member as a read-only view of its memory, which it keeps alive (the policy below).
template <typename Scalar>
nb::ndarray<nb::numpy, const Scalar, nb::ndim<2>> matrix_view(
    const Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& m) {
  return {m.data(), {static_cast<size_t>(m.rows()), static_cast<size_t>(m.cols())}, nb::handle()};
}

ReadOnlyColumn vector_view(const Vector& v) { return {v.data(), {static_cast<size_t>(v.size())}, nb::handle()}; }

// A rows x 3k member as (rows, k, 3).
ReadOnlyPoints points_view(const RowMatrix& m) {
  const auto rows = static_cast<size_t>(m.rows()), points = static_cast<size_t>(m.cols() / 3);
  return ReadOnlyPoints(m.data(), {rows, points, 3}, nb::handle(), {static_cast<int64_t>(m.cols()), 3, 1});
}

// One column of a member.
ReadOnlyColumn column_view(const RowMatrix& m, Eigen::Index column) {
  return ReadOnlyColumn(m.data() + column, {static_cast<size_t>(m.rows())}, nb::handle(),
                        {static_cast<int64_t>(m.cols())});
}

}  // namespace

// Task paths, tasks and braced contacts.
void bind_tasks(nb::module_& m) {
  nb::class_<Path>(m, "Path")
      .def(
          "__init__",
          [](Path* path, PathKind kind, const Vector3& center, double radius, double period, double direction, double phase,
             int u, int v, std::optional<Vector3> point, std::vector<Vector3> waypoints, double segment_time,
             double start_ramp) {
            new (path) Path{kind,         center,        radius,
                            period,       direction,     phase,
                            u,            v,             point.has_value(),
                            point.value_or(Vector3::Zero()), std::move(waypoints), segment_time,
                            start_ramp};
          },
          nb::kw_only(), "kind"_a, "center"_a, "radius"_a, "period"_a, "direction"_a, "phase"_a, "u"_a, "v"_a,
          "point"_a.none(),
          "waypoints"_a, "segment_time"_a, "start_ramp"_a = 0.0)
      .def(
          "sample",
          [](const Path& path, const Vector3& start, double t) {
            Vector3 position, velocity;
            path.sample(start, t, position, velocity);
            return nb::make_tuple(position, velocity);
          },
          "start"_a, "t"_a);

  nb::class_<Task>(m, "Task").def(
      "__init__",
      [](Task* task, std::string frame, const Vector3& kp, const Vector3& kd, const Path& path,
         std::vector<int> axes, const Vector3& ki) {
        new (task) Task{std::move(frame), kp, kd, path, std::move(axes), ki};
      },
      nb::kw_only(), "frame"_a, "kp"_a, "kd"_a, "path"_a, "axes"_a, "ki"_a = Vector3(Vector3::Zero()),
      "gains per world axis (zero: an axis the task does not use); the world axes it uses; integral gains");

  nb::class_<OrientationTask>(m, "OrientationTask")
      .def(
          "__init__",
          [](OrientationTask* task, std::vector<int> axes, const Vector3& kp, const Vector3& kd, const Vector3& ki,
             std::optional<Matrix3> target) {
            new (task) OrientationTask{std::move(axes), kp, kd, ki, target.has_value(),
                                       target.value_or(Matrix3(Matrix3::Identity()))};
          },
          nb::kw_only(), "axes"_a = std::vector<int>(), "kp"_a = Vector3(Vector3::Zero()),
          "kd"_a = Vector3(Vector3::Zero()),
          "ki"_a = Vector3(Vector3::Zero()), "target"_a.none() = nb::none(),
          "the hand frame's orientation held about world axes (gains per world axis); target R_d, None: the first "
          "measured orientation");

  nb::class_<BracedContact>(m, "BracedContact")
      .def(
          "__init__",
          [](BracedContact* brace, const Contact& contact, double desired_normal_force, const Task& task,
             double feedback_kp, double feedback_ki) {
            new (brace) BracedContact{contact, desired_normal_force, task, feedback_kp, feedback_ki};
          },
          nb::kw_only(), "contact"_a, "desired_normal_force"_a, "task"_a, "feedback_kp"_a = 0.0,
          "feedback_ki"_a = 0.0,
          "feedback: f_cmd = f_nd + kp (f_nd - f_meas) + ki * integral (f_nd - f_meas) dt (0 0: the paper's law)");
}

// What a law is built from (LawSpec), keyword by keyword.
void bind_law_spec(nb::module_& m) {
  nb::class_<LawSpec>(m, "LawSpec", "what a Law is built from")
      .def(
          "__init__",
          [](LawSpec* spec, const Robot& robot, const Drive& drive, Vector voltage_gain, const Task& hand,
             std::vector<BracedContact> braces, bool gravity_compensation, double damping_lambda,
             bool dynamically_consistent, double slip_epsilon, bool thermal_compensation, Vector command_limit,
             bool back_emf_compensation, Vector posture_kp, Vector posture_kd, Vector posture_rest,
             bool acceleration_gains, const OrientationTask& orientation) {
            new (spec) LawSpec{robot, drive, std::move(voltage_gain), hand, std::move(braces), gravity_compensation,
                               damping_lambda, dynamically_consistent, slip_epsilon, thermal_compensation,
                               std::move(command_limit), back_emf_compensation, std::move(posture_kp),
                               std::move(posture_kd), std::move(posture_rest), acceleration_gains, orientation};
          },
          nb::kw_only(), "robot"_a, "drive"_a, "voltage_gain"_a, "hand"_a, "braces"_a,
          "gravity_compensation"_a = false, "damping_lambda"_a = 1e-6, "dynamically_consistent"_a = false,
          "slip_epsilon"_a = 1e-4, "thermal_compensation"_a = false, "command_limit"_a = Vector(),
          "back_emf_compensation"_a = false, "posture_kp"_a = Vector(), "posture_kd"_a = Vector(),
          "posture_rest"_a = Vector(), "acceleration_gains"_a = false, "orientation"_a = OrientationTask(),
          "voltage_gain: K_V, model order; command_limit: |command| per joint where the motors saturate (empty: "
          "none); posture_*: the null-space posture task per joint (empty: none; posture_rest empty: the first "
          "measured position)")
      BRACING_RO(LawSpec, robot) BRACING_RO(LawSpec, drive) BRACING_RO(LawSpec, voltage_gain)
      BRACING_RO(LawSpec, hand) BRACING_RO(LawSpec, braces) BRACING_RO(LawSpec, gravity_compensation)
      BRACING_RO(LawSpec, damping_lambda) BRACING_RO(LawSpec, dynamically_consistent)
      BRACING_RO(LawSpec, slip_epsilon) BRACING_RO(LawSpec, thermal_compensation) BRACING_RO(LawSpec, command_limit)
      BRACING_RO(LawSpec, back_emf_compensation) BRACING_RO(LawSpec, posture_kp) BRACING_RO(LawSpec, posture_kd)
      BRACING_RO(LawSpec, posture_rest) BRACING_RO(LawSpec, acceleration_gains) BRACING_RO(LawSpec, orientation);
}

// The control law.
void bind_law(nb::module_& m) {
  nb::class_<LawOutput>(m, "LawOutput")
      .def_rw("command", &LawOutput::command, "v [V] or tau [N m], model order (a drive's base command adds to it)")
      .def_rw("torque", &LawOutput::torque, "tau of eq. 38 [N m]")
      BRACING_RO(LawOutput, hand_desired) BRACING_RO(LawOutput, hand_actual)
      BRACING_RO_DOC(LawOutput, brace_desired, "b x 3") BRACING_RO_DOC(LawOutput, brace_actual, "b x 3")
      BRACING_RO_DOC(LawOutput, force_command, "f_cmd per brace [N] (f_nd without feedback)")
      BRACING_RO_DOC(LawOutput, orientation_error, "the hand frame's log(R_d R^T) [rad], world axes")
      BRACING_RO(LawOutput, damped);
  nb::class_<Law>(m, "Law")
      .def(nb::init<const LawSpec&>(), "spec"_a)
      .def(
          "update",
          [](Law& law, double t, const Vector& q, const Vector& dq) {
            LawOutput o;
            law.update(t, q, dq, o);
            return o;
          },
          "t"_a, "q"_a, "dq"_a, "the command for the measured state (q, dq) at t")
      .def("reset", &Law::reset)
      .def("set_reference", &Law::set_reference, "task"_a, "position"_a, "velocity"_a,
           "task k (0 the hand, 1 + j brace j) follows this desired position and velocity instead of its path")
      .def("clear_reference", &Law::clear_reference, "task"_a, "task k follows its path again")
      .def("set_orientation_reference", &Law::set_orientation_reference, "rotation"_a, "angular_velocity"_a,
           "the orientation task holds R_d = rotation (world), turning at angular_velocity [rad/s], from the next "
           "update on")
      .def("orientation_reference", &Law::orientation_reference, "the orientation task's R_d now")
      .def("path_sample", &Law::path_sample, "task"_a, "t"_a, "task k's configured path at t: (position, velocity)")
      .def("measure_force", &Law::measure_force, "brace"_a, "force"_a,
           "brace j's measured force on the robot [N], world axes (force feedback reads its normal component)")
      .def("measure_temperature", &Law::measure_temperature, "temperature"_a,
           "the windings' measured temperatures [degC] (thermal compensation)")
      .def_prop_ro("uses_force_feedback", &Law::uses_force_feedback)
      .def_prop_ro("uses_temperature", &Law::uses_temperature)
      .def("motion_map", &Law::motion_map, "q"_a,
           "T (n x n) at q: dq = T dq over the motions a differential drive's rolling allows ([0 S_b; 0 I], the "
           "base's velocities those the wheels give), else the identity")
      .def("task_positions", &Law::task_positions, "q"_a, "the hand's and each brace point's positions at q")
      .def("null_space_speed", &Law::null_space_speed, "dq"_a,
           "max |(I - J^+ J) dq| [rad/s or m/s], J the task rows at the last update's q")
      .def("first_rankless_axis", &Law::first_rankless_axis, "q0"_a,
           "(task: 0 the hand, 1 + j brace j; world axis) of the first axis adding no rank at q0, or (-1, -1)")
      .def("task_rank", &Law::task_rank, "q0"_a, "rows"_a,
           "the rank at q0 of the rows [(task: 0 the hand, 1 + j brace j; world axis)] within the motions the "
           "braced contacts allow")
      .def("retune", &Law::retune, "hand_kp"_a, "hand_kd"_a, "brace_kp"_a, "brace_kd"_a, "desired_normal_force"_a,
           "voltage_gain"_a, "hand_ki"_a, "brace_ki"_a)
      .def("task_integral", &Law::task_integral, "task"_a,
           "task k's integral of its position error [m s] (0 the hand, 1 + j brace j), world axes")
      .def_prop_ro("desired_normal_force", &Law::desired_normal_force);
}

// What a real arm measures.
void bind_sensors(nb::module_& m) {
  nb::class_<SensorSpec>(m, "SensorSpec", "what a Sensors measures and how late its commands land")
      .def(
          "__init__",
          [](SensorSpec* spec, double step, Mask revolute, unsigned long long seed, long encoder_counts_per_rev,
             double position_noise, double velocity_noise, double velocity_filter_hz, double force_noise,
             double force_bias, double current_noise, long command_latency_steps) {
            new (spec) SensorSpec{seed,        encoder_counts_per_rev, position_noise,        velocity_noise,
                                  velocity_filter_hz, force_noise,     force_bias,            current_noise,
                                  command_latency_steps, step,         std::move(revolute)};
          },
          nb::kw_only(), "step"_a, "revolute"_a, "seed"_a = 0, "encoder_counts_per_rev"_a = 0,
          "position_noise"_a = 0.0, "velocity_noise"_a = 0.0, "velocity_filter_hz"_a = 0.0, "force_noise"_a = 0.0,
          "force_bias"_a = 0.0, "current_noise"_a = 0.0, "command_latency_steps"_a = 0,
          "step [s]: the control period; revolute: per joint, the encoder's grid applies; noises are sigmas [rad "
          "or m, rad/s or m/s, N, A]; force_bias [N] along the contact's normal")
      BRACING_RO(SensorSpec, step) BRACING_RO(SensorSpec, revolute) BRACING_RO(SensorSpec, seed)
      BRACING_RO(SensorSpec, encoder_counts_per_rev) BRACING_RO(SensorSpec, position_noise)
      BRACING_RO(SensorSpec, velocity_noise) BRACING_RO(SensorSpec, velocity_filter_hz)
      BRACING_RO(SensorSpec, force_noise) BRACING_RO(SensorSpec, force_bias) BRACING_RO(SensorSpec, current_noise)
      BRACING_RO(SensorSpec, command_latency_steps);
  nb::class_<Sensors>(m, "Sensors")
      .def(nb::init<const SensorSpec&, int>(), "spec"_a, "n"_a, "for n joints")
      .def_prop_ro("exact", &Sensors::exact)
      .def_prop_ro("exact_joints", &Sensors::exact_joints)
      .def(
          "joints",
          [](Sensors& s, const Vector& q, const Vector& dq) {
            Vector q_out, dq_out;
            s.joints(q, dq, q_out, dq_out);
            return std::make_pair(q_out, dq_out);
          },
          "q"_a, "dq"_a, "(q, dq) as measured; call once per state, in order")
      .def("force", &Sensors::force, "force"_a, "normal"_a, "a contact sensor's reading [N]")
      .def(
          "currents",
          [](Sensors& s, const Vector& current) {
            Vector out;
            s.currents(current, out);
            return out;
          },
          "current"_a)
      .def(
          "delay", [](Sensors& s, const Vector& command) { return Vector(s.delay(command)); }, "command"_a,
          "the command to apply now (the answer command_latency_steps states ago; zero before the first lands)")
      .def("take_back", &Sensors::take_back, "undo the last delay() (its step was refused)")
      .def("reset", &Sensors::reset);
}

// The closed loop and its recording.
void bind_recording(nb::module_& m) {
  constexpr auto view = nb::rv_policy::reference_internal;
// A member bound as a read-only view (VIEW: matrix_view or vector_view) under its own name.
#define RECORDING_VIEW(VIEW, field, doc) \
  .def_prop_ro(#field, [](const Recording& r) { return VIEW(r.field); }, view, doc)
  nb::class_<Recording>(m, "Recording", "per state k = 0..rows-1, as the nodes publish it in lockstep; arrays are "
                                        "read-only views of its memory")
      .def(nb::init<>(), "empty, for rollout to fill (rollout.RunResult derives from it)")
      RECORDING_VIEW(vector_view, time, "(rows,) [s]")
      RECORDING_VIEW(matrix_view, position, "(rows, n) [rad or m], model order")
      RECORDING_VIEW(matrix_view, velocity, "(rows, n) [rad/s or m/s]")
      RECORDING_VIEW(matrix_view, current, "(rows, n) [A]")
      RECORDING_VIEW(matrix_view, command, "(rows, n) [V or N m], the law's (before saturation)")
      RECORDING_VIEW(matrix_view, temperature, "(rows, n) [degC] the windings' (0 columns without a thermal drive)")
      RECORDING_VIEW(matrix_view, hand_desired, "(rows, 3) [m]")
      RECORDING_VIEW(matrix_view, hand_actual, "(rows, 3) [m]")
      .def_prop_ro("brace_desired", [](const Recording& r) { return points_view(r.brace_desired); }, view,
                   "(rows, b, 3) [m], the braced contacts'")
      .def_prop_ro("brace_actual", [](const Recording& r) { return points_view(r.brace_actual); }, view,
                   "(rows, b, 3) [m]")
      .def_prop_ro("contact_position", [](const Recording& r) { return points_view(r.contact_position); }, view,
                   "(rows, p, 3) [m], the simulator's contact points")
      .def_prop_ro("slip_velocity", [](const Recording& r) { return points_view(r.slip_velocity); }, view,
                   "(rows, p, 3) [m/s]")
      RECORDING_VIEW(matrix_view, normal_force, "(rows, p) [N]")
      RECORDING_VIEW(matrix_view, friction_force, "(rows, p) [N]")
      RECORDING_VIEW(matrix_view, residual, "(rows, p) [m], each contact's C")
      RECORDING_VIEW(matrix_view, active, "(rows, p) held")
      .def_prop_ro("energy_consumed", [](const Recording& r) { return column_view(r.energy, 0); }, view,
                   "[J] consumed up to the step's start (EnergySlot.consumed)")
      .def_prop_ro("energy_net", [](const Recording& r) { return column_view(r.energy, 1); }, view,
                   "[J] net (EnergySlot.net)")
      .def_prop_ro("copper_loss", [](const Recording& r) { return column_view(r.energy, 2); }, view,
                   "[J] copper loss (EnergySlot.copper_loss)")
      RECORDING_VIEW(matrix_view, measured_position, "(rows, n) what the law read (0 rows without sensors)")
      RECORDING_VIEW(matrix_view, measured_velocity, "(rows, n) (0 rows without sensors)")
      RECORDING_VIEW(matrix_view, force_command, "(rows, b) [N]")
      RECORDING_VIEW(matrix_view, hand_orientation_error,
                     "(rows, 3): the hand's log(R_d R^T) [rad] (0 columns without the task)")
      RECORDING_VIEW(vector_view, rolling_residual, "a differential drive's max |A v| [m/s] (empty: none)")
      RECORDING_VIEW(vector_view, desired_normal_force, "(b,) the law's f_nd [N]")
      RECORDING_VIEW(vector_view, command_limit, "the |command| saturation applied (per joint, 0: none)")
      .def_ro("step_status", &Recording::step_status, "not ok: the step from the last row's state was refused")
      .def_ro("refusal", &Recording::refusal, "not none: the node refuses the step after the last row")
      .def_ro("measured", &Recording::measured, "the refusal's speed, temperature or residual");
#undef RECORDING_VIEW
}

void bind_rollout(nb::module_& m) {
  bind_recording(m);
  m.def(
      "rollout",
      [](Law& law, Simulator& simulator, long steps, std::int64_t t0_ns, double divergence_speed, double divergence_residual,
         Recording& out, Sensors* sensors, const Vector& command_limit) {
        nb::gil_scoped_release release;
        rollout(law, simulator, steps, t0_ns, divergence_speed, divergence_residual, out, sensors, command_limit);
      },
      "law"_a, "simulator"_a, "steps"_a, "t0_ns"_a, "divergence_speed"_a, "divergence_residual"_a, "out"_a,
      "sensors"_a.none() = nb::none(), "command_limit"_a = Vector(),
      "The closed loop for `steps` steps (and the final state's answer), all in C++, into `out` (a fresh "
      "Recording): stopped early where a step is refused (step_status) or the node would refuse it (refusal); "
      "each applied |command| saturated to command_limit (per joint, 0: none), the recording keeping the law's.");
}

}  // namespace bracing_engine::bindings
