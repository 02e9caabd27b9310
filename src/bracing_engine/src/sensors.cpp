// Sensing and actuation as a real arm has them (sensors.hpp; docs/model.md, Sensing and actuation).
#include "bracing_engine/sensors.hpp"

#include <cmath>
#include <stdexcept>

namespace bracing_engine {

namespace {

// A stream of its own per sensor kind, from the one seed: adding a force sensor leaves the encoders'
// noise as it was.
std::mt19937_64 stream(unsigned long long seed, unsigned long long kind) {
  std::seed_seq sequence{static_cast<unsigned>(seed & 0xffffffffULL), static_cast<unsigned>(seed >> 32),
                         static_cast<unsigned>(kind)};
  return std::mt19937_64(sequence);
}

}  // namespace

Sensors::Sensors(const SensorSpec& spec, int n) : spec_(spec), n_(n) {
  if (spec.encoder_counts_per_rev < 0 || spec.command_latency_steps < 0)
    throw std::invalid_argument("sensors: encoder counts and latency must be >= 0");
  if (!(spec.step > 0.0)) throw std::invalid_argument("sensors: step must be > 0");
  for (double sigma : {spec.position_noise, spec.velocity_noise, spec.velocity_filter_hz, spec.force_noise,
                       spec.current_noise})
    if (!(sigma >= 0.0) || !std::isfinite(sigma)) throw std::invalid_argument("sensors: noise and cutoff must be finite, >= 0");
  if (!std::isfinite(spec.force_bias)) throw std::invalid_argument("sensors: force bias must be finite");
  if (static_cast<int>(spec_.revolute.size()) != n) spec_.revolute.assign(n, true);
  exact_joints_ = spec.encoder_counts_per_rev == 0 && spec.position_noise == 0.0 && spec.velocity_noise == 0.0 &&
                  spec.velocity_filter_hz == 0.0;
  resolution_ = spec.encoder_counts_per_rev ? 2.0 * M_PI / static_cast<double>(spec.encoder_counts_per_rev) : 0.0;
  reset();
}

bool Sensors::exact() const {
  return exact_joints_ && spec_.force_noise == 0.0 && spec_.force_bias == 0.0 && spec_.current_noise == 0.0 &&
         spec_.command_latency_steps == 0;
}

void Sensors::reset() {
  joint_rng_ = stream(spec_.seed, 0);
  force_rng_ = stream(spec_.seed, 1);
  current_rng_ = stream(spec_.seed, 2);
  joint_normal_.reset();
  force_normal_.reset();
  current_normal_.reset();
  started_ = false;
  previous_q_.setZero(n_);
  filtered_dq_.setZero(n_);
  queue_.clear();
  applied_.setZero(n_);
  popped_ = false;
}

double Sensors::quantised(double q, int joint) const {
  if (resolution_ == 0.0 || !spec_.revolute[joint]) return q;
  return std::round(q / resolution_) * resolution_;
}

void Sensors::joints(const Vector& q, const Vector& dq, Vector& q_out, Vector& dq_out) {
  if (q.size() != n_ || dq.size() != n_) throw std::invalid_argument("sensors: one position and velocity per joint");
  if (exact_joints_) {
    q_out = q;
    dq_out = dq;
    return;
  }
  q_out.resize(n_);
  dq_out.resize(n_);
  for (int j = 0; j < n_; ++j) {
    const double noise = spec_.position_noise > 0.0 ? spec_.position_noise * joint_normal_(joint_rng_) : 0.0;
    q_out[j] = quantised(q[j] + noise, j);
  }
  if (spec_.velocity_filter_hz > 0.0) {
    // backward-Euler first-order low-pass of the finite difference, cutoff w = 2 pi f_c
    const double w = 2.0 * M_PI * spec_.velocity_filter_hz, h = spec_.step, a = h * w / (1.0 + h * w);
    if (started_) filtered_dq_ += a * ((q_out - previous_q_) / h - filtered_dq_);
    dq_out = filtered_dq_;
  } else {
    for (int j = 0; j < n_; ++j)
      dq_out[j] = dq[j] + (spec_.velocity_noise > 0.0 ? spec_.velocity_noise * joint_normal_(joint_rng_) : 0.0);
  }
  previous_q_ = q_out;
  started_ = true;
}

Vector3 Sensors::force(const Vector3& force, const Vector3& normal) {
  Vector3 out = force + spec_.force_bias * normal;
  if (spec_.force_noise > 0.0)
    for (int k = 0; k < 3; ++k) out[k] += spec_.force_noise * force_normal_(force_rng_);
  return out;
}

void Sensors::currents(const Vector& current, Vector& out) {
  out = current;
  if (spec_.current_noise > 0.0)
    for (Eigen::Index j = 0; j < out.size(); ++j) out[j] += spec_.current_noise * current_normal_(current_rng_);
}

const Vector& Sensors::delay(const Vector& command) {
  if (spec_.command_latency_steps == 0) {
    applied_ = command;
    return applied_;
  }
  queue_.push_back(command);
  popped_ = static_cast<long>(queue_.size()) > spec_.command_latency_steps;
  if (popped_) {
    applied_ = queue_.front();
    queue_.pop_front();
  } else {
    applied_.setZero(command.size());
  }
  return applied_;
}

void Sensors::take_back() {
  if (spec_.command_latency_steps == 0 || queue_.empty()) return;
  queue_.pop_back();
  if (popped_) queue_.push_front(applied_);
  popped_ = false;
}

}  // namespace bracing_engine
