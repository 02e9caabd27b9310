// RK4 over the model of dynamics.cpp: the state and its energy integrals, a step from its start (the
// contacts' modes settled) to its end, and the stops (divergence, joint limits, the node's refusals).
// The contact events (release, touchdown, stick, slip) are events.cpp's.
#include <algorithm>
#include <cmath>

#include "bracing_engine/engine.hpp"

namespace bracing_engine {

Simulator::Simulator(std::shared_ptr<const Dynamics> dynamics, double step, int substeps, const Vector& q0,
                     const Vector& dq0, const Vector& lower_limits, const Vector& upper_limits)
    : dynamics_(std::move(dynamics)),
      n_(dynamics_->nv()),
      p_(dynamics_->contact_count()),
      step_(step),
      substeps_(substeps),
      lower_(lower_limits),
      upper_(upper_limits) {
  if (!(std::isfinite(step) && step > 0.0)) throw std::invalid_argument("step: must be > 0 seconds");
  if (substeps < 1) throw std::invalid_argument("substeps: must be an integer >= 1");
  if (q0.size() != n_ || dq0.size() != n_ || lower_.size() != n_ || upper_.size() != n_)
    throw std::invalid_argument("one value per joint expected");
  const int size = kStates * n_ + kEnergies;
  y_.setZero(size);
  y_next_.setZero(size);
  y0_.setZero(size);
  y1_.setZero(size);
  y_.head(n_) = q0;
  y_.segment(n_, n_) = dq0;
  y_.segment(3 * n_, n_).setConstant(dynamics_->drive().ambient);  // the windings start at ambient
  for (const auto& contact : dynamics_->contacts()) {
    unilateral_.push_back(contact.unilateral);
    enforced_.push_back(contact.enforced);
    coulomb_.push_back(contact.coulomb && contact.friction > 0.0);
    any_unilateral_ = any_unilateral_ || contact.unilateral;
    any_coulomb_ = any_coulomb_ || coulomb_.back();
  }
  initial_modes(q0, dq0);
  x_.setZero(kStates * n_);
  for (auto& k : k_) k.setZero(kStates * n_);
  for (auto& e : e_) e.setZero(kEnergies);
  k_end_.setZero(kStates * n_);
  e_end_.setZero(kEnergies);
  start_direction_.setZero(p_, 3);
}

void Simulator::initial_modes(const Vector& q0, const Vector& dq0) {
  modes_.held.assign(p_, true);
  modes_.sticking.assign(p_, false);
  modes_.slide.setZero(p_, 3);
  modes_.pushing.setOnes(p_);
  if (any_coulomb_) {
    Answer terms;
    dynamics_->terms(q0, dq0, terms);
    for (int j = 0; j < p_; ++j) {
      if (!coulomb_[j]) continue;
      const double speed = terms.slip.row(j).norm();
      modes_.sticking[j] = speed <= kSlipAtRest;
      if (speed > kSlipAtRest) modes_.slide.row(j) = terms.slip.row(j) / speed;
    }
  }
  report_modes_ = modes_;
}

bool Simulator::all_active() const {
  for (bool a : modes_.held)
    if (!a) return false;
  return true;
}

void Simulator::set_active(const Mask& active) {
  if (static_cast<int>(active.size()) != p_) throw std::invalid_argument("one flag per contact expected");
  for (int j = 0; j < p_; ++j) {
    if (!active[j]) modes_.sticking[j] = false;
    if (active[j] && !modes_.held[j] && coulomb_[j]) modes_.sticking[j] = true;  // the start check decides
  }
  modes_.held = active;
  end_evaluated_ = false;
}

void Simulator::set_modes(const ContactModes& modes) {
  end_evaluated_ = false;
  if (static_cast<int>(modes.held.size()) != p_ || static_cast<int>(modes.sticking.size()) != p_ ||
      modes.slide.rows() != p_ || modes.pushing.size() != p_)
    throw std::invalid_argument("one mode per contact expected");
  modes_ = modes;
}

void Simulator::set_state(const Vector& y) {
  if (y.size() != y_.size()) throw std::invalid_argument("state: wrong size");
  y_ = y;
  end_evaluated_ = false;
}

void Simulator::truncate_events(std::size_t count) {
  if (count < events_.size()) events_.resize(count);
}

void Simulator::evaluate_at(const Eigen::Ref<const Vector>& x, const Vector& u, bool full, Answer& out) const {
  const int n = n_;
  dynamics_->evaluate(x.head(n), x.segment(n, n), x.segment(2 * n, n), x.segment(3 * n, n), u, modes_, full, out);
}

void Simulator::rates(const Eigen::Ref<const Vector>& x, const Vector& u, bool evaluated, Answer& answer, Vector& k,
                      Vector& e) const {
  const int n = n_;
  const auto dq = x.segment(n, n), i = x.segment(2 * n, n), T = x.segment(3 * n, n);
  if (!evaluated) evaluate_at(x, u, false, answer);
  k.head(n) = dq;
  k.segment(n, n) = answer.ddq;
  k.segment(2 * n, n) = answer.di;
  const Drive& d = dynamics_->drive();
  const auto flow = d.voltage ? i : dq;  // P = v i, or tau dq in torque mode
  e[energy::consumed] = u.cwiseProduct(flow).cwiseAbs().sum();
  e[energy::net] = u.dot(flow);
  e[energy::copper_loss] = d.voltage ? answer.resistance.dot(i.cwiseProduct(i)) : 0.0;
  // the windings heat by the same copper loss the books count, and cool to ambient through R_th
  if (d.voltage && d.thermal)
    k.segment(3 * n, n).array() =
        (answer.resistance.array() * i.array().square() - (T.array() - d.ambient) / d.thermal_resistance.array()) /
        d.heat_capacity.array();
  else
    k.segment(3 * n, n).setZero();
  e[energy::viscous_loss] = d.damping.dot(dq.cwiseProduct(dq));
  e[energy::friction_loss] = answer.friction_power;
  e[energy::constraint_work] = answer.constraint_power;
  e[energy::impact_loss] = 0.0;  // events only
}

void Simulator::evaluate(const Vector& u) {
  evaluate_at(y_, u, true, report);
  report_modes_ = modes_;
}

Refusal Simulator::refusal(double speed_limit, double residual_limit, double& measured) const {
  if (!report.force.allFinite() || !report.friction.allFinite() || !report.slip.allFinite()) return Refusal::non_finite;
  const double speed = y_.segment(n_, n_).cwiseAbs().maxCoeff();
  if (speed > speed_limit) {  // finite, but a state no arm reaches: RK4 overflows a few steps on
    measured = speed;
    return Refusal::too_fast;
  }
  const double hottest = y_.segment(3 * n_, n_).maxCoeff();
  if (hottest > kWindingTemperatureLimit) {
    measured = hottest;
    return Refusal::too_hot;
  }
  measured = 0.0;
  for (int j = 0; j < p_; ++j)
    if (report_modes_.held[j]) measured = std::max(measured, std::abs(report.residual[j]));
  return measured > residual_limit ? Refusal::off_surface : Refusal::none;
}

bool Simulator::end_reusable() const {
  return end_evaluated_ && dynamics_->drive().voltage && end_baumgarte_ == dynamics_->baumgarte;
}

void Simulator::start(const Vector& u) {
  for (int guard = 0; guard < 4 * p_ + 4; ++guard) {
    // one model evaluation of five a step saved (make bench's engine: 71k -> 88k steps/s)
    if (guard == 0 && end_reusable()) {
      const int n = n_;
      std::swap(report, located_);
      dynamics_->rerun_circuit(y_.segment(n, n), y_.segment(2 * n, n), y_.segment(3 * n, n), u, report);
      report_modes_ = modes_;
    } else {
      evaluate(u);
    }
    end_evaluated_ = false;  // located_ is scratch again
    if (release_pulling() || follow_force_signs() || (any_coulomb_ && break_away(0.0))) continue;
    return;
  }
}

void Simulator::rk4(const Vector& y0, double h, const Vector& u, Vector& y1) {
  // stage 1 (k_[0], e_[0]) is the caller's
  const int m = kStates * n_;
  const double c[3] = {0.5 * h, 0.5 * h, h};
  const double w[4] = {h / 6.0, 2.0 * h / 6.0, 2.0 * h / 6.0, h / 6.0};
  const auto start = y0.head(m);
  for (int stage = 1; stage < 4; ++stage) {
    x_ = c[stage - 1] * k_[stage - 1] + start;
    rates(x_, u, false, stage_, k_[stage], e_[stage]);
  }
  y1 = y0;
  y1.head(m).noalias() += w[0] * k_[0] + w[1] * k_[1] + w[2] * k_[2] + w[3] * k_[3];
  y1.tail(kEnergies).noalias() += w[0] * e_[0] + w[1] * e_[1] + w[2] * e_[2] + w[3] * e_[3];
}

void Simulator::hold_current(const Vector& u) {
  const Drive& drive = dynamics_->drive();
  if (!drive.voltage) return;  // torque input: no circuit
  const int n = n_;
  Vector resistance;
  drive.resistance_at(y_.segment(3 * n, n), resistance);
  y_.segment(2 * n, n) =
      (u - drive.torque_constant.cwiseProduct(y_.segment(n, n))).cwiseQuotient(resistance);
}

StepStatus Simulator::step(const Vector& u) {
  const int n = n_;
  if (u.size() != n) throw std::invalid_argument("command: one value per joint expected");
  if (steady_start && steps_taken == 0) hold_current(u);
  start(u);  // the modes at the start; `report` is the first stage
  start_modes_ = modes_;
  const std::size_t event_count = events_.size();
  const double h = step_ / substeps_;
  Vector& y = y_next_;
  y = y_;
  for (int s = 0; s < substeps_; ++s) advance(y, h, u, s == 0, s * h);
  auto refuse = [&](StepStatus status) {
    end_evaluated_ = false;  // the state stays: located_ is the refused step's end
    modes_ = start_modes_;
    events_.resize(event_count);
    return status;
  };
  if (!y.allFinite()) return refuse(StepStatus::diverged);
  for (int j = 0; j < n; ++j)
    if (!(lower_[j] <= y[j] && y[j] <= upper_[j])) {
      failed_joint = j;
      failed_position = y[j];
      return refuse(StepStatus::joint_limit);
    }
  y_.swap(y_next_);
  ++steps_taken;
  if (any_unilateral_ && !all_active()) touchdown();
  if (any_coulomb_) hold_sticking();
  return StepStatus::ok;
}

}  // namespace bracing_engine
