// Python bindings (nanobind: ~0.2 us a call, the lightest of the C++ binding libraries). Arrays
// cross by copy, so nothing Python keeps changes under it.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include "bracing_engine/engine.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace bracing_engine;

namespace {

// positions, jacobians (3p x n), normal_jacobian, tangent_jacobian, drift, residual, slip, direction, normals
nb::tuple contact_terms(const Answer& a) {
  return nb::make_tuple(RowMatrix(a.positions), RowMatrix(a.jacobians), RowMatrix(a.normal_jacobian),
                        RowMatrix(a.tangent_jacobian), Vector(a.drift), Vector(a.residual), RowMatrix(a.slip),
                        RowMatrix(a.direction), RowMatrix(a.normals));
}

// ddq, di, f_n, effort, friction power, constraint power
nb::tuple solution(const Answer& a) {
  return nb::make_tuple(Vector(a.ddq), Vector(a.di), Vector(a.force), Vector(a.effort), a.friction_power,
                        a.constraint_power);
}

}  // namespace

NB_MODULE(_engine, m) {
  m.doc() = "The bracing engine: constrained robot + motor-circuit dynamics and RK4 on pinocchio (C++).";
  m.attr("PINOCCHIO_VERSION") = compiled_pinocchio_version();
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
             bool unilateral, bool enforced) {
            new (c) Contact{std::move(name), std::move(frame), surface, friction, unilateral, enforced};
          },
          "name"_a, "frame"_a, "surface"_a, "friction"_a, "unilateral"_a, "enforced"_a);

  nb::class_<Robot>(m, "Robot")
      .def(
          "__init__",
          [](Robot* r, std::string urdf_path, const Vector3& gravity, std::vector<std::string> locked_joints,
             std::vector<double> locked_positions) {
            new (r) Robot{std::move(urdf_path), gravity, std::move(locked_joints), std::move(locked_positions)};
          },
          "urdf_path"_a, "gravity"_a, "locked_joints"_a, "locked_positions"_a);

  nb::class_<Drive>(m, "Drive")
      .def(
          "__init__",
          [](Drive* d, bool voltage, Vector added_inertia, Vector damping, Vector torque_constant, Vector resistance,
             Vector inductance, Vector reflected_damping) {
            new (d) Drive{voltage, added_inertia, damping, torque_constant, resistance, inductance, reflected_damping};
          },
          "voltage"_a, "added_inertia"_a, "damping"_a, "torque_constant"_a, "resistance"_a, "inductance"_a,
          "reflected_damping"_a);

  nb::class_<Dynamics>(m, "Dynamics")
      .def(nb::init<const Robot&, const Drive&, std::vector<Contact>, double, double>(), "robot"_a, "drive"_a,
           "contacts"_a, "slip_epsilon"_a, "baumgarte"_a)
      .def_prop_ro("nv", &Dynamics::nv)
      .def_prop_ro("joint_names", &Dynamics::joint_names)
      .def_rw("baumgarte", &Dynamics::baumgarte)
      .def(
          "evaluate",
          [](const Dynamics& d, const Vector& q, const Vector& dq, const Vector& current, const Vector& u,
             const Mask& held) {
            Answer a;
            d.evaluate(q, dq, current, u, held, true, a);
            return nb::make_tuple(solution(a), contact_terms(a));
          },
          "q"_a, "dq"_a, "current"_a, "u"_a, "held"_a,
          "((ddq, di, f_n, effort, friction power, constraint power), contact terms) at one state")
      .def(
          "terms",
          [](const Dynamics& d, const Vector& q, const Vector& dq) {
            Answer a;
            d.terms(q, dq, a);
            return contact_terms(a);
          },
          "q"_a, "dq"_a)
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
      .def("step", [](Simulator& s, const Vector& u) { return static_cast<int>(s.step(u)); }, "u"_a,
           "0 ok, 1 diverged, 2 joint limit (failed_joint); the state is unchanged unless 0")
      .def("evaluate", &Simulator::evaluate, "u"_a)
      .def("solution", [](const Simulator& s) { return solution(s.report); })
      .def("contact_terms", [](const Simulator& s) { return contact_terms(s.report); })
      .def_prop_ro("state", [](const Simulator& s) { return Vector(s.state()); })
      .def("set_state", &Simulator::set_state, "y"_a)
      .def_prop_ro("active", &Simulator::active)
      .def("set_active", &Simulator::set_active, "active"_a)
      .def_rw("steps_taken", &Simulator::steps_taken)
      .def_ro("failed_joint", &Simulator::failed_joint)
      .def_ro("failed_position", &Simulator::failed_position)
      .def_prop_ro("event_count", [](const Simulator& s) { return s.events().size(); })
      .def(
          "events_since",
          [](const Simulator& s, std::size_t first) {
            std::vector<std::tuple<long, int, bool, double>> out;
            for (std::size_t k = first; k < s.events().size(); ++k) {
              const auto& e = s.events()[k];
              out.emplace_back(e.step, e.contact, e.touchdown, e.impact_loss);
            }
            return out;
          },
          "first"_a, "(step count, contact index, touchdown?, impact loss [J]) of the events from `first` on")
      .def("truncate_events", &Simulator::truncate_events, "count"_a);
}
