// Python bindings (nanobind: ~0.2 us a call, the lightest of the C++ binding libraries). Answers cross
// as structures with named fields, copied once (so nothing Python keeps changes under it): their arrays
// are views of that copy. Kinds (status, refusal, event, path) cross as enums. No packed form is kept:
// against the former one flat array per answer (measured side by side, paper scenario, best
// of 3): Law.update 6.4 -> 5.0 us, Simulator.step 13.3 -> 12.0 us, the Python face's step 20.9 -> 21.5 us.
#include "bindings.hpp"

#include <stdexcept>

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

// One step as the simulator node takes it (Simulator.advance): its status and refusal, and what the node sends
// of a step kept.
struct Advance {
  bool command_taken = true;           // false: u is not one finite value per joint (nothing done)
  StepStatus status = StepStatus::ok;  // the engine's verdict on the step
  Refusal refusal = Refusal::none;     // the node's on a step taken (non_finite too for a non-finite effort)
  double measured = 0.0;               // the refusal's measure, or the largest held |C| of a step kept
  std::optional<ModalAnswer> answer;   // kept: the model at the step's start
  Vector effort;                       // kept: JointState.effort at the new state under the command
  Vector current, temperature, energy;  // at the step's start (energy in EnergySlot order)
};

// Step with u held (one finite value per joint, else nothing is done), judge the step as the node does (the
// engine's status, then Simulator::refusal, then a finite effort: the model at the new state under u if
// `evaluate_effort`, else u itself) and take back any step not kept, as the node's checkpoint and restore did:
// the state, the step count, the contact modes as they were before the step's start, the event log. One call,
// the GIL released: the node's per-state path.
Advance advance(Simulator& s, const Vector& u, double speed_limit, double residual_limit, bool evaluate_effort) {
  Advance out;
  nb::gil_scoped_release unlocked;
  if (u.size() != s.nv() || !u.allFinite()) {
    out.command_taken = false;
    return out;
  }
  const Vector start = s.state();
  const long steps = s.steps_taken;
  const ContactModes modes = s.modes();
  const std::size_t events = s.events().size();
  const auto n = s.nv();
  out.current = start.segment(2 * n, n);
  out.temperature = start.segment(3 * n, n);
  out.energy = start.tail(kEnergies);
  out.status = s.step(u);
  if (out.status == StepStatus::ok) {
    out.refusal = s.refusal(speed_limit, residual_limit, out.measured);
    if (out.refusal == Refusal::none) {
      out.answer.emplace(s.report, s.report_modes());  // before evaluate replaces the report
      if (evaluate_effort) s.evaluate(u);
      out.effort = evaluate_effort ? s.report.effort : u;
      if (!out.effort.allFinite()) out.refusal = Refusal::non_finite;
    }
    if (out.refusal == Refusal::none) return out;
  }
  s.set_state(start);
  s.steps_taken = steps;
  s.truncate_events(events);
  s.set_modes(modes);
  out.answer.reset();
  return out;
}

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
      BRACING_RO(Robot, urdf_path) BRACING_RO(Robot, gravity) BRACING_RO(Robot, locked_joints)
      BRACING_RO(Robot, locked_positions) BRACING_RO(Robot, mass_scale) BRACING_RO(Robot, urdf_xml)
      BRACING_RO(Robot, left_wheel) BRACING_RO(Robot, right_wheel) BRACING_RO(Robot, wheel_radius)
      BRACING_RO(Robot, collision_description);
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
      BRACING_RO(Drive, voltage) BRACING_RO_DOC(Drive, added_inertia, "Mc - M (J_m, or zeros)")
      BRACING_RO_DOC(Drive, damping, "Dc") BRACING_RO_DOC(Drive, torque_constant, "K_m [N m / A]")
      BRACING_RO_DOC(Drive, resistance, "R_20 [ohm], at 20 degC") BRACING_RO_DOC(Drive, inductance, "L [H]")
      BRACING_RO_DOC(Drive, reflected_damping, "D_m") BRACING_RO(Drive, thermal)
      BRACING_RO_DOC(Drive, thermal_resistance, "R_th, winding to ambient [K/W]")
      BRACING_RO_DOC(Drive, heat_capacity, "C_th [J/K]") BRACING_RO_DOC(Drive, ambient, "T_a [degC]")
      BRACING_RO_DOC(Drive, temperature_coefficient, "alpha [1/K]");
}

// The model's answer (Dynamics.evaluate, Simulator.step), every array a view of one copy.
void bind_answer(nb::module_& m) {
  nb::class_<ModalAnswer>(m, "Answer")
      .def_ro("acceleration", &Answer::ddq, "ddq [rad/s^2 or m/s^2]")
      .def_ro("current_rate", &Answer::di, "di/dt [A/s] (zeros in torque mode)")
      .def_ro("normal_force", &Answer::force, "f_n per contact [N], on the robot along +normal (zero where not held)")
      BRACING_RO_DOC(Answer, effort, "the link-side motor torque tau [N m]")
      BRACING_RO(Answer, friction_power) BRACING_RO(Answer, constraint_power) BRACING_RO_DOC(Answer, positions, "p x 3")
      BRACING_RO_DOC(Answer, jacobians, "3p x n: contact j's translational Jacobian in rows 3j..3j+2")
      BRACING_RO_DOC(Answer, normal_jacobian, "p x n") BRACING_RO_DOC(Answer, tangent_jacobian, "p x n")
      BRACING_RO_DOC(Answer, drift, "gamma = n . (dJ dq) + v^T H v")
      BRACING_RO_DOC(Answer, residual, "C: the signed distance to the surface [m]")
      .def_ro("slip_velocity", &Answer::slip, "p x 3: the contact points' tangential velocity [m/s]")
      .def_ro("slip_direction", &Answer::direction, "p x 3: slip / sqrt(|slip|^2 + eps^2)")
      BRACING_RO_DOC(Answer, normals, "p x 3")
      BRACING_RO_DOC(Answer, tangential_force, "p x 3, the friction force on the robot [N]")
      .def_ro("friction_force", &Answer::friction, "|f_t| of a Coulomb contact, mu f_n of a regularised one [N]")
      BRACING_RO_DOC(Answer, rolling_velocity,
                     "a differential drive's rolling rows A v [m/s] (the wheels' forward slip, the left one's lateral)")
      BRACING_RO_DOC(Answer, rolling_force, "the rolling rows' forces [N]")
      BRACING_RO_DOC(ModalAnswer, held, "per contact: holding a normal force")
      BRACING_RO_DOC(ModalAnswer, sticking, "per contact: a held Coulomb contact that sticks")
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
      BRACING_RO_DOC(LinkMeasurement, links, "the links with collision shapes")
      BRACING_RO_DOC(LinkMeasurement, distance,
                     "surfaces * links: C at each link's point nearest surface s (row s * links + k) [m], < 0 inside")
      BRACING_RO_DOC(LinkMeasurement, points, "that point, world [m]")
      BRACING_RO_DOC(LinkMeasurement, normals, "the surface's normal there");
}

// A simulator's contact modes and events.
void bind_modes_and_events(nb::module_& m) {
  nb::class_<ContactModes>(m, "ContactModes")
      BRACING_RO(ContactModes, held) BRACING_RO(ContactModes, sticking)
      BRACING_RO_DOC(ContactModes, slide, "p x 3: a sliding Coulomb contact's held slip direction d")
      BRACING_RO_DOC(ContactModes, pushing, "p: the sign of f_n held over a step (+1 pushing)");
  nb::class_<TimedEvent>(m, "ContactEvent",
                         "a unilateral contact letting go (release) or landing (touchdown); a Coulomb contact "
                         "starting to stick (stick) or to slide (slip), located inside a step")
      .def(
          "__init__",
          [](TimedEvent* event, double time, std::string contact, EventKind kind, double energy_loss) {
            new (event) TimedEvent{time, std::move(contact), kind, energy_loss};
          },
          nb::kw_only(), "time"_a, "contact"_a, "kind"_a, "energy_loss"_a = 0.0)
      BRACING_RO_DOC(TimedEvent, time, "[s]: its step's start as the controller reads the stamp, plus the offset")
      BRACING_RO_DOC(TimedEvent, contact, "the contact's name") BRACING_RO(TimedEvent, kind)
      BRACING_RO_DOC(TimedEvent, energy_loss,
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
      BRACING_RO_DOC(State, position, "q [rad or m]") BRACING_RO_DOC(State, velocity, "dq [rad/s or m/s]")
      BRACING_RO_DOC(State, current, "i [A] (zeros in torque mode)")
      BRACING_RO_DOC(State, temperature, "the windings' T [degC]")
      BRACING_RO_DOC(State, energy, "the energy integrals [J], in EnergySlot order");
  nb::class_<Advance>(m, "Advance", "a step as the simulator node takes it (Simulator.advance)")
      BRACING_RO_DOC(Advance, command_taken, "false: the command is not one finite value per joint (nothing done)")
      BRACING_RO_DOC(Advance, status, "the engine's verdict: not ok, the step was refused and the state is as it was")
      BRACING_RO_DOC(Advance, refusal, "the node's on a step taken (not none: taken back)")
      BRACING_RO_DOC(Advance, measured, "the refusal's measure (speed, temperature, |C|), or the largest held |C|")
      BRACING_RO_DOC(Advance, answer, "a step kept: the model's answer at its start (else None)")
      BRACING_RO_DOC(Advance, effort, "a step kept: JointState.effort at the new state under the command")
      BRACING_RO_DOC(Advance, current, "i [A] at the step's start")
      BRACING_RO_DOC(Advance, temperature, "the windings' T [degC] at the step's start")
      BRACING_RO_DOC(Advance, energy, "the energy integrals [J] at the step's start, in EnergySlot order");
  nb::class_<StepResult>(m, "StepResult", "a step's outcome (Simulator.step)")
      BRACING_RO(StepResult, status)
      BRACING_RO_DOC(StepResult, answer, "the model's answer at the step's start; None unless status is ok");
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
      .def("advance", &advance, "u"_a, "speed_limit"_a, "residual_limit"_a, "evaluate_effort"_a,
           "a step with u held as the simulator node takes it: stepped, judged (the status, the refusal, a finite "
           "effort: the model's under u at the new state if evaluate_effort, else u) and taken back unless kept, "
           "the GIL released")
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
      BRACING_RO(Simulator, failed_joint) BRACING_RO(Simulator, failed_position)
      .def_prop_ro("event_count", [](const Simulator& s) { return s.events().size(); })
      .def("events_since", &timed_events, "first"_a, "t0_ns"_a,
           "the events from `first` on, timed from t0_ns [ns], the stamp of the state before the first step")
      .def("truncate_events", &Simulator::truncate_events, "count"_a);
}

}  // namespace

using namespace bracing_engine::bindings;

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
  bind_law_api(m);
  bind_command_api(m);
}
