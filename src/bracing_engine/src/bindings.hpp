// What the two binding files share: nanobind with its type casters, the engine's headers, and the parts of the
// module bound in bindings_control.cpp (the law, its tasks, the sensors and the closed loop).
#pragma once

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

// A member of Type bound read-only under its own name (the runs of plain fields, several to a line), and the
// same with its docstring (units, shapes).
#define BRACING_RO(Type, field) .def_ro(#field, &Type::field)
#define BRACING_RO_DOC(Type, field, doc) .def_ro(#field, &Type::field, doc)

namespace bracing_engine::bindings {

void bind_tasks(nb::module_& m);
void bind_law_spec(nb::module_& m);
void bind_law(nb::module_& m);
void bind_sensors(nb::module_& m);
void bind_rollout(nb::module_& m);
void bind_law_api(nb::module_& m);
void bind_command_api(nb::module_& m);

}  // namespace bracing_engine::bindings
