// Python bindings (nanobind: ~0.2 us a call, the lightest of the C++ binding libraries). Arrays
// cross by copy, so nothing Python keeps changes under it.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include "bracing_engine/engine.hpp"
#include "bracing_engine/law.hpp"
#include "bracing_engine/sensors.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace bracing_engine;

namespace {

// The whole answer in one array (one allocation crossing to Python, sliced there: see
// bracing_core.dynamics._packed_layout): ddq, di, f_n, effort (n, n, p, n), friction and constraint
// power, then the contact terms (positions 3p, jacobians 3pn, J_c pn, J_t pn, drift p, residual p,
// slip 3p, direction 3p, normals 3p), the friction force on the robot (3p), its size (p), which
// contacts were held (p, 1/0) and which of those stuck (p, 1/0).
Vector packed(const Answer& a, const ContactModes& modes) {
  const Eigen::Index n = a.ddq.size(), p = a.force.size();
  Vector out(4 * n + p + 2 + 3 * p + 3 * p * n + 2 * p * n + 2 * p + 9 * p + 3 * p + p + p + p);
  Eigen::Index at = 0;
  auto put = [&](const auto& block) {
    const Eigen::Index size = block.size();
    if (size) out.segment(at, size) = Eigen::Map<const Vector>(block.data(), size);
    at += size;
  };
  put(a.ddq);
  put(a.di);
  put(a.force);
  put(a.effort);
  out[at++] = a.friction_power;
  out[at++] = a.constraint_power;
  for (const RowMatrix* m : {&a.positions, &a.jacobians, &a.normal_jacobian, &a.tangent_jacobian}) put(*m);
  put(a.drift);
  put(a.residual);
  for (const RowMatrix* m : {&a.slip, &a.direction, &a.normals, &a.tangential_force}) put(*m);
  put(a.friction);
  for (Eigen::Index j = 0; j < p; ++j) out[at++] = modes.held[j] ? 1.0 : 0.0;
  for (Eigen::Index j = 0; j < p; ++j) out[at++] = modes.sticking[j] ? 1.0 : 0.0;
  return out;
}

}  // namespace

NB_MODULE(_engine, m) {
  m.doc() = "The bracing engine: constrained robot + motor-circuit dynamics and RK4 on pinocchio (C++).";
  m.attr("PINOCCHIO_VERSION") = compiled_pinocchio_version();
  m.attr("WINDING_TEMPERATURE_LIMIT") = kWindingTemperatureLimit;  // [degC], Simulator::refusal code 6
  nb::exception<SingularError>(m, "SingularError", PyExc_ArithmeticError);

  nb::class_<Surface>(m, "Surface")
      .def_static(
          "plane",
          [](const Vector3& normal, double offset) {
            Surface s;
            s.kind = SurfaceKind::plane;
            s.normal = normal;
            s.offset = offset;
            return s;
          },
          "normal"_a, "offset"_a)
      .def_static(
          "sphere",
          [](const Vector3& center, double radius, bool inside) {
            Surface s;
            s.kind = SurfaceKind::sphere;
            s.center = center;
            s.radius = radius;
            s.inside = inside;
            return s;
          },
          "center"_a, "radius"_a, "inside"_a)
      .def_static(
          "cylinder",
          [](const Vector3& point, const Vector3& axis, double radius, bool inside) {
            Surface s;
            s.kind = SurfaceKind::cylinder;
            s.center = point;
            s.axis = axis;
            s.radius = radius;
            s.inside = inside;
            return s;
          },
          "point"_a, "axis"_a, "radius"_a, "inside"_a);

  nb::class_<Contact>(m, "Contact")
      .def(
          "__init__",
          [](Contact* c, std::string name, std::string frame, const Surface& surface, double friction,
             bool unilateral, bool enforced, bool coulomb) {
            new (c) Contact{std::move(name), std::move(frame), surface, friction, unilateral, enforced, coulomb};
          },
          "name"_a, "frame"_a, "surface"_a, "friction"_a, "unilateral"_a, "enforced"_a, "coulomb"_a);

  nb::class_<Robot>(m, "Robot")
      .def(
          "__init__",
          [](Robot* r, std::string urdf_path, const Vector3& gravity, std::vector<std::string> locked_joints,
             std::vector<double> locked_positions, double mass_scale) {
            new (r) Robot{std::move(urdf_path), gravity, std::move(locked_joints), std::move(locked_positions),
                          mass_scale};
          },
          "urdf_path"_a, "gravity"_a, "locked_joints"_a, "locked_positions"_a, "mass_scale"_a = 1.0,
          "mass_scale: every moving link's mass and rotational inertia times this (a plant's model error)");

  nb::class_<Drive>(m, "Drive")
      .def(
          "__init__",
          [](Drive* d, bool voltage, Vector added_inertia, Vector damping, Vector torque_constant, Vector resistance,
             Vector inductance, Vector reflected_damping, bool thermal, Vector thermal_resistance, Vector heat_capacity,
             double ambient, double temperature_coefficient) {
            new (d) Drive{voltage,          added_inertia,   damping,    torque_constant,
                          resistance,       inductance,      reflected_damping, thermal,
                          thermal_resistance, heat_capacity, ambient,    temperature_coefficient};
          },
          "voltage"_a, "added_inertia"_a, "damping"_a, "torque_constant"_a, "resistance"_a, "inductance"_a,
          "reflected_damping"_a, "thermal"_a, "thermal_resistance"_a, "heat_capacity"_a, "ambient"_a,
          "temperature_coefficient"_a,
          "resistance: R_20 at 20 degC; thermal: R(T) = R_20 (1 + alpha (T - 20)), C_th dT/dt = R(T) i^2 - (T - "
          "ambient) / R_th");

  nb::class_<Dynamics>(m, "Dynamics")
      .def(nb::init<const Robot&, const Drive&, std::vector<Contact>, double, double>(), "robot"_a, "drive"_a,
           "contacts"_a, "slip_epsilon"_a, "baumgarte"_a)
      .def_prop_ro("nv", &Dynamics::nv)
      .def_prop_ro("joint_names", &Dynamics::joint_names)
      .def_rw("baumgarte", &Dynamics::baumgarte)
      .def(
          "evaluate_packed",
          [](const Dynamics& d, const Vector& q, const Vector& dq, const Vector& current, const Vector& temperature,
             const Vector& u, const Mask& held) {
            Answer a;
            ContactModes modes{held, Mask(held.size(), false), RowMatrix::Zero(held.size(), 3),
                               Vector::Ones(held.size())};
            d.evaluate(q, dq, current, temperature, u, modes, true, a);
            return packed(a, modes);
          },
          "q"_a, "dq"_a, "current"_a, "temperature"_a, "u"_a, "held"_a, "temperature: the windings' T [degC]")
      .def(
          "terms_packed",
          [](const Dynamics& d, const Vector& q, const Vector& dq) {
            Answer a;
            d.terms(q, dq, a);
            const auto p = static_cast<std::size_t>(d.contact_count());
            return packed(a, ContactModes{Mask(p, false), Mask(p, false), RowMatrix::Zero(p, 3), Vector::Ones(p)});
          },
          "q"_a, "dq"_a, "every contact's terms at (q, dq), packed as an answer with no force (no solve)")
      .def("project", &Dynamics::project, "q"_a, "rows"_a, "tolerance"_a = 1e-13)
      .def(
          "impact",
          [](const Dynamics& d, Vector q, Vector dq, const std::vector<int>& rows) {
            const double loss = d.impact(q, dq, rows);
            return nb::make_tuple(q, dq, loss);
          },
          "q"_a, "dq"_a, "rows"_a);

  nb::class_<Simulator>(m, "Simulator")
      .def(nb::init<std::shared_ptr<const Dynamics>, double, int, const Vector&, const Vector&, const Vector&,
                    const Vector&>(),
           "dynamics"_a, "step"_a, "substeps"_a, "q0"_a, "dq0"_a, "lower_limits"_a, "upper_limits"_a)
      .def(
          "step_packed",
          [](Simulator& s, const Vector& u) {
            const int status = static_cast<int>(s.step(u));
            return std::make_pair(status, status ? Vector() : packed(s.report, s.report_modes()));
          },
          "u"_a, "(0 ok, 1 diverged, 2 joint limit (failed_joint; the state is unchanged unless 0), the packed report at "
          "the step's start)")
      .def(
          "evaluate_packed",
          [](Simulator& s, const Vector& u) {
            s.evaluate(u);
            return packed(s.report, s.report_modes());
          },
          "u"_a)
      .def(
          "refusal",
          [](const Simulator& s, double speed_limit, double residual_limit) {
            double measured = 0.0;
            const int code = static_cast<int>(s.refusal(speed_limit, residual_limit, measured));
            return std::make_pair(code, measured);
          },
          "speed_limit"_a, "residual_limit"_a,
          "(0 accepted, 3 non-finite forces, 4 too fast, 5 a held contact too far off; the speed or largest held |C|) "
          "of the step just taken")
      .def_prop_ro("state", [](const Simulator& s) { return Vector(s.state()); })
      .def("set_state", &Simulator::set_state, "y"_a)
      .def_prop_ro("active", &Simulator::active)
      .def("set_active", &Simulator::set_active, "active"_a)
      .def_prop_ro(
          "modes",
          [](const Simulator& s) {
            const ContactModes& m = s.modes();
            return nb::make_tuple(m.held, m.sticking, RowMatrix(m.slide), Vector(m.pushing));
          },
          "(held, sticking, slide direction d (p x 3), sign of f_n (p)) per contact")
      .def(
          "set_modes",
          [](Simulator& s, Mask held, Mask sticking, RowMatrix slide, Vector pushing) {
            s.set_modes(ContactModes{std::move(held), std::move(sticking), std::move(slide), std::move(pushing)});
          },
          "held"_a, "sticking"_a, "slide"_a, "pushing"_a)
      .def_rw("steps_taken", &Simulator::steps_taken)
      .def_ro("failed_joint", &Simulator::failed_joint)
      .def_ro("failed_position", &Simulator::failed_position)
      .def_prop_ro("event_count", [](const Simulator& s) { return s.events().size(); })
      .def(
          "events_since",
          [](const Simulator& s, std::size_t first) {
            std::vector<std::tuple<long, double, int, int, double>> out;
            for (std::size_t k = first; k < s.events().size(); ++k) {
              const auto& e = s.events()[k];
              out.emplace_back(e.step, e.offset, e.contact, static_cast<int>(e.kind), e.energy_loss);
            }
            return out;
          },
          "first"_a,
          "(step count, offset into that step [s], contact index, kind (0 release, 1 touchdown, 2 stick, 3 slip), "
          "energy lost [J]) of the events from `first` on")
      .def("truncate_events", &Simulator::truncate_events, "count"_a);

  nb::class_<Path>(m, "Path")
      .def(
          "__init__",
          [](Path* path, int kind, const Vector3& center, double radius, double period, double direction, double phase,
             int u, int v, std::optional<Vector3> point, std::vector<Vector3> waypoints, double segment_time) {
            new (path) Path{static_cast<PathKind>(kind), center, radius, period, direction, phase, u, v,
                            point.has_value(), point.value_or(Vector3::Zero()), std::move(waypoints), segment_time};
          },
          "kind"_a, "center"_a, "radius"_a, "period"_a, "direction"_a, "phase"_a, "u"_a, "v"_a, "point"_a.none(),
          "waypoints"_a, "segment_time"_a, "kind: 0 hold, 1 circle, 2 waypoints")
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
         std::vector<int> axes) { new (task) Task{std::move(frame), kp, kd, path, std::move(axes)}; },
      "frame"_a, "kp"_a, "kd"_a, "path"_a, "axes"_a,
      "gains per world axis (zero: an axis the task does not use); the world axes it uses");

  nb::class_<BracedContact>(m, "BracedContact")
      .def(
          "__init__",
          [](BracedContact* brace, const Contact& contact, double desired_normal_force, const Task& task,
             double feedback_kp, double feedback_ki) {
            new (brace) BracedContact{contact, desired_normal_force, task, feedback_kp, feedback_ki};
          },
          "contact"_a, "desired_normal_force"_a, "task"_a, "feedback_kp"_a = 0.0, "feedback_ki"_a = 0.0,
          "feedback: f_cmd = f_nd + kp (f_nd - f_meas) + ki * integral (f_nd - f_meas) dt (0 0: the paper's law)");

  nb::class_<Law>(m, "Law")
      .def(
          "__init__",
          [](Law* law, const Robot& robot, const Drive& drive, Vector voltage_gain, const Task& hand,
             std::vector<BracedContact> braces, bool gravity_compensation, double damping_lambda,
             bool dynamically_consistent, double slip_epsilon, bool thermal_compensation, double command_limit,
             bool back_emf_compensation, Vector posture_kp, Vector posture_kd, Vector posture_rest) {
            new (law) Law(LawSpec{robot, drive, std::move(voltage_gain), hand, std::move(braces), gravity_compensation,
                                  damping_lambda, dynamically_consistent, slip_epsilon, thermal_compensation,
                                  command_limit, back_emf_compensation, std::move(posture_kp), std::move(posture_kd),
                                  std::move(posture_rest)});
          },
          "robot"_a, "drive"_a, "voltage_gain"_a, "hand"_a, "braces"_a, "gravity_compensation"_a, "damping_lambda"_a,
          "dynamically_consistent"_a, "slip_epsilon"_a, "thermal_compensation"_a = false, "command_limit"_a = 0.0,
          "back_emf_compensation"_a = false, "posture_kp"_a = Vector(), "posture_kd"_a = Vector(),
          "posture_rest"_a = Vector())
      .def(
          "update_packed",
          [](Law& law, double t, const Vector& q, const Vector& dq) {
            LawOutput o;
            law.update(t, q, dq, o);
            const Eigen::Index n = o.command.size(), b = o.brace_desired.rows();
            Vector out(2 * n + 6 + 7 * b + 1);
            out << o.command, o.torque, o.hand_desired, o.hand_actual,
                Eigen::Map<const Vector>(o.brace_desired.data(), 3 * b),
                Eigen::Map<const Vector>(o.brace_actual.data(), 3 * b), o.force_command, o.damped ? 1.0 : 0.0;
            return out;
          },
          "t"_a, "q"_a, "dq"_a,
          "update's answer in one array: command, torque (n each), hand desired, hand actual (3 each), brace desired, "
          "brace actual (3b each, row-major), the force command f_cmd (b), damped (1/0)")
      .def("reset", &Law::reset)
      .def("set_reference", &Law::set_reference, "task"_a, "position"_a, "velocity"_a,
           "task k (0 the hand, 1 + j brace j) follows this desired position and velocity instead of its path")
      .def("clear_reference", &Law::clear_reference, "task"_a, "task k follows its path again")
      .def("path_sample", &Law::path_sample, "task"_a, "t"_a, "task k's configured path at t: (position, velocity)")
      .def("measure_force", &Law::measure_force, "brace"_a, "force"_a,
           "brace j's measured force on the robot [N], world axes (force feedback reads its normal component)")
      .def("measure_temperature", &Law::measure_temperature, "temperature"_a,
           "the windings' measured temperatures [degC] (thermal compensation)")
      .def_prop_ro("uses_force_feedback", &Law::uses_force_feedback)
      .def_prop_ro("uses_temperature", &Law::uses_temperature)
      .def("task_positions", &Law::task_positions, "q"_a, "the hand's and each brace point's positions at q")
      .def("null_space_speed", &Law::null_space_speed, "dq"_a,
           "max |(I - J^+ J) dq| [rad/s or m/s], J the task rows at the last update's q")
      .def("first_rankless_axis", &Law::first_rankless_axis, "q0"_a,
           "(task: 0 the hand, 1 + j brace j; world axis) of the first axis adding no rank at q0, or (-1, -1)")
      .def("task_rank", &Law::task_rank, "q0"_a, "rows"_a,
           "the rank at q0 of the rows [(task: 0 the hand, 1 + j brace j; world axis)] within the motions the "
           "braced contacts allow")
      .def("retune", &Law::retune, "hand_kp"_a, "hand_kd"_a, "brace_kp"_a, "brace_kd"_a, "desired_normal_force"_a,
           "voltage_gain"_a)
      .def_prop_ro("desired_normal_force", &Law::desired_normal_force);

  nb::class_<Sensors>(m, "Sensors")
      .def(
          "__init__",
          [](Sensors* sensors, int n, double step, Mask revolute, unsigned long long seed, long encoder_counts_per_rev,
             double position_noise, double velocity_noise, double velocity_filter_hz, double force_noise,
             double force_bias, double current_noise, long command_latency_steps) {
            SensorSpec spec;
            spec.seed = seed;
            spec.encoder_counts_per_rev = encoder_counts_per_rev;
            spec.position_noise = position_noise;
            spec.velocity_noise = velocity_noise;
            spec.velocity_filter_hz = velocity_filter_hz;
            spec.force_noise = force_noise;
            spec.force_bias = force_bias;
            spec.current_noise = current_noise;
            spec.command_latency_steps = command_latency_steps;
            spec.step = step;
            spec.revolute = std::move(revolute);
            new (sensors) Sensors(spec, n);
          },
          "n"_a, "step"_a, "revolute"_a, "seed"_a = 0, "encoder_counts_per_rev"_a = 0, "position_noise"_a = 0.0,
          "velocity_noise"_a = 0.0, "velocity_filter_hz"_a = 0.0, "force_noise"_a = 0.0, "force_bias"_a = 0.0,
          "current_noise"_a = 0.0, "command_latency_steps"_a = 0)
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

  m.def(
      "rollout",
      [](Law& law, Simulator& simulator, long steps, double t0, double divergence_speed, double divergence_residual,
         Sensors* sensors) {
        Recording r;
        {
          nb::gil_scoped_release release;
          rollout(law, simulator, steps, t0, divergence_speed, divergence_residual, r, sensors);
        }
        nb::dict out;
        const long rows = r.rows;
        out["time"] = Vector(r.time.head(rows));
        const std::pair<const char*, RowMatrix*> arrays[] = {
            {"position", &r.position}, {"velocity", &r.velocity}, {"current", &r.current},
            {"temperature", &r.temperature},
            {"command", &r.command}, {"hand_desired", &r.hand_desired}, {"hand_actual", &r.hand_actual},
            {"brace_desired", &r.brace_desired}, {"brace_actual", &r.brace_actual},
            {"contact_position", &r.contact_position}, {"slip_velocity", &r.slip_velocity},
            {"normal_force", &r.normal_force}, {"friction_force", &r.friction_force}, {"residual", &r.residual},
            {"active", &r.active}, {"energy", &r.energy}, {"measured_position", &r.measured_position},
            {"measured_velocity", &r.measured_velocity}, {"force_command", &r.force_command}};
        for (const auto& [name, array] : arrays) out[name] = RowMatrix(array->topRows(std::min<Eigen::Index>(rows, array->rows())));
        out["status"] = r.status;
        out["measured"] = r.measured;
        return out;
      },
      "law"_a, "simulator"_a, "steps"_a, "t0"_a, "divergence_speed"_a, "divergence_residual"_a,
      "sensors"_a.none() = nb::none(),
      "The closed loop for `steps` steps (and the final state's answer), all in C++: the recorded arrays per "
      "state, 'status' (0 ok; 1 diverged, 2 joint limit in the last row's step; 3 non-finite forces, 4 too fast, "
      "5 a held contact too far off, after it) and 'measured' (the speed or residual of 4 / 5).");
}
