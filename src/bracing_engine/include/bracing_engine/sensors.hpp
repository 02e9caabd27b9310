// What a real arm's controller sees and how late its commands land (docs/model.md, Sensing and
// actuation): encoders that quantise and add noise, velocities differentiated from them through a
// first-order filter (or the true velocity with noise), a force sensor per contact with noise and
// bias, current sensors with noise, and a command latency in whole steps. Every part off by default
// (the exact, instant sensing of the paper). Seeded: the same seed gives the same numbers bit for bit.
#pragma once

#include <deque>
#include <random>

#include "bracing_engine/engine.hpp"

namespace bracing_engine {

struct SensorSpec {
  unsigned long long seed = 0;      // sensors.noise_seed
  long encoder_counts_per_rev = 0;  // after the gear, on revolute joints (0: exact positions)
  double position_noise = 0.0;      // sigma [rad or m], before the quantisation
  double velocity_noise = 0.0;      // sigma [rad/s or m/s] on the true velocity (velocity_filter_hz = 0)
  double velocity_filter_hz = 0.0;  // > 0: velocity = first-order low-pass of the measured positions' difference
  double force_noise = 0.0;         // sigma [N] on each force component of a contact's sensor
  double force_bias = 0.0;          // [N] along the contact's normal (a sensor's offset)
  double current_noise = 0.0;       // sigma [A]
  long command_latency_steps = 0;   // a command is applied this many steps after the state it answers
  double step = 0.001;              // [s], the control period (the filter's and the difference's)
  Mask revolute;                    // per joint: the encoder's grid applies (prismatic joints: not quantised)
};

class Sensors {
 public:
  Sensors(const SensorSpec& spec, int n);

  // Whether the joint readings differ from the truth (else joints() copies).
  bool exact_joints() const { return exact_joints_; }
  bool exact() const;  // nothing differs from the truth and no latency
  const SensorSpec& spec() const { return spec_; }

  // The measured (q, dq) of the true (q, dq): called once per state, in order (the velocity filter
  // and the noise streams advance).
  void joints(const Vector& q, const Vector& dq, Vector& q_out, Vector& dq_out);
  // A contact sensor's reading of the true force on the robot `force`, the surface normal `normal`.
  Vector3 force(const Vector3& force, const Vector3& normal);
  // The current sensors' reading of the true currents.
  void currents(const Vector& current, Vector& out);
  // The command to apply now, `command` being the answer to the current state: command_latency_steps
  // answers ago (zero until the first one lands: a drive outputs nothing before its first command).
  const Vector& delay(const Vector& command);
  // Undo the last delay() (its step was refused and is taken back; a new answer comes instead).
  void take_back();
  // Back to the start: the filter, the delay line and the noise streams as constructed.
  void reset();

 private:
  double quantised(double q, int joint) const;

  SensorSpec spec_;
  int n_;
  bool exact_joints_;
  double resolution_;  // [rad] one encoder count
  std::mt19937_64 joint_rng_, force_rng_, current_rng_;  // one stream per sensor kind: independent draws
  std::normal_distribution<double> joint_normal_, force_normal_, current_normal_;
  bool started_ = false;
  Vector previous_q_, filtered_dq_;
  std::deque<Vector> queue_;
  Vector applied_;
  bool popped_ = false;  // the last delay() took applied_ off the queue's front
};

}  // namespace bracing_engine
