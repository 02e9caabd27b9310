// The simulator node's command path on rcl's C API: wait for a motor_command (on a wait set of its own, with a
// stop signal's guard condition), take it and read it, with the GIL released,
// when it has the layout of the MotorCommand byte template (bracing_ros.wire: the configured mode, the joints
// by name in the simulator's order) and needs no word said under the engine's value rule (its C ABI,
// command_api.h, which the Python path calls too): every value finite and within its joint's limit. Any other
// message (another layout or order, a non-finite or saturated value) goes back to Python as its bytes, to the
// node's Python path, which says why it refuses or saturates it: one implementation of each refusal. The stamp
// is the stepping policy's to judge (SimulatorStepper.offer) on both paths.
// And the state out: joint_states and /clock written from their templates and published, without the GIL;
// then the step's reports (contact_wrench/<name>, contacts, motor_state) likewise.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/vector.h>
#include <rcl/rcl.h>
#include <rmw/serialized_message.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "bracing_engine/command_api.h"
#include "common.hpp"

namespace bracing_rcl {
namespace {

using namespace nb::literals;

enum class CommandStatus { empty, python, taken };

// What one take did.
struct CommandTake {
  CommandStatus status = CommandStatus::empty;
  std::int64_t stamp_ns = 0;
  std::vector<double> values;    // taken: the command, the simulator's joint order
  std::optional<nb::bytes> data;  // python: the message's CDR bytes
};

class CommandPath {
 public:
  CommandPath(nb::capsule command_api, std::uintptr_t subscription, std::uintptr_t context,
              std::uintptr_t guard_condition, const Layout& command, std::vector<double> limit)
      : command_api_(command_api), api_(static_cast<const BracingCommandApi*>(command_api.data())),
        subscription_(reinterpret_cast<const rcl_subscription_t*>(subscription)),
        guard_condition_(reinterpret_cast<const rcl_guard_condition_t*>(guard_condition)), command_(command),
        limit_(std::move(limit)), values_(limit_.size()), non_finite_(limit_.size()) {
    if (std::strcmp(command_api.name(), BRACING_COMMAND_API_CAPSULE) != 0 ||
        api_->version != BRACING_COMMAND_API_VERSION) {
      throw std::invalid_argument("not the engine's command_api (or another version of it)");
    }
    if (command_.values() != limit_.size()) throw std::invalid_argument("the layout does not fit the joints' limits");
    rcutils_allocator_t allocator = rcutils_get_default_allocator();
    check(rmw_serialized_message_init(&taken_, 0, &allocator), "rmw_serialized_message_init");
    check(rcl_wait_set_init(&wait_set_, 1, 1, 0, 0, 0, 0, reinterpret_cast<rcl_context_t*>(context), allocator),
          "rcl_wait_set_init");
  }
  ~CommandPath() {
    if (rcl_wait_set_fini(&wait_set_) != RCL_RET_OK) rcl_reset_error();  // nothing more to do at the end
    (void)rmw_serialized_message_fini(&taken_);
  }
  CommandPath(const CommandPath&) = delete;
  CommandPath& operator=(const CommandPath&) = delete;

  // Wait up to timeout_ns for a motor_command (or the guard condition: a stop signal), the GIL released; whether
  // one is there to take.
  bool wait(std::int64_t timeout_ns) {
    nb::gil_scoped_release unlocked;
    check(rcl_wait_set_clear(&wait_set_), "rcl_wait_set_clear");
    check(rcl_wait_set_add_subscription(&wait_set_, subscription_, nullptr), "rcl_wait_set_add_subscription");
    check(rcl_wait_set_add_guard_condition(&wait_set_, guard_condition_, nullptr), "rcl_wait_set_add_guard_condition");
    const rcl_ret_t ret = rcl_wait(&wait_set_, timeout_ns);
    if (ret == RCL_RET_TIMEOUT) return false;
    check(ret, "rcl_wait");
    return wait_set_.subscriptions[0] != nullptr;
  }

  // Take the next motor_command, if one is there: read here, or its bytes for the Python path.
  CommandTake take() {
    CommandTake out;
    {
      nb::gil_scoped_release unlocked;
      if (!take_bytes(subscription_, taken_)) return out;
      out.status = read(out) ? CommandStatus::taken : CommandStatus::python;
    }
    if (out.status == CommandStatus::python) {
      out.data = nb::bytes(reinterpret_cast<const char*>(taken_.buffer), taken_.buffer_length);
    }
    return out;
  }

 private:
  // Whether the message needs nothing of the Python path: the template's layout, and the value rule's verdict
  // that every value is finite and none saturated (the Python path says why otherwise).
  bool read(CommandTake& out) {
    const std::uint8_t* data = taken_.buffer;
    if (!command_.matches(data, taken_.buffer_length)) return false;
    const std::size_t n = limit_.size();
    for (std::size_t k = 0; k < n; ++k) values_[k] = command_.value(data, k);
    out.values.resize(n);
    int saturated = 0;
    if (api_->check_command(values_.data(), limit_.data(), n, out.values.data(), &saturated, non_finite_.data()) > 0 ||
        saturated) {
      out.values.clear();
      return false;
    }
    out.stamp_ns = command_.stamp_ns(data);
    return true;
  }

  nb::capsule command_api_;  // holds the engine's table
  const BracingCommandApi* api_;
  const rcl_subscription_t* subscription_;
  const rcl_guard_condition_t* guard_condition_;
  Layout command_;
  std::vector<double> limit_, values_;
  std::vector<std::size_t> non_finite_;
  rcl_serialized_message_t taken_ = rmw_get_zero_initialized_serialized_message();
  rcl_wait_set_t wait_set_ = rcl_get_zero_initialized_wait_set();
};

// A step's numbers as the engine's answer and the stepping policy hand them over (numpy arrays).
using Column = nb::ndarray<const double, nb::ndim<1>, nb::device::cpu>;
using Points = nb::ndarray<const double, nb::ndim<2>, nb::device::cpu>;  // p x 3
using Flags = nb::ndarray<const bool, nb::ndim<1>, nb::device::cpu>;

void append(std::vector<double>& values, const Column& column) {
  for (std::size_t k = 0; k < column.shape(0); ++k) values.push_back(column(k));
}

// What one StatePath.publish sent: its bytes (for the record batch), and the writes' time.
struct StateSent {
  std::optional<nb::bytes> joint_state, clock;  // keeping bytes: the messages published
  double written_s = 0.0;                       // [s] in rcl_publish
};

class StatePath {
 public:
  StatePath(std::uintptr_t joint_publisher, std::uintptr_t clock_publisher, const Layout& joint_state,
            const Layout& clock, bool keep_bytes)
      : joint_publisher_(reinterpret_cast<const rcl_publisher_t*>(joint_publisher)),
        clock_publisher_(reinterpret_cast<const rcl_publisher_t*>(clock_publisher)), joint_state_(joint_state),
        clock_(clock), keep_bytes_(keep_bytes) {
    if (joint_state_.values() % 3 != 0 || clock_.values() != 0) throw std::invalid_argument("not a state's layouts");
  }

  // joint_states (position, velocity, effort) then /clock, stamped stamp_ns.
  StateSent publish(std::int64_t stamp_ns, const Column& position, const Column& velocity, const Column& effort) {
    const std::size_t n = joint_state_.values() / 3;
    if (position.shape(0) != n || velocity.shape(0) != n || effort.shape(0) != n) {
      throw std::invalid_argument("a state's vectors do not fit its layout");
    }
    StateSent out;
    {
      nb::gil_scoped_release unlocked;
      values_.clear();
      for (const Column* column : {&position, &velocity, &effort}) append(values_, *column);
      joint_state_.fill(joint_bytes_, stamp_ns, values_);
      out.written_s += publish_bytes(joint_publisher_, joint_bytes_, "joint_states");
      clock_.fill(clock_bytes_, stamp_ns, {});
      out.written_s += publish_bytes(clock_publisher_, clock_bytes_, "/clock");
    }
    if (keep_bytes_) {
      out.joint_state = nb::bytes(reinterpret_cast<const char*>(joint_bytes_.data()), joint_bytes_.size());
      out.clock = nb::bytes(reinterpret_cast<const char*>(clock_bytes_.data()), clock_bytes_.size());
    }
    return out;
  }

 private:
  const rcl_publisher_t* joint_publisher_;
  const rcl_publisher_t* clock_publisher_;
  Layout joint_state_, clock_;
  bool keep_bytes_;
  std::vector<double> values_;
  std::vector<std::uint8_t> joint_bytes_, clock_bytes_;
};

void append_row(std::vector<double>& values, const Points& points, std::size_t row) {
  for (std::size_t k = 0; k < 3; ++k) values.push_back(points(row, k));
}

// What one ReportPath.publish sent: its bytes (for the record batch), and the writes' time.
struct ReportsSent {
  std::optional<std::vector<nb::bytes>> wrenches;  // keeping bytes: each contact_wrench/<name>'s
  std::optional<nb::bytes> contacts, motor_state;  // keeping bytes
  double written_s = 0.0;                          // [s] in rcl_publish
};

// The step's reports out on rcl, in the Python path's order: each configured contact's WrenchStamped, then
// Contacts, then MotorState, each written from its template (the names, frames and lengths fixed per run).
class ReportPath {
 public:
  ReportPath(std::vector<std::uintptr_t> wrench_publishers, std::uintptr_t contacts_publisher,
             std::uintptr_t motor_publisher, const Layout& wrench, const Layout& contacts, const Layout& motor_state,
             bool keep_bytes)
      : contacts_publisher_(reinterpret_cast<const rcl_publisher_t*>(contacts_publisher)),
        motor_publisher_(reinterpret_cast<const rcl_publisher_t*>(motor_publisher)), wrench_(wrench),
        contacts_(contacts), motor_state_(motor_state), keep_bytes_(keep_bytes),
        wrench_bytes_(wrench_publishers.size()) {
    for (const auto handle : wrench_publishers) wrench_publishers_.push_back(reinterpret_cast<const rcl_publisher_t*>(handle));
    if (wrench_.values() != 3 || contacts_.values() % kContactValues != 0) {
      throw std::invalid_argument("not a step's reports' layouts");
    }
  }

  // The reports of the step stamped stamp_ns: forces[j] per configured contact; per contact of the set (p)
  // held, positions, normals, normal_force, friction_force, slip_velocity, residual; the motors' voltage,
  // current, power, temperature (empty without the thermal model) and energies (consumed, net, copper loss).
  ReportsSent publish(std::int64_t stamp_ns, const std::vector<Column>& forces, const Flags& held,
                      const Points& positions, const Points& normals, const Column& normal_force,
                      const Column& friction_force, const Points& slip_velocity, const Column& residual,
                      const Column& voltage, const Column& current, const Column& power, const Column& temperature,
                      const std::array<double, 3>& energies) {
    const std::size_t p = contacts_.values() / kContactValues;
    if (forces.size() != wrench_publishers_.size() || held.shape(0) != p || residual.shape(0) != p) {
      throw std::invalid_argument("a step's contacts do not fit the reports' layouts");
    }
    const std::size_t motor_values = voltage.shape(0) + current.shape(0) + power.shape(0) + temperature.shape(0) + 3;
    if (motor_values != motor_state_.values()) throw std::invalid_argument("a step's motors do not fit motor_state's layout");
    ReportsSent out;
    {
      nb::gil_scoped_release unlocked;
      for (std::size_t j = 0; j < forces.size(); ++j) {
        values_.clear();
        append(values_, forces[j]);
        wrench_.fill(wrench_bytes_[j], stamp_ns, values_);
        out.written_s += publish_bytes(wrench_publishers_[j], wrench_bytes_[j], "contact_wrench");
      }
      contact_values(held, positions, normals, normal_force, friction_force, slip_velocity, residual);
      contacts_.fill(contacts_bytes_, stamp_ns, values_);
      out.written_s += publish_bytes(contacts_publisher_, contacts_bytes_, "contacts");
      values_.clear();
      for (const Column* column : {&voltage, &current, &power, &temperature}) append(values_, *column);
      values_.insert(values_.end(), energies.begin(), energies.end());
      motor_state_.fill(motor_bytes_, stamp_ns, values_);
      out.written_s += publish_bytes(motor_publisher_, motor_bytes_, "motor_state");
    }
    if (keep_bytes_) keep(out);
    return out;
  }

 private:
  static constexpr std::size_t kContactValues = 13;  // a ContactState's: active, 3 + 3, 2, 3, 1

  // values_: each contact's, in ContactState's order.
  void contact_values(const Flags& held, const Points& positions, const Points& normals, const Column& normal_force,
                      const Column& friction_force, const Points& slip_velocity, const Column& residual) {
    values_.clear();
    for (std::size_t j = 0; j < held.shape(0); ++j) {
      values_.push_back(held(j) ? 1.0 : 0.0);
      append_row(values_, positions, j);
      append_row(values_, normals, j);
      values_.push_back(normal_force(j));
      values_.push_back(friction_force(j));
      append_row(values_, slip_velocity, j);
      values_.push_back(residual(j));
    }
  }

  static nb::bytes bytes_of(const std::vector<std::uint8_t>& data) {
    return nb::bytes(reinterpret_cast<const char*>(data.data()), data.size());
  }

  void keep(ReportsSent& out) const {
    out.wrenches.emplace();
    for (const auto& data : wrench_bytes_) out.wrenches->push_back(bytes_of(data));
    out.contacts = bytes_of(contacts_bytes_);
    out.motor_state = bytes_of(motor_bytes_);
  }

  std::vector<const rcl_publisher_t*> wrench_publishers_;
  const rcl_publisher_t* contacts_publisher_;
  const rcl_publisher_t* motor_publisher_;
  Layout wrench_, contacts_, motor_state_;
  bool keep_bytes_;
  std::vector<double> values_;
  std::vector<std::vector<std::uint8_t>> wrench_bytes_;
  std::vector<std::uint8_t> contacts_bytes_, motor_bytes_;
};

}  // namespace

void bind_simulator_path(nb::module_& m) {
  nb::enum_<CommandStatus>(m, "CommandStatus", "what one CommandPath.take did")
      .value("empty", CommandStatus::empty, "no motor_command was there")
      .value("python", CommandStatus::python, "taken, not read: its bytes are for the node's Python path")
      .value("taken", CommandStatus::taken, "read: stamp_ns and values");
  nb::class_<CommandTake>(m, "CommandTake", "what one CommandPath.take did")
      .def_ro("status", &CommandTake::status)
      .def_ro("stamp_ns", &CommandTake::stamp_ns, "taken: [ns] the command's stamp")
      .def_ro("values", &CommandTake::values, "taken: the command, the simulator's joint order [V or N m]")
      .def_ro("data", &CommandTake::data, "python: the message's CDR bytes");
  nb::class_<CommandPath>(m, "CommandPath", "the simulator's motor_command path on rcl")
      .def(nb::init<nb::capsule, std::uintptr_t, std::uintptr_t, std::uintptr_t, const Layout&,
                    std::vector<double>>(),
           "command_api"_a, "subscription"_a, "context"_a, "guard_condition"_a, "command"_a, "limit"_a)
      .def("wait", &CommandPath::wait, "timeout_ns"_a,
           "wait up to timeout_ns [ns] for a motor_command (or the guard condition), the GIL released; whether one "
           "is there")
      .def("take", &CommandPath::take, "take the next motor_command and read it if it needs nothing else");
  nb::class_<StateSent>(m, "StateSent", "what one StatePath.publish sent")
      .def_ro("joint_state", &StateSent::joint_state, "keeping bytes: joint_states' CDR bytes")
      .def_ro("clock", &StateSent::clock, "keeping bytes: /clock's CDR bytes")
      .def_ro("written_s", &StateSent::written_s, "[s] in rcl_publish");
  nb::class_<StatePath>(m, "StatePath", "the simulator's state out on rcl: joint_states and /clock")
      .def(nb::init<std::uintptr_t, std::uintptr_t, const Layout&, const Layout&, bool>(), "joint_publisher"_a,
           "clock_publisher"_a, "joint_state"_a, "clock"_a, "keep_bytes"_a)
      .def("publish", &StatePath::publish, "stamp_ns"_a, "position"_a, "velocity"_a, "effort"_a,
           "joint_states then /clock stamped stamp_ns, published");
  nb::class_<ReportsSent>(m, "ReportsSent", "what one ReportPath.publish sent")
      .def_ro("wrenches", &ReportsSent::wrenches, "keeping bytes: each contact_wrench/<name>'s CDR bytes")
      .def_ro("contacts", &ReportsSent::contacts, "keeping bytes: contacts' CDR bytes")
      .def_ro("motor_state", &ReportsSent::motor_state, "keeping bytes: motor_state's CDR bytes")
      .def_ro("written_s", &ReportsSent::written_s, "[s] in rcl_publish");
  nb::class_<ReportPath>(m, "ReportPath", "the simulator's step reports on rcl: contact_wrench/*, contacts, motor_state")
      .def(nb::init<std::vector<std::uintptr_t>, std::uintptr_t, std::uintptr_t, const Layout&, const Layout&,
                    const Layout&, bool>(),
           "wrench_publishers"_a, "contacts_publisher"_a, "motor_publisher"_a, "wrench"_a, "contacts"_a,
           "motor_state"_a, "keep_bytes"_a)
      .def("publish", &ReportPath::publish, "stamp_ns"_a, "forces"_a, "held"_a, "positions"_a, "normals"_a,
           "normal_force"_a, "friction_force"_a, "slip_velocity"_a, "residual"_a, "voltage"_a, "current"_a, "power"_a,
           "temperature"_a, "energies"_a,
           "the step's reports stamped stamp_ns (forces [N] per configured contact, the contact set's, the motors'), "
           "published");
}

}  // namespace bracing_rcl
