// RK4 over the model of dynamics.cpp, with the energy integrals, unilateral contacts and the stops.
#include <cmath>
#include <limits>

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
  y_.setZero(3 * n_ + kEnergies);
  y_next_.setZero(3 * n_ + kEnergies);
  y_.head(n_) = q0;
  y_.segment(n_, n_) = dq0;
  active_.assign(p_, true);
  report_active_ = active_;
  for (const auto& contact : dynamics_->contacts()) {
    unilateral_.push_back(contact.unilateral);
    enforced_.push_back(contact.enforced);
    any_unilateral_ = any_unilateral_ || contact.unilateral;
  }
  x_.setZero(3 * n_);
  for (auto& k : k_) k.setZero(3 * n_);
  for (auto& e : e_) e.setZero(kEnergies);
}

bool Simulator::all_active() const {
  for (bool a : active_)
    if (!a) return false;
  return true;
}

void Simulator::set_active(const Mask& active) {
  if (static_cast<int>(active.size()) != p_) throw std::invalid_argument("one flag per contact expected");
  active_ = active;
}

void Simulator::set_state(const Vector& y) {
  if (y.size() != y_.size()) throw std::invalid_argument("state: wrong size");
  y_ = y;
}

void Simulator::truncate_events(std::size_t count) {
  if (count < events_.size()) events_.resize(count);
}

void Simulator::rates(const Eigen::Ref<const Vector>& x, const Vector& u, bool evaluated, Answer& answer, Vector& k,
                      Vector& e) const {
  const int n = n_;
  const auto q = x.head(n), dq = x.segment(n, n), i = x.segment(2 * n, n);
  if (!evaluated) dynamics_->evaluate(q, dq, i, u, active_, false, answer);
  k.head(n) = dq;
  k.segment(n, n) = answer.ddq;
  k.segment(2 * n, n) = answer.di;
  // consumed |P|, net P (P = v i, or tau dq in torque mode), copper loss R i^2, viscous loss
  // dq^T Dc dq, friction loss, constraint work, impact loss (events only)
  const Drive& d = dynamics_->drive();
  const auto flow = d.voltage ? i : dq;
  e[0] = u.cwiseProduct(flow).cwiseAbs().sum();
  e[1] = u.dot(flow);
  e[2] = d.voltage ? d.resistance.dot(i.cwiseProduct(i)) : 0.0;
  e[3] = d.damping.dot(dq.cwiseProduct(dq));
  e[4] = answer.friction_power;
  e[5] = answer.constraint_power;
  e[6] = 0.0;
}

void Simulator::evaluate(const Vector& u) {
  const int n = n_;
  dynamics_->evaluate(y_.head(n), y_.segment(n, n), y_.segment(2 * n, n), u, active_, true, report);
  report_active_ = active_;
}

void Simulator::release(const Vector& u) {
  // Unilateral contacts whose force would pull let go, the most negative first, until every held force pushes.
  for (;;) {
    evaluate(u);
    int pulling = -1;
    for (int j = 0; j < p_; ++j)
      if (active_[j] && unilateral_[j] && report.force[j] < 0.0 && (pulling < 0 || report.force[j] < report.force[pulling]))
        pulling = j;
    if (pulling < 0) return;
    active_[pulling] = false;
    events_.push_back({steps_taken, pulling, false, 0.0});
  }
}

StepStatus Simulator::step(const Vector& u) {
  const int n = n_, m = 3 * n_;
  if (u.size() != n) throw std::invalid_argument("command: one value per joint expected");
  // The model at the start: released contacts first (this answer is the first stage).
  if (any_unilateral_)
    release(u);
  else
    evaluate(u);
  const double h = step_ / substeps_;
  const double c[3] = {0.5 * h, 0.5 * h, h};
  const double w[4] = {h / 6.0, 2.0 * h / 6.0, 2.0 * h / 6.0, h / 6.0};
  Vector& y = y_next_;
  y = y_;
  for (int s = 0; s < substeps_; ++s) {
    const auto start = y.head(m);
    if (s == 0)
      rates(start, u, true, report, k_[0], e_[0]);  // the report is the first stage
    else
      rates(start, u, false, stage_, k_[0], e_[0]);
    for (int stage = 1; stage < 4; ++stage) {
      x_ = c[stage - 1] * k_[stage - 1] + start;
      rates(x_, u, false, stage_, k_[stage], e_[stage]);
    }
    y.head(m).noalias() += w[0] * k_[0] + w[1] * k_[1] + w[2] * k_[2] + w[3] * k_[3];
    y.tail(kEnergies) += w[0] * e_[0] + w[1] * e_[1] + w[2] * e_[2] + w[3] * e_[3];
  }
  if (!y.allFinite()) return StepStatus::diverged;
  for (int j = 0; j < n; ++j)
    if (!(lower_[j] <= y[j] && y[j] <= upper_[j])) {
      failed_joint = j;
      failed_position = y[j];
      return StepStatus::joint_limit;
    }
  y_.swap(y_next_);
  ++steps_taken;
  if (any_unilateral_ && !all_active()) touchdown();
  return StepStatus::ok;
}

void Simulator::touchdown() {
  // Released contacts that reached their surface while approaching land (inelastic impact).
  const int n = n_;
  Answer terms;
  dynamics_->terms(y_.head(n), y_.segment(n, n), terms);
  const Vector approach = terms.normal_jacobian * y_.segment(n, n);
  std::vector<int> landing, held;
  for (int j = 0; j < p_; ++j) {
    const bool lands = !active_[j] && enforced_[j] && terms.residual[j] <= 0.0 && approach[j] < 0.0;
    if (lands) landing.push_back(j);
    if (lands || active_[j]) held.push_back(j);
  }
  if (landing.empty()) return;
  Vector q = y_.head(n), dq = y_.segment(n, n);
  const double loss = dynamics_->impact(q, dq, held);
  y_.head(n) = q;
  y_.segment(n, n) = dq;
  y_[3 * n + 6] += loss;
  for (int j : landing) {
    active_[j] = true;
    events_.push_back({steps_taken, j, true, loss});
  }
}

}  // namespace bracing_engine
