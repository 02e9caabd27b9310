// The braces' part of the law (docs/model.md, Control law and Control law under stick): the contacts' rows
// J_c, W, gamma and f_cmd, and tau = B^+ (a - A f_nd) + (I - B^+ B) l, or its point-constraint form.
#include "law_impl.hpp"

#include <pinocchio/algorithm/frames.hpp>

#include <Eigen/Dense>
#include <Eigen/SVD>

#include <cmath>

namespace bracing_engine {

// Smallest singular value of B (relative to its largest) below which B^+ is damped.
constexpr double kSingularRatio = 1e-8;

namespace {

// B^+ = B^T (B B^T)^-1, damped (B^T (B B^T + lambda I)^-1, `damped` set) when B's smallest singular
// value is below kSingularRatio of its largest.
Eigen::MatrixXd pseudo_inverse(const Eigen::MatrixXd& b, double damping_lambda, bool& damped) {
  const Eigen::Index p = b.rows();
  const Eigen::MatrixXd gram = b * b.transpose();
  double largest, smallest;
  if (p == 1) {
    largest = smallest = std::sqrt(gram(0, 0));
  } else {
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(b);
    largest = svd.singularValues()[0];
    smallest = svd.singularValues()[p - 1];
  }
  if (smallest > kSingularRatio * std::max(largest, 1e-300)) return gram.partialPivLu().solve(b).transpose();
  damped = true;
  const double lambda = damping_lambda * std::max(largest * largest, 1.0);
  return (gram + lambda * Eigen::MatrixXd::Identity(p, p)).partialPivLu().solve(b).transpose();
}

// A sticking brace's point constraint: the normal rows of every brace (R = W as BraceRows has them),
// then each sticking brace's tangential rows t^T J (W = R), with their gamma.
struct StickRows {
  Eigen::MatrixXd r, wr;
  Vector gamma;
  std::vector<Vector3> tangents;
  std::vector<int> owner;  // the brace of each tangential row
};

StickRows stick_rows(const BraceRows& braces, const Eigen::MatrixXd& brace_jacobians) {
  const Eigen::Index p = braces.jc.rows(), n = braces.jc.cols();
  StickRows s;
  for (int j : braces.sticking) {
    Vector3 t[2];
    const int count = Dynamics::tangent_directions(braces.normals[j], brace_jacobians.middleRows<3>(3 * j), t);
    for (int k = 0; k < count; ++k) {
      s.tangents.push_back(t[k]);
      s.owner.push_back(j);
    }
  }
  const Eigen::Index rows = p + static_cast<Eigen::Index>(s.tangents.size());
  s.r.resize(rows, n);
  s.wr.resize(rows, n);
  s.gamma.resize(rows);
  s.r.topRows(p) = braces.jc;
  s.wr.topRows(p) = braces.w;
  s.gamma.head(p) = braces.gamma;
  for (std::size_t k = 0; k < s.tangents.size(); ++k) {
    const Eigen::Index i = p + static_cast<Eigen::Index>(k);
    s.r.row(i).noalias() = s.tangents[k].transpose() * brace_jacobians.middleRows<3>(3 * s.owner[k]);
    s.wr.row(i) = s.r.row(i);
    s.gamma[i] = s.tangents[k].dot(braces.accelerations[s.owner[k]]);
  }
  return s;
}

// The change of the tangential forces `lambda` (rows after the p normal ones) that brings each sticking
// brace whose |f_t| leaves the cone |f_t| <= mu |f_nd| back onto its surface, just inside (the simulator
// then holds the stick, as modelled); false if every one is inside.
bool cone_correction(const StickRows& s, const BraceRows& braces, const LawSpec& spec, const Vector& lambda,
                     Eigen::Index p, Vector& change) {
  change = Vector::Zero(lambda.size());
  bool outside = false;
  for (int j : braces.sticking) {
    Vector3 force = Vector3::Zero();
    for (std::size_t k = 0; k < s.tangents.size(); ++k)
      if (s.owner[k] == j) force += lambda[p + static_cast<int>(k)] * s.tangents[k];
    const double limit = (1.0 - 1e-9) * spec.braces[j].contact.friction * std::abs(braces.f_nd[j]);
    if (force.norm() <= limit) continue;
    outside = true;
    const double scale = limit / force.norm() - 1.0;
    for (std::size_t k = 0; k < s.tangents.size(); ++k)
      if (s.owner[k] == j) change[p + static_cast<int>(k)] = scale * lambda[p + static_cast<int>(k)];
  }
  return outside;
}

}  // namespace

BraceRows Law::Impl::brace_rows(const Eigen::MatrixXd& brace_jacobians, const Vector& dq, double dt, LawOutput& out) {
  const int n = model.nv, p = static_cast<int>(spec.braces.size());
  BraceRows rows{Eigen::MatrixXd(p, n), Eigen::MatrixXd(p, n), Vector(p), Vector(p), std::vector<Vector3>(p),
                 std::vector<Vector3>(p), {}};
  for (int j = 0; j < p; ++j) {
    const Contact& contact = spec.braces[j].contact;
    const auto jacobian = brace_jacobians.middleRows<3>(3 * j);
    const Vector3 position = out.brace_actual.row(j).transpose();
    rows.accelerations[j] =
        pin::getFrameClassicalAcceleration(model, data, frames[j + 1], pin::LOCAL_WORLD_ALIGNED).linear();
    if (wheels) rows.accelerations[j] += base_drifts[j + 1];
    const Vector3 velocity = jacobian * dq;
    const ContactPoint point = contact_point(contact.surface, position, velocity, rows.accelerations[j]);
    rows.normals[j] = point.normal;
    rows.gamma[j] = point.drift;
    const double speed = point.slip.norm();
    rows.f_nd[j] = out.force_command[j] = force_command(j, point.normal, dt);
    rows.jc.row(j).noalias() = point.normal.transpose() * jacobian;
    rows.w.row(j) = rows.jc.row(j);
    if (contact.friction == 0.0) continue;
    if (!contact.coulomb) {
      const Vector3 direction = point.slip / std::sqrt(speed * speed + spec.slip_epsilon * spec.slip_epsilon);
      subtract_friction(rows.w.row(j), contact.friction, direction, jacobian);  // J_c - mu J_t
    } else if (speed > kSlipAtRest) {  // sliding: |f_t| = mu |f_nd| against the slip d
      const Vector3 e = (rows.f_nd[j] < 0.0 ? -1.0 : 1.0) * point.slip / speed;
      subtract_friction(rows.w.row(j), contact.friction, e, jacobian);
    } else {
      rows.sticking.push_back(j);
    }
  }
  return rows;
}

Vector Law::Impl::sliding_torque(const BraceRows& rows, const Vector& bias, const Vector& l, bool& damped,
                                 ArmResponse* response) {
  const int n = model.nv, p = static_cast<int>(rows.jc.rows());
  Eigen::MatrixXd b(p, n);  // B = J_c Mc^-1 (Mc symmetric)
  inverse_rows(rows.jc, b);
  const Eigen::MatrixXd a_matrix = b * rows.w.transpose();
  const Vector a_vector = b * bias - rows.gamma;
  const Eigen::MatrixXd b_pinv =
      spec.dynamically_consistent
          ? Eigen::MatrixXd((b * rows.jc.transpose()).partialPivLu().solve(rows.jc).transpose())
          : pseudo_inverse(b, spec.damping_lambda, damped);
  // tau = B^+ (a - A f_nd) + (I - B^+ B) l = l + B^+ ((a - A f_nd) - B l)
  Vector torque = l + b_pinv * (a_vector - a_matrix * rows.f_nd - b * l);
  if (response) {  // f_n = f_cmd: Mc ddq = tau - bias + W^T f_cmd; B (I - B^+ B) = 0, so l leaves f_n alone
    response->acceleration = mass_solve(torque - bias + rows.w.transpose() * rows.f_nd);
    response->mobility = mass_inverse() * (Eigen::MatrixXd::Identity(n, n) - b_pinv * b);
  }
  return torque;
}

Vector Law::Impl::sticking_torque(const BraceRows& rows, const Eigen::MatrixXd& brace_jacobians, const Vector& bias,
                                  const Vector& l, bool& damped, ArmResponse* response) {
  // A sticking contact is a point constraint (its normal and tangential rows R, forces through
  // W): lambda = G^-1 (R Mc^-1 (h + g + Dc dq - tau) - gamma_R), G = R Mc^-1 W^T. The law asks
  // only the normal forces S lambda to be f_nd: C tau = e with C = S G^-1 R Mc^-1 and
  // e = S G^-1 (R Mc^-1 (h + g + Dc dq) - gamma_R) - f_nd; the null space of C leaves the
  // tangential forces free (docs/model.md, Control law under stick).
  const Eigen::Index p = rows.jc.rows();
  const StickRows s = stick_rows(rows, brace_jacobians);
  Eigen::MatrixXd y(model.nv, s.r.rows());  // Mc^-1 R^T
  inverse_rows(s.r, y.transpose());
  const Eigen::MatrixXd g = y.transpose() * s.wr.transpose();  // R Mc^-1 W^T
  // (least-norm where the rows are dependent, as the simulator solves them)
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> g_lu(g);
  const Eigen::MatrixXd g_inv_rows = g_lu.solve(y.transpose());  // G^-1 R Mc^-1 (d lambda = -this d tau)
  const Eigen::MatrixXd c_matrix = g_inv_rows.topRows(p);        // C = S G^-1 R Mc^-1
  const Vector e = g_inv_rows.topRows(p) * bias - g_lu.solve(s.gamma).head(p) - rows.f_nd;
  Eigen::MatrixXd c_pinv;
  if (spec.dynamically_consistent) {  // C^# = K^T (K Mc^-1 K^T)^-1 with K = S G^-1 R (C = K Mc^-1)
    const Eigen::MatrixXd k_rows = g_lu.solve(s.r).topRows(p);
    c_pinv = (c_matrix * k_rows.transpose()).partialPivLu().solve(k_rows).transpose();
  } else {
    c_pinv = pseudo_inverse(c_matrix, spec.damping_lambda, damped);
  }
  // tau for l: l + C^+ (e - C l); where a sticking contact's tangential force would leave the cone, the
  // least torque in the null space of C (f_n stays f_nd) brings it back onto it.
  auto torque_for = [&](const Vector& task_input) {
    Vector torque = task_input + c_pinv * (e - c_matrix * task_input);
    const Vector lambda = g_lu.solve(y.transpose() * (bias - torque) - s.gamma);
    Vector change;
    if (cone_correction(s, rows, spec, lambda, p, change))  // -G^-1 R Mc^-1 d tau = change (its normal part zero)
      torque -= g_inv_rows.completeOrthogonalDecomposition().solve(change);
    return torque;
  };
  const Vector torque = torque_for(l);
  if (response) {  // ddq = Mc^-1 (tau - bias + W^T lambda), lambda = G^-1 (R Mc^-1 (bias - tau) - gamma_R): the held rows
    const Vector lambda = g_lu.solve(y.transpose() * (bias - torque) - s.gamma);
    response->acceleration = mass_solve(torque - bias + s.wr.transpose() * lambda);
    const int n = model.nv;
    Eigen::MatrixXd w_inverse(s.wr.rows(), n);  // W Mc^-1
    inverse_rows(s.wr, w_inverse);
    // d tau / d l: (I - C^+ C) and the cone's correction (piecewise affine in l: a difference is exact in its piece)
    Eigen::MatrixXd torque_rate(n, n);
    const double h = 1e-6 * std::max(1.0, l.cwiseAbs().maxCoeff());
    for (int i = 0; i < n; ++i) {
      Vector nudged = l;
      nudged[i] += h;
      torque_rate.col(i) = (torque_for(nudged) - torque) / h;
    }
    response->mobility = (mass_inverse() - w_inverse.transpose() * g_inv_rows) * torque_rate;
  }
  return torque;
}

Vector Law::Impl::contact_torque(const BraceRows* rows, const Eigen::MatrixXd& brace_jacobians, const Vector& bias,
                                 const Vector& l, bool& damped, ArmResponse* response) {
  if (!rows) {
    if (response) {
      response->acceleration = mass_solve(l - bias);
      response->mobility = mass_inverse();
    }
    return l;
  }
  return rows->sticking.empty() ? sliding_torque(*rows, bias, l, damped, response)
                                : sticking_torque(*rows, brace_jacobians, bias, l, damped, response);
}

}  // namespace bracing_engine
