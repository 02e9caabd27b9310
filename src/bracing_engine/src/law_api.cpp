// The C ABI of law_api.h: the controller's per-state answer (the state check, the law, the finite check) for a
// module without Python on its path, and the one state check the Python path calls too.
#include "bracing_engine/law_api.h"

#include <chrono>
#include <cstdio>
#include <cstring>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "bindings.hpp"

namespace bracing_engine::bindings {
namespace {

constexpr std::int64_t kStampLimitNs = 2147483648LL * 1000000000LL;  // builtin_interfaces/Time: int32 seconds

void copy_text(const std::string& text, char* out, std::size_t size) {
  if (size == 0) return;
  std::snprintf(out, size, "%s", text.c_str());
}

// Why a state cannot be answered, after its names are matched: (kind, message), or nothing.
std::optional<std::pair<std::string, std::string>> refusal(std::int64_t stamp_ns, const double* q, const double* dq,
                                                           int n) {
  for (int k = 0; k < n; ++k) {
    if (!std::isfinite(q[k]) || !std::isfinite(dq[k])) return {{"non-finite", "non-finite position or velocity"}};
  }
  if (stamp_ns < -kStampLimitNs || stamp_ns >= kStampLimitNs) {  // a nanosec field >= 1e9 can push it out
    return {{"stamp", "stamp " + std::to_string(stamp_ns) +
                          " ns cannot be answered (builtin_interfaces/Time: int32 seconds)"}};
  }
  return std::nullopt;
}

int state_refusal(std::int64_t stamp_ns, const double* q, const double* dq, int n, char* kind, char* message,
                  std::size_t size) {
  const auto found = refusal(stamp_ns, q, dq, n);
  if (!found) return 0;
  copy_text(found->first, kind, size);
  copy_text(found->second, message, size);
  return 1;
}

bool finite(const double* values, Eigen::Index count) {
  for (Eigen::Index k = 0; k < count; ++k) {
    if (!std::isfinite(values[k])) return false;
  }
  return true;
}

// The Python type nanobind raises for a C++ exception (what the Python path's handlers see).
int failure(const std::exception_ptr& error, char* text, std::size_t size) {
  try {
    std::rethrow_exception(error);
  } catch (const std::domain_error& e) {
    copy_text(e.what(), text, size);
  } catch (const std::invalid_argument& e) {
    copy_text(e.what(), text, size);
  } catch (const std::length_error& e) {
    copy_text(e.what(), text, size);
  } catch (const std::range_error& e) {
    copy_text(e.what(), text, size);
  } catch (const std::overflow_error& e) {
    copy_text(e.what(), text, size);
  } catch (const std::bad_alloc& e) {
    copy_text(std::string("MemoryError: ") + e.what(), text, size);
    return BRACING_LAW_INTERNAL;
  } catch (const std::out_of_range& e) {
    copy_text(std::string("IndexError: ") + e.what(), text, size);
    return BRACING_LAW_INTERNAL;
  } catch (const std::exception& e) {
    copy_text(std::string("RuntimeError: ") + e.what(), text, size);
    return BRACING_LAW_INTERNAL;
  }
  return BRACING_LAW_FAILED;  // ValueError or OverflowError: the law failed on this state
}

int answer(const void* api_pointer, std::int64_t stamp_ns, const double* q, const double* dq, BracingLawAnswer* out,
           char* error, std::size_t size) {
  const auto* api = static_cast<const BracingLawApi*>(api_pointer);
  Law& law = *static_cast<Law*>(api->law);
  const int n = api->joints, b = api->braces;
  LawOutput o;
  const auto start = std::chrono::steady_clock::now();
  try {
    law.update(stamp_seconds(stamp_ns), Eigen::Map<const Vector>(q, n), Eigen::Map<const Vector>(dq, n), o);
  } catch (...) {
    return failure(std::current_exception(), error, size);
  }
  out->compute_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const Vector force = law.desired_normal_force();
  if (!(finite(o.command.data(), o.command.size()) && finite(o.hand_desired.data(), 3) &&
        finite(o.hand_actual.data(), 3) && finite(force.data(), force.size()) &&
        finite(o.brace_desired.data(), o.brace_desired.size()) &&
        finite(o.brace_actual.data(), o.brace_actual.size()))) {
    return BRACING_NOT_FINITE;
  }
  std::memcpy(out->command, o.command.data(), sizeof(double) * static_cast<std::size_t>(n));
  std::memcpy(out->hand_desired, o.hand_desired.data(), sizeof(double) * 3);
  std::memcpy(out->hand_actual, o.hand_actual.data(), sizeof(double) * 3);
  std::memcpy(out->desired_normal_force, force.data(), sizeof(double) * static_cast<std::size_t>(b));
  std::memcpy(out->brace_desired, o.brace_desired.data(), sizeof(double) * 3 * static_cast<std::size_t>(b));
  std::memcpy(out->brace_actual, o.brace_actual.data(), sizeof(double) * 3 * static_cast<std::size_t>(b));
  out->damped = o.damped ? 1 : 0;
  return BRACING_ANSWERED;
}

// The capsule's contents: the ABI, then the law's Python object it keeps alive (the ABI first: the capsule's
// pointer is the holder's).
struct HeldApi {
  BracingLawApi api;
  nb::object law;
};

}  // namespace

void bind_law_api(nb::module_& m) {
  m.def(
      "state_refusal",
      [](std::int64_t stamp_ns, const Vector& q, const Vector& dq) {
        if (q.size() != dq.size()) throw std::invalid_argument("state_refusal: q and dq differ in length");
        return refusal(stamp_ns, q.data(), dq.data(), static_cast<int>(q.size()));
      },
      "stamp_ns"_a, "q"_a, "dq"_a,
      "why a joint state (q, dq in the law's order, stamped stamp_ns) cannot be answered: (kind, message), or "
      "None; the check every answered state passes, on either of the controller's paths");
  m.def(
      "law_api",
      [](nb::object law_object) {
        Law& law = nb::cast<Law&>(law_object);
        auto* held = new HeldApi{{BRACING_LAW_API_VERSION, &law, law.nv(), law.braces(), &state_refusal, &answer},
                                 law_object};
        return nb::capsule(&held->api, BRACING_LAW_API_CAPSULE,
                           [](void* p) noexcept { delete reinterpret_cast<HeldApi*>(p); });
      },
      "law"_a, "the law's C ABI (law_api.h) for another extension module: a capsule that keeps the law alive");
}

}  // namespace bracing_engine::bindings
