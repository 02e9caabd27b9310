// Python bindings (nanobind: ~0.2 us a call, the lightest of the C++ binding libraries). Answers cross
// as structures with named fields, copied once (so nothing Python keeps changes under it): their arrays
// are views of that copy. Kinds (status, refusal, event, path) cross as enums. No packed form is kept:
// against the former one flat array per answer (measured side by side, 2026-11-26, paper scenario, best
// of 3): Law.update 6.4 -> 5.0 us, Simulator.step 13.3 -> 12.0 us, the Python face's step 20.9 -> 21.5 us.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>

#include "bracing_engine/engine.hpp"
#include "bracing_engine/law.hpp"
#include "bracing_engine/sensors.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace bracing_engine;

namespace {

using Flags = Eigen::Array<bool, Eigen::Dynamic, 1>;

Flags flags(const Mask& mask) {
  Flags out(static_cast<Eigen::Index>(mask.size()));
  for (std::size_t j = 0; j < mask.size(); ++j) out[static_cast<Eigen::Index>(j)] = mask[j];
  return out;
}

// The model's answer with the contact modes it was made in, as Python reads it.
struct ModalAnswer : Answer {
  ModalAnswer(const Answer& answer, const ContactModes& modes)
      : Answer(answer), held(flags(modes.held)), sticking(flags(modes.sticking)) {}
  Flags held, sticking;  // per contact: held a normal force; of those, stuck (Coulomb)
};

// A step's outcome: its status and, taken (ok), the model's answer at its start.
struct StepResult {
  StepStatus status;
  std::optional<ModalAnswer> answer;  // moved in and out: the answer's arrays are copied once
};

// A contact event as Python reads it: when (the state's stamp as the controller reads it, plus the offset into
// the step) and which contact, by name.
struct TimedEvent {
  double time;          // [s]
  std::string contact;  // its name
  EventKind kind;
  double energy_loss;  // [J]
};

std::vector<TimedEvent> timed_events(const Simulator& s, std::size_t first, std::int64_t t0_ns) {
  const auto& events = s.events();
  const auto& contacts = s.dynamics().contacts();
  std::vector<TimedEvent> out;
  for (std::size_t k = std::min(first, events.size()); k < events.size(); ++k) {
    const ContactEvent& e = events[k];
    const double time = stamp_seconds(t0_ns + static_cast<std::int64_t>(e.step) * s.step_ns()) + e.offset;
    out.push_back(TimedEvent{time, contacts[static_cast<std::size_t>(e.contact)].name, e.kind, e.energy_loss});
  }
  return out;
}

// The simulator's state by name (the engine keeps it packed: [q, dq, i, T, energies]).
struct State {
  Vector position, velocity, current, temperature;
  Vector energy;  // in EnergySlot order
};

State state_of(const Simulator& s) {
  const Vector& y = s.state();
  const auto n = s.nv();
  return State{y.head(n), y.segment(n, n), y.segment(2 * n, n), y.segment(3 * n, n), y.tail(kEnergies)};
}

Vector packed(const Simulator& s, const State& state) {
  const auto n = s.nv();
  for (const Vector* block : {&state.position, &state.velocity, &state.current, &state.temperature})
    if (block->size() != n) throw std::invalid_argument("State: each of position, velocity, current, temperature "
                                                        "needs one value per joint");
  if (state.energy.size() != kEnergies) throw std::invalid_argument("State: energy needs one value per EnergySlot");
  Vector y(kStates * n + kEnergies);
  y << state.position, state.velocity, state.current, state.temperature, state.energy;
  return y;
}

// The modes with the contacts `held` holding a force, none sticking.
ContactModes modes_of(const Mask& held) {
  const auto p = static_cast<Eigen::Index>(held.size());
  return ContactModes{held, Mask(held.size(), false), RowMatrix::Zero(p, 3), Vector::Ones(p)};
}

// A recording cut to the rows the rollout filled.
void keep_filled_rows(Recording& r) {
  r.time.conservativeResize(r.rows);
  for (RowMatrix* a : {&r.position, &r.velocity, &r.current, &r.temperature, &r.command, &r.hand_desired,
                       &r.hand_actual, &r.brace_desired, &r.brace_actual, &r.contact_position, &r.slip_velocity,
                       &r.normal_force, &r.friction_force, &r.residual, &r.active, &r.energy,
                       &r.measured_position, &r.measured_velocity, &r.force_command, &r.orientation_error})
    a->conservativeResize(std::min<Eigen::Index>(r.rows, a->rows()), Eigen::NoChange);
}

// The kinds that cross as enums, and the state's layout.
void bind_kinds(nb::module_& m) {
  nb::enum_<StepStatus>(m, "StepStatus", "a step: taken, or refused with the state unchanged")
      .value("ok", StepStatus::ok)
      .value("diverged", StepStatus::diverged)
      .value("joint_limit", StepStatus::joint_limit);
  nb::enum_<Refusal>(m, "Refusal", "why the simulator node refuses a step it took (Simulator.refusal)")
      .value("none", Refusal::none)
      .value("non_finite", Refusal::non_finite, "non-finite forces or slip")
      .value("too_fast", Refusal::too_fast, "a joint faster than the speed limit")
      .value("off_surface", Refusal::off_surface, "a held contact further than the residual limit off its surface")
      .value("too_hot", Refusal::too_hot, "a winding hotter than WINDING_TEMPERATURE_LIMIT");
  nb::enum_<EventKind>(m, "EventKind")
      .value("release", EventKind::release)
      .value("touchdown", EventKind::touchdown)
      .value("stick", EventKind::stick)
      .value("slip", EventKind::slip);
  nb::enum_<PathKind>(m, "PathKind").value("hold", PathKind::hold).value("circle", PathKind::circle).value(
      "waypoints", PathKind::waypoints);
  nb::enum_<energy::Slot>(m, "EnergySlot", "the energy integrals after [q, dq, i, T] in the state, in order")
      .value("consumed", energy::consumed)
      .value("net", energy::net)
      .value("copper_loss", energy::copper_loss)
      .value("viscous_loss", energy::viscous_loss)
      .value("friction_loss", energy::friction_loss)
      .value("constraint_work", energy::constraint_work)
      .value("impact_loss", energy::impact_loss);
}

// Surfaces and contacts.
void bind_surfaces(nb::module_& m) {
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
             bool unilateral, bool enforced, bool coulomb, bool geometry) {
            new (c) Contact{std::move(name), std::move(frame), surface, friction, unilateral, enforced, coulomb, geometry};
          },
          nb::kw_only(), "name"_a, "frame"_a, "surface"_a, "friction"_a, "unilateral"_a, "enforced"_a, "coulomb"_a,
          "geometry"_a = false, "geometry: the contact point is where the frame's link's collision shapes are nearest "
                                "the surface (point: geometry)");
}

// The robot.
void bind_robot(nb::module_& m) {
  nb::class_<Robot>(m, "Robot")
      .def(
          "__init__",
          [](Robot* r, std::string urdf_path, const Vector3& gravity, std::vector<std::string> locked_joints,
             std::vector<double> locked_positions, double mass_scale, std::string urdf_xml, std::string left_wheel,
             std::string right_wheel, double wheel_radius, std::string collision_description) {
            new (r) Robot{std::move(urdf_path),        gravity,
                          std::move(locked_joints),    std::move(locked_positions),
                          mass_scale,                  std::move(urdf_xml),
                          std::move(left_wheel),       std::move(right_wheel),
                          wheel_radius,                std::move(collision_description)};
          },
          nb::kw_only(), "urdf_path"_a, "gravity"_a, "locked_joints"_a = std::vector<std::string>(),
          "locked_positions"_a = std::vector<double>(), "mass_scale"_a = 1.0,
          "urdf_xml"_a = "", "left_wheel"_a = "", "right_wheel"_a = "", "wheel_radius"_a = 0.0,
          "collision_description"_a = "",
          "mass_scale: every moving link's mass and rotational inertia times this (a plant's model error); "
          "urdf_xml: the URDF text to build from instead of the file's (empty: the file); left_wheel, right_wheel, "
          "wheel_radius [m]: a differential drive's wheel joints (empty: none), rolling without slipping; "
          "collision_description: the URDF text whose <collision> shapes are measured (meshes by absolute or "
          "file:// paths), empty: none")
      .def_ro("urdf_path", &Robot::urdf_path)
      .def_ro("gravity", &Robot::gravity)
      .def_ro("locked_joints", &Robot::locked_joints)
      .def_ro("locked_positions", &Robot::locked_positions)
      .def_ro("mass_scale", &Robot::mass_scale)
      .def_ro("urdf_xml", &Robot::urdf_xml)
      .def_ro("left_wheel", &Robot::left_wheel)
      .def_ro("right_wheel", &Robot::right_wheel)
      .def_ro("wheel_radius", &Robot::wheel_radius)
      .def_ro("collision_description", &Robot::collision_description);
}

// The joints' drive: motors in the loop (voltage) or direct drive (torque).
void bind_drive(nb::module_& m) {
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
          nb::kw_only(), "voltage"_a, "added_inertia"_a, "damping"_a, "torque_constant"_a, "resistance"_a,
          "inductance"_a,
          "reflected_damping"_a, "thermal"_a, "thermal_resistance"_a, "heat_capacity"_a, "ambient"_a,
          "temperature_coefficient"_a,
          "resistance: R_20 at 20 degC; thermal: R(T) = R_20 (1 + alpha (T - 20)), C_th dT/dt = R(T) i^2 - (T - "
          "ambient) / R_th")
      .def_ro("voltage", &Drive::voltage)
      .def_ro("added_inertia", &Drive::added_inertia, "Mc - M (J_m, or zeros)")
      .def_ro("damping", &Drive::damping, "Dc")
      .def_ro("torque_constant", &Drive::torque_constant, "K_m [N m / A]")
      .def_ro("resistance", &Drive::resistance, "R_20 [ohm], at 20 degC")
      .def_ro("inductance", &Drive::inductance, "L [H]")
      .def_ro("reflected_damping", &Drive::reflected_damping, "D_m")
      .def_ro("thermal", &Drive::thermal)
      .def_ro("thermal_resistance", &Drive::thermal_resistance, "R_th, winding to ambient [K/W]")
      .def_ro("heat_capacity", &Drive::heat_capacity, "C_th [J/K]")
      .def_ro("ambient", &Drive::ambient, "T_a [degC]")
      .def_ro("temperature_coefficient", &Drive::temperature_coefficient, "alpha [1/K]");
}

// The model's answer (Dynamics.evaluate, Simulator.step), every array a view of one copy.
void bind_answer(nb::module_& m) {
  nb::class_<ModalAnswer>(m, "Answer")
      .def_ro("acceleration", &Answer::ddq, "ddq [rad/s^2 or m/s^2]")
      .def_ro("current_rate", &Answer::di, "di/dt [A/s] (zeros in torque mode)")
      .def_ro("normal_force", &Answer::force, "f_n per contact [N], on the robot along +normal (zero where not held)")
      .def_ro("effort", &Answer::effort, "the link-side motor torque tau [N m]")
      .def_ro("friction_power", &Answer::friction_power)
      .def_ro("constraint_power", &Answer::constraint_power)
      .def_ro("positions", &Answer::positions, "p x 3")
      .def_ro("jacobians", &Answer::jacobians, "3p x n: contact j's translational Jacobian in rows 3j..3j+2")
      .def_ro("normal_jacobian", &Answer::normal_jacobian, "p x n")
      .def_ro("tangent_jacobian", &Answer::tangent_jacobian, "p x n")
      .def_ro("drift", &Answer::drift, "gamma = n . (dJ dq) + v^T H v")
      .def_ro("residual", &Answer::residual, "C: the signed distance to the surface [m]")
      .def_ro("slip_velocity", &Answer::slip, "p x 3: the contact points' tangential velocity [m/s]")
      .def_ro("slip_direction", &Answer::direction, "p x 3: slip / sqrt(|slip|^2 + eps^2)")
      .def_ro("normals", &Answer::normals, "p x 3")
      .def_ro("tangential_force", &Answer::tangential_force, "p x 3, the friction force on the robot [N]")
      .def_ro("friction_force", &Answer::friction, "|f_t| of a Coulomb contact, mu f_n of a regularised one [N]")
      .def_ro("rolling_velocity", &Answer::rolling_velocity,
              "a differential drive's rolling rows A v [m/s] (the wheels' forward slip, the left one's lateral)")
      .def_ro("rolling_force", &Answer::rolling_force, "the rolling rows' forces [N]")
      .def_ro("held", &ModalAnswer::held, "per contact: holding a normal force")
      .def_ro("sticking", &ModalAnswer::sticking, "per contact: a held Coulomb contact that sticks")
      .def_prop_ro("contact_count", [](const ModalAnswer& a) { return a.residual.size(); });
}

// The model.
void bind_dynamics(nb::module_& m) {
  nb::class_<Dynamics>(m, "Dynamics")
      .def(nb::init<const Robot&, const Drive&, std::vector<Contact>, double, double>(), "robot"_a, "drive"_a,
           "contacts"_a, "slip_epsilon"_a, "baumgarte"_a)
      .def_prop_ro("nv", &Dynamics::nv)
      .def_prop_ro("rolling_rows", &Dynamics::rolling_rows)
      .def_prop_ro("joint_names", &Dynamics::joint_names)
      .def_rw("baumgarte", &Dynamics::baumgarte)
      .def(
          "evaluate",
          [](const Dynamics& d, const Vector& q, const Vector& dq, const Vector& current, const Vector& temperature,
             const Vector& u, const Mask& held) {
            Answer a;
            const ContactModes modes = modes_of(held);
            d.evaluate(q, dq, current, temperature, u, modes, true, a);
            return ModalAnswer(a, modes);
          },
          "q"_a, "dq"_a, "current"_a, "temperature"_a, "u"_a, "held"_a, "temperature: the windings' T [degC]")
      .def(
          "terms",
          [](const Dynamics& d, const Vector& q, const Vector& dq) {
            Answer a;
            d.terms(q, dq, a);
            return ModalAnswer(a, modes_of(Mask(static_cast<std::size_t>(d.contact_count()), false)));
          },
          "q"_a, "dq"_a, "every contact's terms at (q, dq), as an answer with no force (no solve)")
      .def("project", &Dynamics::project, "q"_a, "rows"_a, "tolerance"_a = 1e-13)
      .def(
          "impact",
          [](const Dynamics& d, Vector q, Vector dq, const std::vector<int>& rows) {
            const double loss = d.impact(q, dq, rows);
            return nb::make_tuple(q, dq, loss);
          },
          "q"_a, "dq"_a, "rows"_a, "(q, dq, the kinetic energy lost)")
      .def(
          "measure_links",
          [](const Dynamics& d, const Vector& q, const std::vector<Surface>& surfaces) {
            LinkMeasurement out;
            d.measure_links(q, surfaces, out);
            return out;
          },
          "q"_a, "surfaces"_a, "every link with collision shapes against each surface at q");
  nb::class_<LinkMeasurement>(m, "LinkMeasurement")
      .def_ro("links", &LinkMeasurement::links, "the links with collision shapes")
      .def_ro("distance", &LinkMeasurement::distance,
              "surfaces * links: C at each link's point nearest surface s (row s * links + k) [m], < 0 inside")
      .def_ro("points", &LinkMeasurement::points, "that point, world [m]")
      .def_ro("normals", &LinkMeasurement::normals, "the surface's normal there");
}

// A simulator's contact modes and events.
void bind_modes_and_events(nb::module_& m) {
  nb::class_<ContactModes>(m, "ContactModes")
      .def_ro("held", &ContactModes::held)
      .def_ro("sticking", &ContactModes::sticking)
      .def_ro("slide", &ContactModes::slide, "p x 3: a sliding Coulomb contact's held slip direction d")
      .def_ro("pushing", &ContactModes::pushing, "p: the sign of f_n held over a step (+1 pushing)");
  nb::class_<TimedEvent>(m, "ContactEvent",
                         "a unilateral contact letting go (release) or landing (touchdown); a Coulomb contact "
                         "starting to stick (stick) or to slide (slip), located inside a step")
      .def(
          "__init__",
          [](TimedEvent* event, double time, std::string contact, EventKind kind, double energy_loss) {
            new (event) TimedEvent{time, std::move(contact), kind, energy_loss};
          },
          nb::kw_only(), "time"_a, "contact"_a, "kind"_a, "energy_loss"_a = 0.0)
      .def_ro("time", &TimedEvent::time, "[s]: its step's start as the controller reads the stamp, plus the offset")
      .def_ro("contact", &TimedEvent::contact, "the contact's name")
      .def_ro("kind", &TimedEvent::kind)
      .def_ro("energy_loss", &TimedEvent::energy_loss,
              "[J] lost: a touchdown's impact, the tangential impulse that makes a contact stick");
}

// The integrator's state and a step's outcome.
void bind_state(nb::module_& m) {
  nb::class_<State>(m, "State", "a simulator's state, each block a copy")
      .def(
          "__init__",
          [](State* state, Vector position, Vector velocity, Vector current, Vector temperature, Vector energy) {
            new (state) State{std::move(position), std::move(velocity), std::move(current), std::move(temperature),
                              std::move(energy)};
          },
          nb::kw_only(), "position"_a, "velocity"_a, "current"_a, "temperature"_a, "energy"_a)
      .def_ro("position", &State::position, "q [rad or m]")
      .def_ro("velocity", &State::velocity, "dq [rad/s or m/s]")
      .def_ro("current", &State::current, "i [A] (zeros in torque mode)")
      .def_ro("temperature", &State::temperature, "the windings' T [degC]")
      .def_ro("energy", &State::energy, "the energy integrals [J], in EnergySlot order");
  nb::class_<StepResult>(m, "StepResult", "a step's outcome (Simulator.step)")
      .def_ro("status", &StepResult::status)
      .def_ro("answer", &StepResult::answer, "the model's answer at the step's start; None unless status is ok");
}

// The integrator.
void bind_simulator(nb::module_& m) {
  nb::class_<Simulator>(m, "Simulator")
      .def(nb::init<std::shared_ptr<const Dynamics>, double, int, const Vector&, const Vector&, const Vector&,
                    const Vector&>(),
           "dynamics"_a, "step"_a, "substeps"_a, "q0"_a, "dq0"_a, "lower_limits"_a, "upper_limits"_a)
      .def(
          "step",
          [](Simulator& s, const Vector& u) {
            StepResult result{s.step(u), std::nullopt};
            if (result.status == StepStatus::ok) result.answer.emplace(s.report, s.report_modes());
            return result;
          },
          "u"_a, "the step's status and the answer at its start (None unless ok: the state is then unchanged, "
          "failed_joint names a joint limit)")
      .def(
          "evaluate",
          [](Simulator& s, const Vector& u) {
            s.evaluate(u);
            return ModalAnswer(s.report, s.report_modes());
          },
          "u"_a)
      .def(
          "refusal",
          [](const Simulator& s, double speed_limit, double residual_limit) {
            double measured = 0.0;
            const Refusal refusal = s.refusal(speed_limit, residual_limit, measured);
            return std::make_pair(refusal, measured);
          },
          "speed_limit"_a, "residual_limit"_a,
          "(Refusal, the speed, temperature or largest held |C| it measured) of the step just taken")
      .def_prop_ro("state", &state_of, "a copy of the state")
      .def_prop_ro("position", [](const Simulator& s) { return Vector(s.state().head(s.nv())); })
      .def_prop_ro("velocity", [](const Simulator& s) { return Vector(s.state().segment(s.nv(), s.nv())); })
      .def_prop_ro("current", [](const Simulator& s) { return Vector(s.state().segment(2 * s.nv(), s.nv())); })
      .def_prop_ro("temperature", [](const Simulator& s) { return Vector(s.state().segment(3 * s.nv(), s.nv())); })
      .def_prop_ro("energy", [](const Simulator& s) { return Vector(s.state().tail(kEnergies)); }, "in EnergySlot order")
      .def(
          "set_state", [](Simulator& s, const State& state) { s.set_state(packed(s, state)); }, "state"_a)
      .def_prop_ro("active", &Simulator::active)
      .def("set_active", &Simulator::set_active, "active"_a)
      .def_prop_ro("modes", [](const Simulator& s) { return s.modes(); })
      .def("set_modes", &Simulator::set_modes, "modes"_a)
      .def_rw("steps_taken", &Simulator::steps_taken)
      .def_prop_ro("step_ns", &Simulator::step_ns, "[ns] what each step adds to the state's stamp")
      .def_rw("steady_start", &Simulator::steady_start,
              "voltage input: the first step starts its windings at its command's steady current")
      .def("hold_current", &Simulator::hold_current, "u"_a, "the windings at their steady current under u, now")
      .def_ro("failed_joint", &Simulator::failed_joint)
      .def_ro("failed_position", &Simulator::failed_position)
      .def_prop_ro("event_count", [](const Simulator& s) { return s.events().size(); })
      .def("events_since", &timed_events, "first"_a, "t0_ns"_a,
           "the events from `first` on, timed from t0_ns [ns], the stamp of the state before the first step")
      .def("truncate_events", &Simulator::truncate_events, "count"_a);
}

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
      .def_ro("robot", &LawSpec::robot)
      .def_ro("drive", &LawSpec::drive)
      .def_ro("voltage_gain", &LawSpec::voltage_gain)
      .def_ro("hand", &LawSpec::hand)
      .def_ro("braces", &LawSpec::braces)
      .def_ro("gravity_compensation", &LawSpec::gravity_compensation)
      .def_ro("damping_lambda", &LawSpec::damping_lambda)
      .def_ro("dynamically_consistent", &LawSpec::dynamically_consistent)
      .def_ro("slip_epsilon", &LawSpec::slip_epsilon)
      .def_ro("thermal_compensation", &LawSpec::thermal_compensation)
      .def_ro("command_limit", &LawSpec::command_limit)
      .def_ro("back_emf_compensation", &LawSpec::back_emf_compensation)
      .def_ro("posture_kp", &LawSpec::posture_kp)
      .def_ro("posture_kd", &LawSpec::posture_kd)
      .def_ro("posture_rest", &LawSpec::posture_rest)
      .def_ro("acceleration_gains", &LawSpec::acceleration_gains)
      .def_ro("orientation", &LawSpec::orientation);
}

// The control law.
void bind_law(nb::module_& m) {
  nb::class_<LawOutput>(m, "LawOutput")
      .def_rw("command", &LawOutput::command, "v [V] or tau [N m], model order (a drive's base command adds to it)")
      .def_rw("torque", &LawOutput::torque, "tau of eq. 38 [N m]")
      .def_ro("hand_desired", &LawOutput::hand_desired)
      .def_ro("hand_actual", &LawOutput::hand_actual)
      .def_ro("brace_desired", &LawOutput::brace_desired, "b x 3")
      .def_ro("brace_actual", &LawOutput::brace_actual, "b x 3")
      .def_ro("force_command", &LawOutput::force_command, "f_cmd per brace [N] (f_nd without feedback)")
      .def_ro("orientation_error", &LawOutput::orientation_error, "the hand frame's log(R_d R^T) [rad], world axes")
      .def_ro("damped", &LawOutput::damped);
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
      .def_ro("step", &SensorSpec::step)
      .def_ro("revolute", &SensorSpec::revolute)
      .def_ro("seed", &SensorSpec::seed)
      .def_ro("encoder_counts_per_rev", &SensorSpec::encoder_counts_per_rev)
      .def_ro("position_noise", &SensorSpec::position_noise)
      .def_ro("velocity_noise", &SensorSpec::velocity_noise)
      .def_ro("velocity_filter_hz", &SensorSpec::velocity_filter_hz)
      .def_ro("force_noise", &SensorSpec::force_noise)
      .def_ro("force_bias", &SensorSpec::force_bias)
      .def_ro("current_noise", &SensorSpec::current_noise)
      .def_ro("command_latency_steps", &SensorSpec::command_latency_steps);
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
void bind_rollout(nb::module_& m) {
  nb::class_<Recording>(m, "Recording", "per state k = 0..rows-1, as the nodes publish it in lockstep")
      .def_ro("time", &Recording::time)
      .def_ro("position", &Recording::position)
      .def_ro("velocity", &Recording::velocity)
      .def_ro("current", &Recording::current)
      .def_ro("temperature", &Recording::temperature)
      .def_ro("command", &Recording::command)
      .def_ro("hand_desired", &Recording::hand_desired)
      .def_ro("hand_actual", &Recording::hand_actual)
      .def_ro("brace_desired", &Recording::brace_desired, "rows x 3b")
      .def_ro("brace_actual", &Recording::brace_actual, "rows x 3b")
      .def_ro("contact_position", &Recording::contact_position, "rows x 3p")
      .def_ro("slip_velocity", &Recording::slip_velocity, "rows x 3p")
      .def_ro("normal_force", &Recording::normal_force)
      .def_ro("friction_force", &Recording::friction_force)
      .def_ro("residual", &Recording::residual)
      .def_ro("active", &Recording::active, "1/0")
      .def_prop_ro(
          "energy_consumed", [](const Recording& r) { return Vector(r.energy.col(0)); },
          "[J] consumed up to the step's start (EnergySlot.consumed)")
      .def_prop_ro(
          "energy_net", [](const Recording& r) { return Vector(r.energy.col(1)); }, "[J] net (EnergySlot.net)")
      .def_prop_ro(
          "copper_loss", [](const Recording& r) { return Vector(r.energy.col(2)); },
          "[J] copper loss (EnergySlot.copper_loss)")
      .def_ro("measured_position", &Recording::measured_position, "(0 rows without sensors)")
      .def_ro("measured_velocity", &Recording::measured_velocity)
      .def_ro("force_command", &Recording::force_command)
      .def_ro("orientation_error", &Recording::orientation_error, "rows x 3: the hand's log(R_d R^T) [rad]")
      .def_ro("step_status", &Recording::step_status, "not ok: the step from the last row's state was refused")
      .def_ro("refusal", &Recording::refusal, "not none: the node refuses the step after the last row")
      .def_ro("measured", &Recording::measured, "the refusal's speed, temperature or residual");
  m.def(
      "rollout",
      [](Law& law, Simulator& simulator, long steps, std::int64_t t0_ns, double divergence_speed, double divergence_residual,
         Sensors* sensors, const Vector& command_limit) {
        Recording r;
        {
          nb::gil_scoped_release release;
          rollout(law, simulator, steps, t0_ns, divergence_speed, divergence_residual, r, sensors, command_limit);
        }
        keep_filled_rows(r);
        return r;
      },
      "law"_a, "simulator"_a, "steps"_a, "t0_ns"_a, "divergence_speed"_a, "divergence_residual"_a,
      "sensors"_a.none() = nb::none(), "command_limit"_a = Vector(),
      "The closed loop for `steps` steps (and the final state's answer), all in C++: the Recording, stopped "
      "early where a step is refused (step_status) or the node would refuse it (refusal); each applied |command| "
      "saturated to command_limit (per joint, 0: none), the recording keeping the law's.");
}

}  // namespace

NB_MODULE(_engine, m) {
  m.doc() = "The bracing engine: constrained robot + motor-circuit dynamics and RK4 on pinocchio (C++).";
  m.attr("PINOCCHIO_VERSION") = compiled_pinocchio_version();
  m.attr("WINDING_TEMPERATURE_LIMIT") = kWindingTemperatureLimit;  // [degC], Refusal.too_hot
  m.def("stamp_seconds", &stamp_seconds, "ns"_a,
        "[s] the sim time of a stamp [ns]: the one conversion the controller node, the rollout and the "
        "Simulator read a state's time with");
  nb::exception<SingularError>(m, "SingularError", PyExc_ArithmeticError);
  bind_kinds(m);
  bind_surfaces(m);
  bind_robot(m);
  bind_drive(m);
  bind_answer(m);
  bind_dynamics(m);
  bind_modes_and_events(m);
  bind_state(m);
  bind_simulator(m);
  bind_tasks(m);
  bind_law_spec(m);
  bind_law(m);
  bind_sensors(m);
  bind_rollout(m);
}
