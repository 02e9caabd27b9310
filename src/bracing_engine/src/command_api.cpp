// The motor command's value rule (command_api.h): one implementation for both of the simulator's command paths,
// bracing_rcl's in C++ through the C ABI and bracing_ros.commands through the binding.
#include "bracing_engine/command_api.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "bindings.hpp"

namespace bracing_engine::bindings {
namespace {

std::size_t check_command(const double* values, const double* limit, std::size_t n, double* out, int* saturated,
                          std::size_t* non_finite) {
  std::size_t bad = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (!std::isfinite(values[k])) non_finite[bad++] = k;
  }
  if (bad > 0) return bad;
  bool over = false;
  for (std::size_t k = 0; k < n; ++k) {
    // Not above zero (a NaN limit too): no limit, as np.where(limit > 0, limit, inf) reads it.
    const double bound = limit[k] > 0.0 ? limit[k] : std::numeric_limits<double>::infinity();
    const double v = values[k];
    over = over || std::fabs(v) > bound;
    out[k] = v > bound ? bound : (v < -bound ? -bound : v);  // np.clip's value, bit for bit
  }
  *saturated = over ? 1 : 0;
  return 0;
}

constexpr BracingCommandApi kCommandApi{BRACING_COMMAND_API_VERSION, &check_command};

// What check_command says of one command, for Python.
struct CommandCheck {
  Vector values;                       // finite: the command saturated (else empty)
  bool saturated = false;              // a value was over its joint's limit
  std::vector<std::size_t> non_finite;  // the indices of the values that are not finite
};

}  // namespace

void bind_command_api(nb::module_& m) {
  nb::class_<CommandCheck>(m, "CommandCheck", "what the motor command's value rule says of one command")
      .def_ro("values", &CommandCheck::values, "every value finite: the command saturated to the limits (else empty)")
      .def_ro("saturated", &CommandCheck::saturated, "a value was over its joint's limit (and is now at it)")
      .def_ro("non_finite", &CommandCheck::non_finite, "the indices of the values that are not finite, ascending");
  m.def(
      "check_command",
      [](const Vector& values, const Vector& limit) {
        if (values.size() != limit.size()) throw std::invalid_argument("check_command: a limit per value is needed");
        const auto n = static_cast<std::size_t>(values.size());
        CommandCheck check;
        check.non_finite.resize(n);
        Vector out(values.size());
        int saturated = 0;
        check.non_finite.resize(check_command(values.data(), limit.data(), n, out.data(), &saturated,
                                              check.non_finite.data()));
        if (check.non_finite.empty()) check.values = out, check.saturated = saturated != 0;
        return check;
      },
      "values"_a, "limit"_a,
      "the motor command's value rule on values (in the joints' order): every value finite, then each saturated "
      "to its joint's limit (limit > 0; else none) as np.clip does; the one rule of both of the simulator's "
      "command paths (bracing_rcl's CommandPath calls it through command_api)");
  m.def(
      "command_api",
      [] { return nb::capsule(&kCommandApi, BRACING_COMMAND_API_CAPSULE); },
      "the value rule's C ABI (command_api.h) for another extension module: a capsule (the table is static)");
}

}  // namespace bracing_engine::bindings
