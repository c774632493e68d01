// Viable joint limits; see joint_limits.hpp.
#include "tasks/joint_limits.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hqp {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// The approach to the braking curve over T (hqp.tasks.joint_limits._approach).
double approach(double q, double v, double q_max, double B, double cap, double T) {
  const double v_b = std::sqrt(2.0 * B * std::max(q_max - q, 0.0));
  const double toward = std::max(v, 0.0);
  const double ff = v_b > 0.0 ? B * toward / v_b : (toward > 0.0 ? kInf : 0.0);
  return (v_b - v) / T - std::min(cap, ff);
}

/// The upper bound toward q_max of one joint (hqp.tasks.joint_limits._upper_bounds).
double upper_bound(double q, double v, double q_max, double v_max, double A, double B,
                   double cap, double rec, double dt, bool clip, double v_time,
                   double a_time) {
  const double room = q_max - q - dt * v;
  const double pos = std::min(2.0 * room, room) / (dt * dt);
  const double T = std::max(dt, v_time);
  const double vel = (v_max - v) / T;
  double via = kInf;
  const bool finite = std::isfinite(B) && std::isfinite(q_max);
  if (finite) {
    const double b = dt * (2.0 * v + B * dt);
    const double c = v * v + 2.0 * B * (q + dt * v - q_max);
    const double disc = b * b - 4.0 * dt * dt * c;
    double root = (-b + std::sqrt(std::max(disc, 0.0))) / (2.0 * dt * dt);
    if (a_time > 0.0) root = std::min(root, approach(q, v, q_max, B, cap, std::max(dt, a_time)));
    const double vp = std::max(v, 0.0);
    const double needed = vp * vp / (2.0 * std::max(q_max - q, 1e-12));
    const double brake = -std::min(rec, std::max(B, needed));
    via = disc >= 0.0 ? std::max(root, brake) : brake;
  }
  double bound = std::min(std::min(pos, vel), via);
  if (clip) bound = std::min(bound, A);
  if (finite && q > q_max) {
    const double v_ret = -std::min(v_max, std::sqrt(2.0 * B * (q - q_max)));
    bound = std::clamp((v_ret - v) / T, -cap, cap);
  }
  return bound;
}

}  // namespace

void joint_limit_bounds(const JointLimitParams& p, const Eigen::Ref<const Eigen::VectorXd>& q,
                        const Eigen::Ref<const Eigen::VectorXd>& v,
                        const Eigen::Ref<const Eigen::VectorXd>& A,
                        const Eigen::Ref<const Eigen::VectorXd>& B, double dt,
                        Eigen::Ref<Eigen::VectorXd> lb, Eigen::Ref<Eigen::VectorXd> ub) {
  const bool clip = p.acceleration_bounds;
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    const double cap = std::min(A(i), p.reserve * B(i));
    const double rec = p.recovery.size() > 0 ? std::max(cap, p.recovery(i)) : cap;
    double u = upper_bound(q(i), v(i), p.q_upper(i), p.v_max(i), A(i), B(i), cap, rec, dt, clip,
                           p.velocity_time, p.approach_time);
    double l = -upper_bound(-q(i), -v(i), -p.q_lower(i), p.v_max(i), A(i), B(i), cap, rec, dt,
                            clip, p.velocity_time, p.approach_time);
    if (l > u) {
      // crossed at a state that is not viable: brake (past a limit: the return wins)
      double brake = v(i) >= 0.0 ? -cap : cap;
      // with a recovery deceleration: the braking the crossed side asks, within it
      if (rec > cap) brake = v(i) >= 0.0 ? std::max(u, -rec) : std::min(l, rec);
      if (!std::isfinite(brake)) brake = v(i) >= 0.0 ? u : l;
      if (q(i) > p.q_upper(i))
        brake = u;
      else if (q(i) < p.q_lower(i))
        brake = l;
      l = u = brake;
    }
    ub(i) = u > p.inactive_beyond ? kInf : u;
    lb(i) = l < -p.inactive_beyond ? -kInf : l;
  }
}

}  // namespace hqp
