// What the nodes' per-state paths on rcl share (controller_path.cpp, simulator_path.cpp): a message's byte
// template as bracing_ros.cdr_template.Template.layout hands it over, and rcl's failures as exceptions.
#ifndef BRACING_RCL_COMMON_HPP
#define BRACING_RCL_COMMON_HPP

#include <nanobind/nanobind.h>
#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rmw/serialized_message.h>
#include <time.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace bracing_rcl {

namespace nb = nanobind;

constexpr std::int64_t kNsPerS = 1000000000;

// [s] CLOCK_MONOTONIC: time.perf_counter's and time.monotonic's clock on Linux.
inline double monotonic_s() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

// An rcl call's failure as an exception (nanobind: a RuntimeError) with rcl's message.
inline void check(rcl_ret_t ret, const char* what) {
  if (ret == RCL_RET_OK) return;
  std::string text = std::string(what) + " failed: " + rcl_get_error_string().str;
  rcl_reset_error();
  throw std::runtime_error(text);
}

// Take the next message's CDR bytes into `taken`; whether one was there.
inline bool take_bytes(const rcl_subscription_t* subscription, rcl_serialized_message_t& taken) {
  rmw_message_info_t info = rmw_get_zero_initialized_message_info();
  const rcl_ret_t ret = rcl_take_serialized_message(subscription, &taken, &info, nullptr);
  if (ret == RCL_RET_SUBSCRIPTION_TAKE_FAILED) return false;
  check(ret, "rcl_take_serialized_message");
  return true;
}

// Publish a message's CDR bytes on an rcl publisher; [s] the write's time.
inline double publish_bytes(const rcl_publisher_t* publisher, std::vector<std::uint8_t>& bytes, const char* topic) {
  const double start = monotonic_s();
  rcl_serialized_message_t message = rmw_get_zero_initialized_serialized_message();
  message.buffer = bytes.data();
  message.buffer_length = message.buffer_capacity = bytes.size();
  message.allocator = rcutils_get_default_allocator();
  const rcl_ret_t ret = rcl_publish_serialized_message(publisher, &message, nullptr);
  if (ret != RCL_RET_OK) {
    std::string text = std::string("publishing ") + topic + " failed: " + rcl_get_error_string().str;
    rcl_reset_error();
    throw std::runtime_error(text);
  }
  return monotonic_s() - start;
}

// A message's byte template: its bytes with every slot zero, the constant runs a message of this layout
// repeats, and where each value of the slots goes. The values are a header stamp (int32 sec, uint32
// nanosec) then float64s and bools (a ContactState's active: one byte, 1 or 0).
class Layout {
 public:
  Layout(nb::bytes bytes, std::vector<std::pair<std::uint32_t, std::uint32_t>> constants,
         std::vector<std::uint32_t> offsets, std::string codes)
      : bytes_(static_cast<const std::uint8_t*>(bytes.data()),
               static_cast<const std::uint8_t*>(bytes.data()) + bytes.size()),
        constants_(std::move(constants)), offsets_(std::move(offsets)) {
    if (codes.size() != offsets_.size() || codes.size() < 2 || codes.compare(0, 2, "iI") != 0 ||
        codes.find_first_not_of("d?", 2) != std::string::npos) {
      throw std::invalid_argument("a layout's values are a stamp (iI) then float64s and bools, not " + codes);
    }
    for (const auto& [offset, length] : constants_) {
      if (std::size_t{offset} + length > bytes_.size()) throw std::invalid_argument("a constant run past the end");
    }
    for (std::size_t k = 0; k < offsets_.size(); ++k) {
      const std::size_t size = k < 2 ? 4 : codes[k] == '?' ? 1 : 8;
      if (std::size_t{offsets_[k]} + size > bytes_.size()) throw std::invalid_argument("a value past the end");
      if (k >= 2) bools_.push_back(codes[k] == '?');
    }
  }
  std::size_t values() const { return offsets_.size() - 2; }  // the float64s
  // Whether data has this layout (the same constants; bytes past its end ignored, as rclpy's messages carry).
  bool matches(const std::uint8_t* data, std::size_t size) const {
    if (size < bytes_.size()) return false;
    for (const auto& [offset, length] : constants_) {
      if (std::memcmp(data + offset, bytes_.data() + offset, length) != 0) return false;
    }
    return true;
  }
  std::int64_t stamp_ns(const std::uint8_t* data) const {
    std::int32_t sec;
    std::uint32_t nanosec;
    std::memcpy(&sec, data + offsets_[0], 4);
    std::memcpy(&nanosec, data + offsets_[1], 4);
    return std::int64_t{sec} * kNsPerS + nanosec;
  }
  double value(const std::uint8_t* data, std::size_t k) const {
    if (bools_[k]) return data[offsets_[2 + k]] != 0 ? 1.0 : 0.0;
    double v;
    std::memcpy(&v, data + offsets_[2 + k], 8);
    return v;
  }
  // The message stamped stamp_ns (sec, nanosec as rclpy's Time.to_msg: nanosec in [0, 1e9)) with values.
  void fill(std::vector<std::uint8_t>& out, std::int64_t stamp_ns, const std::vector<double>& values) const {
    out = bytes_;
    std::int64_t sec = stamp_ns / kNsPerS, nanosec = stamp_ns % kNsPerS;
    if (nanosec < 0) sec -= 1, nanosec += kNsPerS;
    const auto sec32 = static_cast<std::int32_t>(sec);
    const auto nanosec32 = static_cast<std::uint32_t>(nanosec);
    std::memcpy(out.data() + offsets_[0], &sec32, 4);
    std::memcpy(out.data() + offsets_[1], &nanosec32, 4);
    for (std::size_t k = 0; k < values.size(); ++k) {
      std::uint8_t* at = out.data() + offsets_[2 + k];
      if (bools_[k]) {
        *at = values[k] != 0.0 ? 1 : 0;
      } else {
        std::memcpy(at, &values[k], 8);
      }
    }
  }

 private:
  std::vector<std::uint8_t> bytes_;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> constants_;
  std::vector<std::uint32_t> offsets_;
  std::vector<bool> bools_;  // per value: a bool's one byte, else a float64's eight
};

// The simulator's command path (simulator_path.cpp), bound into the module with the controller's.
void bind_simulator_path(nb::module_& m);

}  // namespace bracing_rcl

#endif
