// The contact events of a step (docs/model.md, Friction and Unilateral contacts): unilateral
// contacts release at a step's start and land at its end; Coulomb stick and slip are located inside it.
//
// A step is integrated in the modes it starts with; if at its end a sliding contact's slip has
// reversed, or a sticking contact's holding force has left the cone, the crossing time is found on the
// step's cubic Hermite interpolant (Illinois method), the step is redone up to it, the mode switched,
// and the rest of the step integrated the same way. So the switching times carry no error of the step
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
// [m/s] A held contact at its link's shapes approaching its surface faster than this has moved onto another part
// of the shapes (the point of a smooth shape rolling on the surface moves with ~0 normal speed).
constexpr double kShiftSpeed = 1e-6;

int sign_of(double value) { return value < 0.0 ? -1 : 1; }

}  // namespace

bool Simulator::release_pulling() {
  int pulling = -1;
  for (int j = 0; j < p_; ++j)
    if (modes_.held[j] && unilateral_[j] && report.force[j] < 0.0 &&
        (pulling < 0 || report.force[j] < report.force[pulling]))
      pulling = j;
  if (pulling < 0) return false;
  modes_.held[pulling] = false;
  modes_.sticking[pulling] = false;
  events_.push_back({steps_taken, 0.0, pulling, EventKind::release, 0.0});
  return true;
}

bool Simulator::follow_force_signs() {
  bool flipped = false;
  for (int j = 0; j < p_; ++j) {
    if (!coulomb_[j] || !modes_.held[j] || modes_.sticking[j] || report.force[j] == 0.0) continue;
    if (sign_of(report.force[j]) != modes_.pushing[j]) {
      modes_.pushing[j] = sign_of(report.force[j]);
      flipped = true;
    }
  }
  return flipped;
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
  end_evaluated_ = false;  // the state moves
  Vector q = y_.head(n), dq = y_.segment(n, n);
  y_[energy_index(energy::friction_loss)] += dynamics_->hold_velocity(q, dq, modes_);
  y_.segment(n, n) = dq;
}

void Simulator::touchdown() {
  const int n = n_;
  Answer terms;
  dynamics_->terms(y_.head(n), y_.segment(n, n), terms);
  const Vector approach = terms.normal_jacobian * y_.segment(n, n);
  const auto& contacts = dynamics_->contacts();
  std::vector<int> landing, held;
  bool shifted = false;
  for (int j = 0; j < p_; ++j) {
    const bool lands = !modes_.held[j] && enforced_[j] && terms.residual[j] <= 0.0 && approach[j] < 0.0;
    // A held contact at its link's shapes whose nearest point moved to another part of them (a link lying down
    // along the surface: the point jumps from one end to the other) meets the surface there with that part's
    // approach speed: it lands again (the held rows only keep the normal acceleration).
    shifted = shifted || (modes_.held[j] && contacts[j].geometry && unilateral_[j] && approach[j] < -kShiftSpeed);
    if (lands) landing.push_back(j);
    if (lands || modes_.held[j]) held.push_back(j);
  }
  if (landing.empty() && !shifted) return;
  end_evaluated_ = false;  // the state moves
  Vector q = y_.head(n), dq = y_.segment(n, n);
  const double loss = dynamics_->impact(q, dq, held);
  y_.head(n) = q;
  y_.segment(n, n) = dq;
  y_[energy_index(energy::impact_loss)] += loss;
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

double Simulator::cone_excess(const Answer& answer, int j) const {
  const double limit = dynamics_->contacts()[j].friction * std::abs(answer.force[j]);
  const double excess = answer.friction[j] - limit;
  return excess > 1e-12 * std::max(1.0, limit) ? excess : 0.0;
}

void Simulator::start_sliding(int j, const Answer& answer, double offset) {
  const Vector3 force = answer.tangential_force.row(j).transpose();
  modes_.sticking[j] = false;
  modes_.slide.row(j) = (-force / force.norm()).transpose();
  modes_.pushing[j] = sign_of(answer.force[j]);
  events_.push_back({steps_taken, offset, j, EventKind::slip, 0.0});
}

bool Simulator::break_away(double offset) {
  // The sticking contact whose holding force leaves the cone |f_t| <= mu |f_n| the most slides.
  int worst = -1;
  double largest = 0.0;
  for (int j = 0; j < p_; ++j) {
    if (!modes_.held[j] || !modes_.sticking[j]) continue;
    const double excess = cone_excess(report, j);
    if (excess > largest) {
      worst = j;
      largest = excess;
    }
  }
  if (worst < 0) return false;
  start_sliding(worst, report, offset);
  return true;
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

const Answer& Simulator::open_interval(const Vector& y, const Vector& u, bool first) {
  const int m = kStates * n_;
  y0_ = y;
  if (first) {
    rates(y0_.head(m), u, true, report, k_[0], e_[0]);
    return report;
  }
  evaluate_at(y0_, u, false, stage_);
  rates(y0_.head(m), u, true, stage_, k_[0], e_[0]);
  return stage_;
}

void Simulator::hold_slide_directions(const Answer& opening) {
  // held as the direction their friction keeps past a reversal (see Dynamics::evaluate)
  for (int j = 0; j < p_; ++j) {
    const double speed = opening.slip.row(j).norm();
    if (coulomb_[j] && !modes_.sticking[j] && speed > kSlipAtRest) modes_.slide.row(j) = opening.slip.row(j) / speed;
    start_direction_.row(j) = modes_.slide.row(j);
  }
}

double Simulator::locate(int j, double span, const Vector& u) {
  // Illinois on g_j over (0, span]: g_j(0) >= 0 > g_j(span)
  const int m = kStates * n_;
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
  return b;  // just past the crossing: the switch then holds for what follows
}

int Simulator::first_event(double span, const Vector& u, double& when) {
  int contact = -1;
  when = span;
  for (int j = 0; j < p_; ++j) {
    if (!(g_end_[j] < 0.0)) continue;
    const double root = locate(j, span, u);
    if (root < when) {
      when = root;
      contact = j;
    }
  }
  return contact;
}

void Simulator::switch_mode(int j, Vector& y, const Vector& u, double at) {
  const int n = n_;
  if (modes_.sticking[j]) {
    evaluate_at(y, u, true, located_);
    start_sliding(j, located_, at);
    return;
  }
  modes_.sticking[j] = true;
  Vector q = y.head(n), dq = y.segment(n, n);
  const double loss = dynamics_->hold_velocity(q, dq, modes_);  // the slip left at the crossing
  y.segment(n, n) = dq;
  y[energy_index(energy::friction_loss)] += loss;  // friction's: the tangential impulse
  events_.push_back({steps_taken, at, j, EventKind::stick, loss});
  // a stick the forces cannot hold slides on at once, the other way
  evaluate_at(y, u, true, located_);
  if (cone_excess(located_, j) > 0.0) start_sliding(j, located_, at);
}

void Simulator::advance(Vector& y, double h, const Vector& u, bool first, double offset) {
  const int m = kStates * n_;
  double done = 0.0;
  end_evaluated_ = false;
  for (int events = 0;; ++events) {
    const double span = h - done;
    const Answer& opening = open_interval(y, u, first);
    first = false;
    if (!any_coulomb_) {  // no events inside a step
      rk4(y0_, span, u, y);
      return;
    }
    hold_slide_directions(opening);
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
    // `full` (every contact's terms) where located_ can be the next step's `report` (end_reusable: voltage input)
    evaluate_at(y1_, u, dynamics_->drive().voltage, located_);
    event_functions(located_, g_end_);
    if ((g_end_.array() >= 0.0).all()) {
      y = y1_;
      end_evaluated_ = true;  // located_ is the model at the step's end
      end_baumgarte_ = dynamics_->baumgarte;
      return;
    }
    rates(y1_.head(m), u, true, located_, k_end_, e_end_);
    double when;
    const int contact = first_event(span, u, when);
    if (contact < 0) {  // no root found (cannot happen: g(0) >= 0 > g(end))
      y = y1_;
      return;
    }
    // Redo the step up to the event, and switch there.
    k_[0] = k_first_;
    e_[0] = e_first_;
    rk4(y0_, when, u, y);
    done += when;
    switch_mode(contact, y, u, offset + done);
    if (h - done <= 1e-15 * h) return;
  }
}

}  // namespace bracing_engine
