// The controller node's per-state path on rcl's C API: wait for a joint_states, take it, check it, run the law,
// publish the motor_command and then the controller_state, with the GIL released, state after state until
// something needs Python (ControllerPath.serve). Its messages are the byte templates
// bracing_ros.cdr_template derives from the definitions (handed over as Layouts); the check and the law are the
// engine's (its C ABI, law_api.h: one implementation for both of the node's paths). A state this path does not
// answer itself (another layout, a refusal, a new run, a pending retune or target) goes back to Python as its
// bytes, to the node's Python path.
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>
#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rmw/serialized_message.h>
#include <time.h>

#include <cstdint>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bracing_engine/law_api.h"
#include "common.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using bracing_rcl::check;
using bracing_rcl::kNsPerS;
using bracing_rcl::Layout;
using bracing_rcl::monotonic_s;
using bracing_rcl::publish_bytes;

// [ns] CLOCK_REALTIME: the clock of the middleware's reception timestamps (Fast DDS: the system clock).
std::int64_t realtime_ns() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return std::int64_t{now.tv_sec} * kNsPerS + now.tv_nsec;
}

enum class Status { python, answered, law_failed, law_internal, not_finite };

// What serve did with one state, for the node's Python side (its bookkeeping, its log).
struct Outcome {
  Status status = Status::python;
  std::int64_t stamp_ns = 0;
  std::optional<nb::bytes> data, command, state;  // python: the state's bytes; answered: the answer's (batching)
  std::vector<std::uint8_t> data_kept, command_kept, state_kept;  // those bytes, until the GIL is held again
  double taken_at = 0.0, command_out_at = 0.0, done_at = 0.0;  // [s] CLOCK_MONOTONIC
  double written_s = 0.0;  // [s] in rcl_publish (the DDS writes)
  double landed_s = -1.0;  // [s] from the middleware's reception of the state to its take (-1: not told)
  bool damped = false;
  std::vector<double> hand_desired, hand_actual, dq;  // answered: for the null-space watch
  std::string message;  // law_failed, law_internal: the exception's
};

// What one serve did: the states taken in order, and why it returned.
struct Served {
  std::vector<Outcome> outcomes;
  std::vector<std::size_t> others_ready;  // the other subscriptions with a message (their index)
  bool interrupted = false;  // the guard condition (a stop signal) was triggered
  bool timed_out = false;  // nothing came within the timeout
};

class ControllerPath {
 public:
  ControllerPath(nb::capsule law_api, std::uintptr_t context, std::uintptr_t state_subscription,
                 std::vector<std::uintptr_t> other_subscriptions, std::uintptr_t guard_condition,
                 std::uintptr_t command_publisher, std::uintptr_t state_publisher, const Layout& joint_state,
                 const Layout& command, const Layout& controller_state, bool keep_bytes)
      : law_api_(law_api), api_(static_cast<const BracingLawApi*>(law_api.data())),
        subscription_(reinterpret_cast<const rcl_subscription_t*>(state_subscription)),
        guard_condition_(reinterpret_cast<const rcl_guard_condition_t*>(guard_condition)),
        command_publisher_(reinterpret_cast<const rcl_publisher_t*>(command_publisher)),
        state_publisher_(reinterpret_cast<const rcl_publisher_t*>(state_publisher)), joint_state_(joint_state),
        command_(command), controller_state_(controller_state), keep_bytes_(keep_bytes) {
    if (std::strcmp(law_api.name(), BRACING_LAW_API_CAPSULE) != 0 || api_->version != BRACING_LAW_API_VERSION) {
      throw std::invalid_argument("not the engine's law_api (or another version of it)");
    }
    const std::size_t n = static_cast<std::size_t>(api_->joints), b = static_cast<std::size_t>(api_->braces);
    if (joint_state_.values() != 3 * n || command_.values() != n || controller_state_.values() != 7 + n + 7 * b) {
      throw std::invalid_argument("the layouts do not fit the law's joints and braces");
    }
    q_.resize(n), dq_.resize(n), command_values_.resize(n), state_values_.resize(controller_state_.values());
    for (const std::uintptr_t other : other_subscriptions) {
      others_.push_back(reinterpret_cast<const rcl_subscription_t*>(other));
    }
    rcutils_allocator_t allocator = rcutils_get_default_allocator();
    check(rmw_serialized_message_init(&taken_, 0, &allocator), "rmw_serialized_message_init");
    check(rcl_wait_set_init(&wait_set_, 1 + others_.size(), 1, 0, 0, 0, 0,
                            reinterpret_cast<rcl_context_t*>(context), allocator),
          "rcl_wait_set_init");
  }
  ~ControllerPath() {
    if (rcl_wait_set_fini(&wait_set_) != RCL_RET_OK) rcl_reset_error();  // nothing more to do at the end
    (void)rmw_serialized_message_fini(&taken_);
  }
  ControllerPath(const ControllerPath&) = delete;
  ControllerPath& operator=(const ControllerPath&) = delete;

  // Wait up to timeout_ns for joint_states and answer each as it comes (when `answer`, and it needs nothing
  // else: its layout the template's, the check passed, not before previous_ns), without the GIL, until `limit`
  // states are taken or something needs Python: a state it does not answer (its bytes back) or the law's
  // failure, a message on another subscription, the guard condition, the timeout. The states of a wait are
  // all taken before the others are looked at (a target is followed from the next state on).
  Served serve(std::optional<std::int64_t> previous_ns, bool answer, std::size_t limit, std::int64_t timeout_ns) {
    Served served;
    {
      nb::gil_scoped_release unlocked;
      while (served.outcomes.size() < limit && !wait(timeout_ns, served)) {
        if (!take_queued(previous_ns, answer, limit, served)) break;
        if (served.interrupted || !served.others_ready.empty()) break;
      }
    }
    for (Outcome& out : served.outcomes) {
      to_python(out.data_kept, out.data);
      to_python(out.command_kept, out.command);
      to_python(out.state_kept, out.state);
    }
    return served;
  }

 private:
  // rcl_wait on the subscriptions and the guard condition; true when it timed out (else what is ready noted).
  bool wait(std::int64_t timeout_ns, Served& served) {
    check(rcl_wait_set_clear(&wait_set_), "rcl_wait_set_clear");
    check(rcl_wait_set_add_subscription(&wait_set_, subscription_, nullptr), "rcl_wait_set_add_subscription");
    for (const rcl_subscription_t* other : others_) {
      check(rcl_wait_set_add_subscription(&wait_set_, other, nullptr), "rcl_wait_set_add_subscription");
    }
    check(rcl_wait_set_add_guard_condition(&wait_set_, guard_condition_, nullptr), "rcl_wait_set_add_guard_condition");
    const rcl_ret_t ret = rcl_wait(&wait_set_, timeout_ns);
    if (ret == RCL_RET_TIMEOUT) return served.timed_out = true;
    check(ret, "rcl_wait");
    for (std::size_t k = 0; k < others_.size(); ++k) {
      if (wait_set_.subscriptions[1 + k] != nullptr) served.others_ready.push_back(k);
    }
    served.interrupted = wait_set_.guard_conditions[0] != nullptr;
    return false;
  }

  // Every joint_states waiting, each answered or handed over; false once one needs Python (the rest wait).
  bool take_queued(std::optional<std::int64_t>& previous_ns, bool answer, std::size_t limit, Served& served) {
    while (served.outcomes.size() < limit) {
      Outcome out;
      rmw_message_info_t info = rmw_get_zero_initialized_message_info();
      const rcl_ret_t ret = rcl_take_serialized_message(subscription_, &taken_, &info, nullptr);
      if (ret == RCL_RET_SUBSCRIPTION_TAKE_FAILED) return true;
      check(ret, "rcl_take_serialized_message");
      out.taken_at = monotonic_s();
      if (info.received_timestamp > 0) {
        out.landed_s = 1e-9 * static_cast<double>(realtime_ns() - info.received_timestamp);
      }
      out.status = answer ? respond(previous_ns, out) : Status::python;
      if (out.status == Status::python) {
        out.data_kept.assign(taken_.buffer, taken_.buffer + taken_.buffer_length);
      } else if (out.status == Status::answered && keep_bytes_) {
        out.command_kept = command_bytes_, out.state_kept = state_bytes_;
      }
      const bool answered = out.status == Status::answered;
      if (answered) previous_ns = out.stamp_ns;
      served.outcomes.push_back(std::move(out));
      if (!answered) return false;
    }
    return true;
  }

  static void to_python(std::vector<std::uint8_t>& kept, std::optional<nb::bytes>& field) {
    if (kept.empty()) return;
    field = nb::bytes(reinterpret_cast<const char*>(kept.data()), kept.size());
    std::vector<std::uint8_t>().swap(kept);
  }

  // Decode, check, answer and publish (without the GIL).
  Status respond(std::optional<std::int64_t> previous_ns, Outcome& out) {
    const std::uint8_t* data = taken_.buffer;
    if (!joint_state_.matches(data, taken_.buffer_length)) return Status::python;
    const std::int64_t stamp_ns = joint_state_.stamp_ns(data);
    const std::size_t n = q_.size();
    for (std::size_t k = 0; k < n; ++k) q_[k] = joint_state_.value(data, k), dq_[k] = joint_state_.value(data, n + k);
    char kind[8], message[8];  // only whether: the Python path says why
    if (api_->state_refusal(stamp_ns, q_.data(), dq_.data(), static_cast<int>(n), kind, message, sizeof kind)) {
      return Status::python;
    }
    if (previous_ns && stamp_ns < *previous_ns) return Status::python;  // a new run: the Python path restarts
    out.stamp_ns = stamp_ns;
    return law_answer(stamp_ns, out);
  }

  Status law_answer(std::int64_t stamp_ns, Outcome& out) {
    const std::size_t n = q_.size(), b = static_cast<std::size_t>(api_->braces);
    double* s = state_values_.data();  // hand_desired, hand_actual, f_nd, brace_desired, brace_actual, command, time
    BracingLawAnswer answer{command_values_.data(), s, s + 3, s + 6, s + 6 + b, s + 6 + 4 * b, 0.0, 0};
    char error[512] = "";
    const int status = api_->answer(api_, stamp_ns, q_.data(), dq_.data(), &answer, error, sizeof error);
    if (status != BRACING_ANSWERED) {
      out.message = error;
      return status == BRACING_LAW_FAILED ? Status::law_failed
             : status == BRACING_NOT_FINITE ? Status::not_finite
                                             : Status::law_internal;
    }
    out.damped = answer.damped != 0;
    out.hand_desired.assign(s, s + 3), out.hand_actual.assign(s + 3, s + 6), out.dq = dq_;
    std::memcpy(s + 6 + 7 * b, command_values_.data(), n * sizeof(double));
    s[6 + 7 * b + n] = answer.compute_time_s;
    command_.fill(command_bytes_, stamp_ns, command_values_);
    out.written_s += publish_bytes(command_publisher_, command_bytes_, "motor_command");
    out.command_out_at = monotonic_s();
    controller_state_.fill(state_bytes_, stamp_ns, state_values_);
    out.written_s += publish_bytes(state_publisher_, state_bytes_, "controller_state");
    out.done_at = monotonic_s();
    return Status::answered;
  }

  nb::capsule law_api_;  // keeps the law alive
  const BracingLawApi* api_;
  const rcl_subscription_t* subscription_;
  const rcl_guard_condition_t* guard_condition_;
  std::vector<const rcl_subscription_t*> others_;
  rcl_wait_set_t wait_set_ = rcl_get_zero_initialized_wait_set();
  const rcl_publisher_t* command_publisher_;
  const rcl_publisher_t* state_publisher_;
  Layout joint_state_, command_, controller_state_;
  bool keep_bytes_;
  rcl_serialized_message_t taken_ = rmw_get_zero_initialized_serialized_message();
  std::vector<double> q_, dq_, command_values_, state_values_;
  std::vector<std::uint8_t> command_bytes_, state_bytes_;
};

}  // namespace

NB_MODULE(_rcl, m) {
  m.doc() = "The nodes' per-state paths on rcl's C API (bracing_rcl.ControllerPath, bracing_rcl.CommandPath)";
  nb::enum_<Status>(m, "Status", "what ControllerPath.serve did with one state")
      .value("python", Status::python, "taken, not answered: its bytes are for the node's Python path")
      .value("answered", Status::answered, "motor_command and controller_state published")
      .value("law_failed", Status::law_failed, "the law raised ValueError or ArithmeticError's like: message")
      .value("law_internal", Status::law_internal, "the law raised another exception: message '<type>: <text>'")
      .value("not_finite", Status::not_finite, "the law's output is not finite: nothing sent");
  nb::class_<Layout>(m, "Layout", "a message's byte template (bracing_ros.cdr_template.Template.layout)")
      .def(nb::init<nb::bytes, std::vector<std::pair<std::uint32_t, std::uint32_t>>, std::vector<std::uint32_t>,
                    std::string>(),
           "bytes"_a, "constants"_a, "offsets"_a, "codes"_a);
  nb::class_<Outcome>(m, "Outcome", "what serve did with one state")
      .def_ro("status", &Outcome::status)
      .def_ro("stamp_ns", &Outcome::stamp_ns, "[ns] the state's stamp (answered and the law's outcomes)")
      .def_ro("data", &Outcome::data, "python: the state's CDR bytes")
      .def_ro("command", &Outcome::command, "answered, keeping bytes: motor_command's")
      .def_ro("state", &Outcome::state, "answered, keeping bytes: controller_state's")
      .def_ro("taken_at", &Outcome::taken_at, "[s] CLOCK_MONOTONIC (time.perf_counter's on Linux): taken")
      .def_ro("command_out_at", &Outcome::command_out_at, "[s] the command published")
      .def_ro("done_at", &Outcome::done_at, "[s] the controller_state published")
      .def_ro("written_s", &Outcome::written_s, "[s] in rcl_publish")
      .def_ro("landed_s", &Outcome::landed_s, "[s] from the state's reception (DDS) to its take (-1: unknown)")
      .def_ro("damped", &Outcome::damped, "the law used a damped inverse")
      .def_ro("hand_desired", &Outcome::hand_desired, "answered: the hand's desired position [m]")
      .def_ro("hand_actual", &Outcome::hand_actual, "answered: the hand's position [m]")
      .def_ro("dq", &Outcome::dq, "answered: the state's joint velocities, the law's order")
      .def_ro("message", &Outcome::message, "law_failed, law_internal: what the law raised");
  nb::class_<Served>(m, "Served", "what one serve did")
      .def_ro("outcomes", &Served::outcomes, "the states taken, in order")
      .def_ro("others_ready", &Served::others_ready, "the other subscriptions with a message (their index)")
      .def_ro("interrupted", &Served::interrupted, "the guard condition was triggered")
      .def_ro("timed_out", &Served::timed_out, "nothing came within the timeout");
  nb::class_<ControllerPath>(m, "ControllerPath", "the controller's per-state path on rcl")
      .def(nb::init<nb::capsule, std::uintptr_t, std::uintptr_t, std::vector<std::uintptr_t>, std::uintptr_t,
                    std::uintptr_t, std::uintptr_t, const Layout&, const Layout&, const Layout&, bool>(),
           "law_api"_a, "context"_a, "state_subscription"_a, "other_subscriptions"_a, "guard_condition"_a,
           "command_publisher"_a, "state_publisher"_a, "joint_state"_a, "command"_a, "controller_state"_a,
           "keep_bytes"_a)
      .def("serve", &ControllerPath::serve, "previous_ns"_a.none(), "answer"_a, "limit"_a, "timeout_ns"_a,
           "wait for joint_states and answer them as they come, until `limit` are taken or one needs Python, "
           "another subscription has a message, the guard condition is triggered or timeout_ns [ns] passes");
  bracing_rcl::bind_simulator_path(m);
}
