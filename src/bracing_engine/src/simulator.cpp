// RK4 over the model of dynamics.cpp: the energy integrals, unilateral contacts, Coulomb stick and
// slip, the stops.
//
// Coulomb stick and slip are events located inside a step (docs/model.md, Friction): a step is
// integrated in the modes it starts with; if at its end a sliding contact's slip has reversed, or a
// sticking contact's holding force has left the cone, the crossing time is found on the step's
// cubic Hermite interpolant (Illinois method), the step is redone up to it, the mode switched, and
// the rest of the step integrated the same way. So the switching times carry no error of the step
// size, and results converge with the step as in a smooth phase. The check at the end costs one
// model evaluation per step while a Coulomb contact is held.
#include <algorithm>
#include <cmath>
#include <limits>

#include "bracing_engine/engine.hpp"

namespace bracing_engine {

namespace {

constexpr int kMaxEventsPerStep = 8;  // a stick-slip chatter guard: the rest of the step keeps its modes
constexpr int kMaxIterations = 60;    // Illinois iterations per located event

int sign_of(double value) { return value < 0.0 ? -1 : 1; }

}  // namespace

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
  // Coulomb contacts at rest start sticking; moving ones slide along their slip.
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
  x_.setZero(kStates * n_);
  for (auto& k : k_) k.setZero(kStates * n_);
  for (auto& e : e_) e.setZero(kEnergies);
  k_end_.setZero(kStates * n_);
  e_end_.setZero(kEnergies);
  start_direction_.setZero(p_, 3);
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
}

void Simulator::set_modes(const ContactModes& modes) {
  if (static_cast<int>(modes.held.size()) != p_ || static_cast<int>(modes.sticking.size()) != p_ ||
      modes.slide.rows() != p_ || modes.pushing.size() != p_)
    throw std::invalid_argument("one mode per contact expected");
  modes_ = modes;
}

void Simulator::set_state(const Vector& y) {
  if (y.size() != y_.size()) throw std::invalid_argument("state: wrong size");
  y_ = y;
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
  // consumed |P|, net P (P = v i, or tau dq in torque mode), copper loss R(T) i^2, viscous loss
  // dq^T Dc dq, friction loss, constraint work, impact loss (events only)
  const Drive& d = dynamics_->drive();
  const auto flow = d.voltage ? i : dq;
  e[0] = u.cwiseProduct(flow).cwiseAbs().sum();
  e[1] = u.dot(flow);
  e[2] = d.voltage ? answer.resistance.dot(i.cwiseProduct(i)) : 0.0;
  // the windings heat by the same copper loss the books count, and cool to ambient through R_th
  if (d.voltage && d.thermal)
    k.segment(3 * n, n).array() =
        (answer.resistance.array() * i.array().square() - (T.array() - d.ambient) / d.thermal_resistance.array()) /
        d.heat_capacity.array();
  else
    k.segment(3 * n, n).setZero();
  e[3] = d.damping.dot(dq.cwiseProduct(dq));
  e[4] = answer.friction_power;
  e[5] = answer.constraint_power;
  e[6] = 0.0;
}

void Simulator::evaluate(const Vector& u) {
  evaluate_at(y_, u, true, report);
  report_modes_ = modes_;
}

int Simulator::refusal(double speed_limit, double residual_limit, double& measured) const {
  if (!report.force.allFinite() || !report.friction.allFinite() || !report.slip.allFinite()) return 3;
  const double speed = y_.segment(n_, n_).cwiseAbs().maxCoeff();
  if (speed > speed_limit) {  // finite, but a state no arm reaches: RK4 overflows a few steps on
    measured = speed;
    return 4;
  }
  const double hottest = y_.segment(3 * n_, n_).maxCoeff();
  if (hottest > kWindingTemperatureLimit) {
    measured = hottest;
    return 6;
  }
  measured = 0.0;
  for (int j = 0; j < p_; ++j)
    if (report_modes_.held[j]) measured = std::max(measured, std::abs(report.residual[j]));
  return measured > residual_limit ? 5 : 0;
}

bool Simulator::break_away(double offset) {
  // The sticking contact whose holding force leaves the cone |f_t| <= mu |f_n| the most slides,
  // along where that force was holding it back from: d = -f_t / |f_t|.
  const auto& contacts = dynamics_->contacts();
  int worst = -1;
  double largest = 0.0;
  for (int j = 0; j < p_; ++j) {
    if (!modes_.held[j] || !modes_.sticking[j]) continue;
    const double limit = contacts[j].friction * std::abs(report.force[j]);
    const double excess = report.friction[j] - limit;
    if (excess > 1e-12 * std::max(1.0, limit) && excess > largest) {
      worst = j;
      largest = excess;
    }
  }
  if (worst < 0) return false;
  const Vector3 force = report.tangential_force.row(worst).transpose();
  modes_.sticking[worst] = false;
  modes_.slide.row(worst) = (-force / force.norm()).transpose();
  modes_.pushing[worst] = sign_of(report.force[worst]);
  events_.push_back({steps_taken, offset, worst, EventKind::slip, 0.0});
  return true;
}

void Simulator::start(const Vector& u) {
  for (int guard = 0; guard < 4 * p_ + 4; ++guard) {
    evaluate(u);
    // Unilateral contacts whose force would pull let go, the most negative first.
    int pulling = -1;
    for (int j = 0; j < p_; ++j)
      if (modes_.held[j] && unilateral_[j] && report.force[j] < 0.0 &&
          (pulling < 0 || report.force[j] < report.force[pulling]))
        pulling = j;
    if (pulling >= 0) {
      modes_.held[pulling] = false;
      modes_.sticking[pulling] = false;
      events_.push_back({steps_taken, 0.0, pulling, EventKind::release, 0.0});
      continue;
    }
    // A sliding Coulomb contact's friction follows the sign of its normal force (held over the step).
    bool flipped = false;
    for (int j = 0; j < p_; ++j) {
      if (!coulomb_[j] || !modes_.held[j] || modes_.sticking[j] || report.force[j] == 0.0) continue;
      if (sign_of(report.force[j]) != modes_.pushing[j]) {
        modes_.pushing[j] = sign_of(report.force[j]);
        flipped = true;
      }
    }
    if (flipped) continue;
    if (any_coulomb_ && break_away(0.0)) continue;
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

void Simulator::event_functions(const Answer& answer, Vector& g) const {
  // Per held Coulomb contact: sticking, mu |f_n| - |f_t| (the room left in the cone); sliding, the
  // slip along its direction at the interval's start (it reverses through zero). Others: +inf.
  // Each with the tolerance of its test at a step's start, so rounding at a boundary (a stick held
  // just inside the cone, a slip just starting) is no event.
  const auto& contacts = dynamics_->contacts();
  g.setConstant(p_, std::numeric_limits<double>::infinity());
  for (int j = 0; j < p_; ++j) {
    if (!coulomb_[j] || !modes_.held[j]) continue;
    if (modes_.sticking[j]) {
      const double limit = contacts[j].friction * std::abs(answer.force[j]);
      g[j] = limit - answer.friction[j] + 1e-12 * std::max(1.0, limit);
    } else {
      g[j] = answer.slip.row(j).dot(start_direction_.row(j)) + kSlipAtRest;
    }
  }
}

void Simulator::advance(Vector& y, double h, const Vector& u, bool first, double offset) {
  const int n = n_, m = kStates * n_;
  double done = 0.0;
  end_evaluated_ = false;
  for (int events = 0;; ++events) {
    const double span = h - done;
    y0_ = y;
    if (!first) {
      evaluate_at(y0_, u, false, stage_);
      rates(y0_.head(m), u, true, stage_, k_[0], e_[0]);
    } else {
      rates(y0_.head(m), u, true, report, k_[0], e_[0]);
    }
    const Answer& opening = first ? report : stage_;
    first = false;
    if (!any_coulomb_) {  // no events inside a step
      rk4(y0_, span, u, y);
      return;
    }
    // the sliding contacts' slip directions at the start (their stored direction while at rest), held
    // as the direction their friction keeps past a reversal (see Dynamics::evaluate)
    for (int j = 0; j < p_; ++j) {
      const double speed = opening.slip.row(j).norm();
      if (coulomb_[j] && !modes_.sticking[j] && speed > kSlipAtRest) modes_.slide.row(j) = opening.slip.row(j) / speed;
      start_direction_.row(j) = modes_.slide.row(j);
    }
    event_functions(opening, g_start_);
    k_first_ = k_[0];
    e_first_ = e_[0];
    rk4(y0_, span, u, y1_);
    if (events >= kMaxEventsPerStep) {
      y = y1_;
      return;
    }
    // The event functions at the end (the 4th stage's state is not enough: an event it misses is a
    // reversal taken as slip in the other direction); where one crossed zero, locate it on the cubic
    // Hermite interpolant of the step (q, dq, i, T).
    evaluate_at(y1_, u, false, located_);
    event_functions(located_, g_end_);
    if ((g_end_.array() >= 0.0).all()) {
      y = y1_;
      end_evaluated_ = true;  // located_ is the model at the step's end
      return;
    }
    rates(y1_.head(m), u, true, located_, k_end_, e_end_);
    int contact = -1;
    double when = span;
    for (int j = 0; j < p_; ++j) {
      if (!(g_end_[j] < 0.0)) continue;
      // Illinois on g_j over (0, span]: g_j(0) >= 0 > g_j(span)
      double a = 0.0, b = span, ga = std::max(g_start_[j], 0.0), gb = g_end_[j];
      int side = 0;
      for (int it = 0; it < kMaxIterations && b - a > 1e-14 * std::max(span, 1e-6); ++it) {
        const double c = ga == gb ? 0.5 * (a + b) : b - gb * (b - a) / (gb - ga);
        const double theta = c / span, theta2 = theta * theta, theta3 = theta2 * theta;
        x_ = (2.0 * theta3 - 3.0 * theta2 + 1.0) * y0_.head(m) + ((theta3 - 2.0 * theta2 + theta) * span) * k_first_ +
             (-2.0 * theta3 + 3.0 * theta2) * y1_.head(m) + ((theta3 - theta2) * span) * k_end_;
        evaluate_at(x_, u, false, located_);
        event_functions(located_, g_trial_);
        const double gc = g_trial_[j];
        if (gc < 0.0) {
          b = c;
          gb = gc;
          if (side == -1) ga *= 0.5;
          side = -1;
        } else {
          a = c;
          ga = gc;
          if (side == 1) gb *= 0.5;
          side = 1;
        }
      }
      const double root = b;  // just past the crossing: the switch then holds for what follows
      if (root < when) {
        when = root;
        contact = j;
      }
    }
    if (contact < 0) {  // no root found (cannot happen: g(0) >= 0 > g(end))
      y = y1_;
      return;
    }
    // Redo the step up to the event, and switch there.
    k_[0] = k_first_;
    e_[0] = e_first_;
    rk4(y0_, when, u, y);
    done += when;
    const double at = offset + done;
    if (modes_.sticking[contact]) {
      evaluate_at(y, u, true, located_);
      const Vector3 force = located_.tangential_force.row(contact).transpose();
      modes_.sticking[contact] = false;
      modes_.slide.row(contact) = (-force / force.norm()).transpose();
      modes_.pushing[contact] = sign_of(located_.force[contact]);
      events_.push_back({steps_taken, at, contact, EventKind::slip, 0.0});
    } else {
      modes_.sticking[contact] = true;
      Vector q = y.head(n), dq = y.segment(n, n);
      const double loss = dynamics_->hold_velocity(q, dq, modes_);  // the slip left at the crossing
      y.segment(n, n) = dq;
      y[kStates * n + 4] += loss;  // friction's: the tangential impulse
      events_.push_back({steps_taken, at, contact, EventKind::stick, loss});
      // a stick the forces cannot hold slides on at once, the other way
      evaluate_at(y, u, true, located_);
      const double limit = dynamics_->contacts()[contact].friction * std::abs(located_.force[contact]);
      if (located_.friction[contact] - limit > 1e-12 * std::max(1.0, limit)) {
        const Vector3 force = located_.tangential_force.row(contact).transpose();
        modes_.sticking[contact] = false;
        modes_.slide.row(contact) = (-force / force.norm()).transpose();
        modes_.pushing[contact] = sign_of(located_.force[contact]);
        events_.push_back({steps_taken, at, contact, EventKind::slip, 0.0});
      }
    }
    if (h - done <= 1e-15 * h) return;
  }
}

StepStatus Simulator::step(const Vector& u) {
  const int n = n_;
  if (u.size() != n) throw std::invalid_argument("command: one value per joint expected");
  start(u);  // the modes at the start; `report` is the first stage
  const ContactModes modes = modes_;
  const std::size_t event_count = events_.size();
  const double h = step_ / substeps_;
  Vector& y = y_next_;
  y = y_;
  for (int s = 0; s < substeps_; ++s) advance(y, h, u, s == 0, s * h);
  auto refuse = [&](StepStatus status) {
    modes_ = modes;
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

void Simulator::hold_sticking() {
  // A sticking contact's tangential velocity is held at the acceleration level, so the integration
  // lets it drift (1e-10 m/s in a step seen with two contacts); projected back to zero at each step's
  // end (an impulse, its tiny loss booked as friction's), a stuck contact is at rest to rounding for
  // whoever reads the state, as the law does to tell stick from slip.
  bool any = false, drifted = !end_evaluated_;
  for (int j = 0; j < p_; ++j) {
    if (!modes_.held[j] || !modes_.sticking[j]) continue;
    any = true;
    // the step's end evaluation has the slip already: nothing to project below 1e-13 m/s (a pass saved)
    drifted = drifted || located_.slip.row(j).norm() > 1e-13;
  }
  if (!any || !drifted) return;
  const int n = n_;
  Vector q = y_.head(n), dq = y_.segment(n, n);
  y_[kStates * n + 4] += dynamics_->hold_velocity(q, dq, modes_);
  y_.segment(n, n) = dq;
}

void Simulator::touchdown() {
  // Released contacts that reached their surface while approaching land (inelastic impact).
  const int n = n_;
  Answer terms;
  dynamics_->terms(y_.head(n), y_.segment(n, n), terms);
  const Vector approach = terms.normal_jacobian * y_.segment(n, n);
  std::vector<int> landing, held;
  for (int j = 0; j < p_; ++j) {
    const bool lands = !modes_.held[j] && enforced_[j] && terms.residual[j] <= 0.0 && approach[j] < 0.0;
    if (lands) landing.push_back(j);
    if (lands || modes_.held[j]) held.push_back(j);
  }
  if (landing.empty()) return;
  end_evaluated_ = false;  // the state moves
  Vector q = y_.head(n), dq = y_.segment(n, n);
  const double loss = dynamics_->impact(q, dq, held);
  y_.head(n) = q;
  y_.segment(n, n) = dq;
  y_[kStates * n + 6] += loss;
  dynamics_->terms(q, dq, terms);
  for (int j : landing) {
    modes_.held[j] = true;
    // a Coulomb contact lands sliding along its slip (sticking if at rest: the next step's start checks it)
    const double speed = terms.slip.row(j).norm();
    modes_.sticking[j] = coulomb_[j] && speed <= kSlipAtRest;
    if (coulomb_[j] && speed > kSlipAtRest) {
      modes_.slide.row(j) = terms.slip.row(j) / speed;
      modes_.pushing[j] = 1.0;
    }
    events_.push_back({steps_taken, 0.0, j, EventKind::touchdown, loss});
  }
}

}  // namespace bracing_engine
