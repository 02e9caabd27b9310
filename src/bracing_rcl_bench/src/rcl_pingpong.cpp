// One side of make bench's DDS bound without Python: a lockstep ping-pong of the pair's own messages
// between two processes over rcl's C API (bench/dds_bound.py, wire "rcl", starts both sides).
//
//   rcl_pingpong pong [--timeout=S]
//   rcl_pingpong ping [--n=N] [--repeats=R] [--warmup=W] [--discovery-timeout=S] [--timeout=S]
//
// ping plays the simulator: a sensor_msgs/JointState of 4 joints on "ping", a new stamp per message, then
// the wait for the bracing_msgs/MotorCommand answering it (matched by stamp) on "pong". pong plays the
// controller and answers every state at once (VOLTAGE, 4 values, the state's stamp). Message for message,
// topic for topic and QoS for QoS (bracing_ros.qos) what dds_bound.py's Python sides exchange; both sides
// check every field of what they receive. ping prints one JSON line: {"samples": [round trips/s, one per
// repeat], "round_trips": timed round trips, "checked": answers received and found as sent}.
// Exit status: 0 done; 1 an rcl error or a timeout; 2 bad arguments; 3 a message not as sent (stderr says
// which). pong ends on SIGINT or SIGTERM, or when its parent process is gone.
#include <bracing_msgs/msg/motor_command.h>
#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rosidl_runtime_c/primitives_sequence_functions.h>
#include <rosidl_runtime_c/string_functions.h>
#include <sensor_msgs/msg/joint_state.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

constexpr const char* kPingTopic = "ping";
constexpr const char* kPongTopic = "pong";
constexpr int kJoints = 4;
const char* const kJointNames[kJoints] = {"joint1", "joint2", "joint3", "joint4"};
// What ping sends (dds_bound.py's position, velocity and effort) and pong answers (its value) [SI units].
constexpr double kPosition[kJoints] = {0.1, 0.2, 0.3, 0.4};
constexpr double kVelocity[kJoints] = {0.0, 0.0, 0.0, 0.0};
constexpr double kEffort[kJoints] = {1.0, 2.0, 3.0, 4.0};
constexpr double kAnswer[kJoints] = {0.1, 0.2, 0.3, 0.4};
constexpr int64_t kNsPerS = 1000000000;

volatile std::sig_atomic_t g_stop = 0;
void on_stop_signal(int) { g_stop = 1; }

struct RclError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
struct ContentError : std::runtime_error {  // a message not as sent
  using std::runtime_error::runtime_error;
};

void check(rcl_ret_t ret, const char* what) {
  if (ret == RCL_RET_OK) return;
  std::string text = std::string(what) + " failed: " + rcl_get_error_string().str;
  rcl_reset_error();
  throw RclError(text);
}

// A handle's finalisation at the end: a failure there changes no result, so it is said and the end goes on.
void finish(rcl_ret_t ret, const char* what) {
  if (ret == RCL_RET_OK) return;
  std::fprintf(stderr, "rcl_pingpong: %s failed at shutdown: %s\n", what, rcl_get_error_string().str);
  rcl_reset_error();
}

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The nodes' QoS (bracing_ros.qos): STREAM_QOS for what they publish, SUBSCRIBE_QOS for what they take.
rmw_qos_profile_t qos(size_t depth, rmw_qos_durability_policy_t durability) {
  rmw_qos_profile_t profile = rmw_qos_profile_default;
  profile.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
  profile.depth = depth;
  profile.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
  profile.durability = durability;
  return profile;
}

// Each rcl handle owns itself: finalised in reverse order of creation, also when a later one fails.
struct InitOptions {
  rcl_init_options_t handle = rcl_get_zero_initialized_init_options();
  InitOptions() { check(rcl_init_options_init(&handle, rcl_get_default_allocator()), "rcl_init_options_init"); }
  ~InitOptions() { finish(rcl_init_options_fini(&handle), "rcl_init_options_fini"); }
};

struct Context {
  rcl_context_t handle = rcl_get_zero_initialized_context();
  explicit Context(const InitOptions& options) { check(rcl_init(0, nullptr, &options.handle, &handle), "rcl_init"); }
  ~Context() {
    if (rcl_context_is_valid(&handle)) finish(rcl_shutdown(&handle), "rcl_shutdown");
    finish(rcl_context_fini(&handle), "rcl_context_fini");
  }
};

struct NodeHandle {
  rcl_node_t handle = rcl_get_zero_initialized_node();
  NodeHandle(Context& context, const char* name) {
    rcl_node_options_t options = rcl_node_get_default_options();
    check(rcl_node_init(&handle, name, "", &context.handle, &options), "rcl_node_init");
  }
  ~NodeHandle() { finish(rcl_node_fini(&handle), "rcl_node_fini"); }
};

struct Publisher {
  rcl_publisher_t handle = rcl_get_zero_initialized_publisher();
  rcl_node_t* node;
  Publisher(NodeHandle& owner, const rosidl_message_type_support_t* type, const char* topic) : node(&owner.handle) {
    rcl_publisher_options_t options = rcl_publisher_get_default_options();
    options.qos = qos(10000, RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL);
    check(rcl_publisher_init(&handle, node, type, topic, &options), "rcl_publisher_init");
  }
  ~Publisher() { finish(rcl_publisher_fini(&handle, node), "rcl_publisher_fini"); }
  void publish(const void* message) { check(rcl_publish(&handle, message, nullptr), "rcl_publish"); }
};

struct Subscription {
  rcl_subscription_t handle = rcl_get_zero_initialized_subscription();
  rcl_node_t* node;
  Subscription(NodeHandle& owner, const rosidl_message_type_support_t* type, const char* topic)
      : node(&owner.handle) {
    rcl_subscription_options_t options = rcl_subscription_get_default_options();
    options.qos = qos(2000, RMW_QOS_POLICY_DURABILITY_VOLATILE);
    check(rcl_subscription_init(&handle, node, type, topic, &options), "rcl_subscription_init");
  }
  ~Subscription() { finish(rcl_subscription_fini(&handle, node), "rcl_subscription_fini"); }
  // The next message into ``message``; false when none is waiting.
  bool take(void* message) {
    rmw_message_info_t info;
    rcl_ret_t ret = rcl_take(&handle, message, &info, nullptr);
    if (ret == RCL_RET_SUBSCRIPTION_TAKE_FAILED) return false;
    check(ret, "rcl_take");
    return true;
  }
};

struct WaitSet {
  rcl_wait_set_t handle = rcl_get_zero_initialized_wait_set();
  explicit WaitSet(Context& context) {
    check(rcl_wait_set_init(&handle, 1, 0, 0, 0, 0, 0, &context.handle, rcl_get_default_allocator()),
          "rcl_wait_set_init");
  }
  ~WaitSet() { finish(rcl_wait_set_fini(&handle), "rcl_wait_set_fini"); }
  // Whether ``subscription`` has a message within ``timeout_s``.
  bool wait(Subscription& subscription, double timeout_s) {
    check(rcl_wait_set_clear(&handle), "rcl_wait_set_clear");
    check(rcl_wait_set_add_subscription(&handle, &subscription.handle, nullptr), "rcl_wait_set_add_subscription");
    rcl_ret_t ret = rcl_wait(&handle, static_cast<int64_t>(timeout_s * 1e9));
    if (ret == RCL_RET_TIMEOUT) return false;
    check(ret, "rcl_wait");
    return handle.subscriptions[0] != nullptr;
  }
};

// A message of C type support, initialised and finalised with it.
template <class M, bool (*Init)(M*), void (*Fini)(M*)>
struct Message {
  M data;
  Message() {
    if (!Init(&data)) throw RclError("a message could not be initialised (out of memory)");
  }
  ~Message() { Fini(&data); }
  Message(const Message&) = delete;
  Message& operator=(const Message&) = delete;
};
using JointState = Message<sensor_msgs__msg__JointState, sensor_msgs__msg__JointState__init,
                           sensor_msgs__msg__JointState__fini>;
using MotorCommand = Message<bracing_msgs__msg__MotorCommand, bracing_msgs__msg__MotorCommand__init,
                             bracing_msgs__msg__MotorCommand__fini>;

void fill_names(rosidl_runtime_c__String__Sequence& names) {
  if (!rosidl_runtime_c__String__Sequence__init(&names, kJoints)) throw RclError("out of memory");
  for (int j = 0; j < kJoints; ++j) {
    if (!rosidl_runtime_c__String__assign(&names.data[j], kJointNames[j])) throw RclError("out of memory");
  }
}

void fill_values(rosidl_runtime_c__double__Sequence& values, const double* from) {
  if (!rosidl_runtime_c__double__Sequence__init(&values, kJoints)) throw RclError("out of memory");
  std::memcpy(values.data, from, sizeof(double) * kJoints);
}

void set_stamp(builtin_interfaces__msg__Time& stamp, int64_t stamp_ns) {
  stamp.sec = static_cast<int32_t>(stamp_ns / kNsPerS);
  stamp.nanosec = static_cast<uint32_t>(stamp_ns % kNsPerS);
}

int64_t stamp_ns(const builtin_interfaces__msg__Time& stamp) {
  return static_cast<int64_t>(stamp.sec) * kNsPerS + stamp.nanosec;
}

void expect_names(const rosidl_runtime_c__String__Sequence& names, const char* what) {
  bool same = names.size == static_cast<size_t>(kJoints);
  for (int j = 0; same && j < kJoints; ++j) same = std::strcmp(names.data[j].data, kJointNames[j]) == 0;
  if (!same) throw ContentError(std::string(what) + ": the joint names are not as sent");
}

void expect_values(const rosidl_runtime_c__double__Sequence& values, const double* sent, const char* what) {
  if (values.size != static_cast<size_t>(kJoints) || std::memcmp(values.data, sent, sizeof(double) * kJoints) != 0) {
    throw ContentError(std::string(what) + " not as sent");
  }
}

// One process's node: its publisher, its subscription and the wait on it.
struct Side {
  InitOptions options;
  Context context{options};
  NodeHandle node;
  Publisher publisher;
  Subscription subscription;
  WaitSet wait_set{context};
  Side(const char* name, const rosidl_message_type_support_t* out_type, const char* out_topic,
       const rosidl_message_type_support_t* in_type, const char* in_topic)
      : node(context, name), publisher(node, out_type, out_topic), subscription(node, in_type, in_topic) {}
};

struct Options {
  std::string role;
  long n = 3000, repeats = 3, warmup = 200;
  double discovery_timeout_s = 15.0, timeout_s = 5.0;
};

// --------------------------------------------------------------------------- pong

int run_pong(const Options&) {
  Side side("bench_rcl_pong", ROSIDL_GET_MSG_TYPE_SUPPORT(bracing_msgs, msg, MotorCommand), kPongTopic,
            ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, JointState), kPingTopic);
  JointState state;
  MotorCommand answer;
  answer.data.mode = bracing_msgs__msg__MotorCommand__VOLTAGE;
  fill_names(answer.data.name);
  fill_values(answer.data.value, kAnswer);
  const pid_t parent = getppid();
  while (!g_stop && getppid() == parent) {  // no orphaned pong
    if (!side.wait_set.wait(side.subscription, 0.2)) continue;
    while (side.subscription.take(&state.data)) {
      expect_names(state.data.name, "joint_states");
      expect_values(state.data.position, kPosition, "joint_states position");
      expect_values(state.data.velocity, kVelocity, "joint_states velocity");
      expect_values(state.data.effort, kEffort, "joint_states effort");
      answer.data.header.stamp = state.data.header.stamp;
      side.publisher.publish(&answer.data);
    }
  }
  return 0;
}

// --------------------------------------------------------------------------- ping

struct Pinger {
  Side side{"bench_rcl_ping", ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, JointState), kPingTopic,
            ROSIDL_GET_MSG_TYPE_SUPPORT(bracing_msgs, msg, MotorCommand), kPongTopic};
  JointState state;
  MotorCommand answer;
  long checked = 0;  // answers received, every field as sent

  Pinger() {
    fill_names(state.data.name);
    fill_values(state.data.position, kPosition);
    fill_values(state.data.velocity, kVelocity);
    fill_values(state.data.effort, kEffort);
  }

  void send(int64_t stamp) {
    set_stamp(state.data.header.stamp, stamp);
    side.publisher.publish(&state.data);
  }

  // Whether the answer stamped ``stamp`` came within ``timeout_s`` (earlier answers are taken too).
  bool wait_for(int64_t stamp, double timeout_s) {
    const double deadline = now_s() + timeout_s;
    for (double left = timeout_s; left > 0.0; left = deadline - now_s()) {
      if (!side.wait_set.wait(side.subscription, left)) continue;
      bool found = false;
      while (side.subscription.take(&answer.data)) {
        if (answer.data.mode != bracing_msgs__msg__MotorCommand__VOLTAGE) throw ContentError("motor_command mode");
        expect_names(answer.data.name, "motor_command");
        expect_values(answer.data.value, kAnswer, "motor_command value");
        ++checked;
        found = found || stamp_ns(answer.data.header.stamp) == stamp;
      }
      if (found) return true;
    }
    return false;
  }

  void discover(double timeout_s) {
    const double deadline = now_s() + timeout_s;
    size_t readers = 0, writers = 0;
    while (true) {
      check(rcl_publisher_get_subscription_count(&side.publisher.handle, &readers), "subscription count");
      check(rcl_subscription_get_publisher_count(&side.subscription.handle, &writers), "publisher count");
      if (readers >= 1 && writers >= 1) return;
      if (now_s() > deadline || g_stop) {
        throw RclError("pong not discovered within " + std::to_string(static_cast<int>(timeout_s)) + " s");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }

  // The first messages after matching may still be in flight, so each is resent until answered.
  void warm_up(long count) {
    for (long i = 0; i < count; ++i) {
      bool answered = false;
      for (int attempt = 0; attempt < 20 && !answered; ++attempt) {
        send(i);
        answered = wait_for(i, 0.25);
      }
      if (!answered) throw RclError("no echo during warm-up");
    }
  }
};

int run_ping(const Options& options) {
  Pinger ping;
  ping.discover(options.discovery_timeout_s);
  ping.warm_up(options.warmup);
  std::vector<double> samples;
  for (long r = 1; r <= options.repeats; ++r) {
    const double start = now_s();
    for (long i = 0; i < options.n; ++i) {
      const int64_t stamp = (r * 1000000 + i) * 1000000;  // dds_bound.py's stamps [ns]
      ping.send(stamp);
      if (!ping.wait_for(stamp, options.timeout_s)) {
        throw RclError("lost echo (repeat " + std::to_string(r) + ", message " + std::to_string(i) + ")");
      }
    }
    samples.push_back(static_cast<double>(options.n) / (now_s() - start));
  }
  std::printf("{\"samples\": [");
  for (size_t k = 0; k < samples.size(); ++k) std::printf("%s%.17g", k ? ", " : "", samples[k]);
  std::printf("], \"round_trips\": %ld, \"checked\": %ld}\n", options.n * options.repeats, ping.checked);
  std::fflush(stdout);
  return 0;
}

// --------------------------------------------------------------------------- arguments

bool parse_number(const std::string& text, double& out) {
  char* end = nullptr;
  out = std::strtod(text.c_str(), &end);
  return !text.empty() && *end == '\0' && out >= 0.0;
}

// "--name=value" options after the role; false (and why, on stderr) if one is not understood.
bool parse(int argc, char** argv, Options& options) {
  if (argc < 2 || (std::strcmp(argv[1], "ping") != 0 && std::strcmp(argv[1], "pong") != 0)) {
    std::fprintf(stderr, "rcl_pingpong: the first argument is the role: ping or pong\n");
    return false;
  }
  options.role = argv[1];
  for (int k = 2; k < argc; ++k) {
    const std::string arg = argv[k];
    const size_t equals = arg.find('=');
    const std::string name = arg.substr(0, equals);
    double value = 0.0;
    if (equals == std::string::npos || !parse_number(arg.substr(equals + 1), value)) {
      std::fprintf(stderr, "rcl_pingpong: %s: expected --name=number (>= 0)\n", arg.c_str());
      return false;
    }
    if (name == "--n") options.n = static_cast<long>(value);
    else if (name == "--repeats") options.repeats = static_cast<long>(value);
    else if (name == "--warmup") options.warmup = static_cast<long>(value);
    else if (name == "--discovery-timeout") options.discovery_timeout_s = value;
    else if (name == "--timeout") options.timeout_s = value;
    else {
      std::fprintf(stderr, "rcl_pingpong: unknown option %s\n", name.c_str());
      return false;
    }
  }
  if (options.n < 1 || options.repeats < 1) {
    std::fprintf(stderr, "rcl_pingpong: --n and --repeats must be at least 1\n");
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  if (!parse(argc, argv, options)) return 2;
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  try {
    return options.role == "pong" ? run_pong(options) : run_ping(options);
  } catch (const ContentError& exc) {
    std::fprintf(stderr, "rcl_pingpong %s: a message not as sent: %s\n", options.role.c_str(), exc.what());
    return 3;
  } catch (const std::exception& exc) {
    std::fprintf(stderr, "rcl_pingpong %s: %s\n", options.role.c_str(), exc.what());
    return 1;
  }
}
