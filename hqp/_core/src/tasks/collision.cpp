// Capsule distance kernel; see collision.hpp.
#include "tasks/collision.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace hqp {

namespace {

constexpr double kEps = 1e-12;

double clip01(double x) { return std::min(std::max(x, 0.0), 1.0); }

/// A moving segment a + s u: the body-fixed points of a robot frame, or an obstacle.
struct Segment {
  Eigen::Vector3d a, u, u_dot;
  double radius = 0.0;
  bool robot = false;
  int frame = -1;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  RobotCore::Vector6d v6 = RobotCore::Vector6d::Zero(), a6 = RobotCore::Vector6d::Zero();

  Eigen::Vector3d velocity(const Eigen::Vector3d& p) const {
    if (!robot) return v6.head<3>();
    return v6.head<3>() + v6.tail<3>().cross(p - origin);
  }
  Eigen::Vector3d drift(const Eigen::Vector3d& p) const {
    if (!robot) return Eigen::Vector3d::Zero();
    const Eigen::Vector3d r = p - origin;
    const Eigen::Vector3d w = v6.tail<3>();
    return a6.head<3>() + a6.tail<3>().cross(r) + w.cross(w.cross(r));
  }
};

Segment robot_segment(const RobotCore& robot, const CapsuleC& c) {
  Segment s;
  const pinocchio::SE3& T = robot.frame_placement(c.frame);
  s.a = T.translation() + T.rotation() * c.a;
  s.u = T.rotation() * (c.b - c.a);
  s.v6 = robot.frame_velocity(c.frame);
  s.u_dot = s.v6.tail<3>().cross(s.u);
  s.radius = c.radius;
  s.robot = true;
  s.frame = c.frame;
  s.origin = T.translation();
  s.a6 = robot.frame_drift(c.frame);
  return s;
}

Segment obstacle_segment(const ObstacleC& o) {
  Segment s;
  s.a = o.a;
  s.u = o.b - o.a;
  s.u_dot.setZero();
  s.radius = o.radius;
  s.v6.head<3>() = o.velocity;
  return s;
}

}  // namespace

void closest_parameters(const Eigen::Vector3d& a1, const Eigen::Vector3d& u1,
                        const Eigen::Vector3d& a2, const Eigen::Vector3d& u2, double& s,
                        double& t) {
  const Eigen::Vector3d r = a1 - a2;
  const double a = u1.dot(u1), e = u2.dot(u2), f = u2.dot(r);
  s = t = 0.0;
  if (a <= kEps && e <= kEps) return;
  if (a <= kEps) {
    t = clip01(f / e);
    return;
  }
  const double c = u1.dot(r);
  if (e <= kEps) {
    s = clip01(-c / a);
    return;
  }
  const double b = u1.dot(u2);
  const double denom = a * e - b * b;
  s = denom > 1e-12 * a * e ? clip01((b * f - c * e) / denom) : 0.0;
  t = (b * s + f) / e;
  if (t < 0.0) {
    t = 0.0;
    s = clip01(-c / a);
  } else if (t > 1.0) {
    t = 1.0;
    s = clip01((b - c) / a);
  }
}

DistanceKernel::DistanceKernel(const DistanceParams& params) : p_(params) {
  if (!(p_.d_influence > p_.d_safe)) throw std::invalid_argument("distance: d_influence <= d_safe");
}

int DistanceKernel::add_pair(const CapsuleC& first, const CapsuleC& second) {
  pairs_.push_back({first, second, -1});
  margins_.setZero(rows());
  d_ = d_dot_ = drift_ = margins_;
  return int(pairs_.size()) - 1;
}

int DistanceKernel::add_obstacle_pair(const CapsuleC& capsule, int obstacle) {
  if (obstacle < 0) throw std::invalid_argument("distance: obstacle index < 0");
  if (obstacle >= int(obstacles_.size())) obstacles_.resize(std::size_t(obstacle) + 1);
  pairs_.push_back({capsule, CapsuleC{}, obstacle});
  margins_.setZero(rows());
  d_ = d_dot_ = drift_ = margins_;
  return int(pairs_.size()) - 1;
}

void DistanceKernel::set_obstacle(int obstacle, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  const Eigen::Vector3d& velocity, double radius) {
  if (obstacle < 0 || obstacle >= int(obstacles_.size()))
    throw std::invalid_argument("distance: no such obstacle");
  obstacles_[std::size_t(obstacle)] = {a, b, velocity, radius};
}

void DistanceKernel::write(const RobotCore& robot, double dt, Eigen::Ref<Eigen::MatrixXd> C,
                           Eigen::Ref<Eigen::VectorXd> lo, Eigen::Ref<Eigen::VectorXd> up) {
  const double inf = std::numeric_limits<double>::infinity();
  const Index nv = robot.nv();
  if (J6_.cols() != nv) J6_.resize(6, nv);
  const double kv = p_.kv > 0.0 ? p_.kv : 1.0 / dt;
  C.setZero();
  up.setConstant(inf);
  for (Index i = 0; i < rows(); ++i) {
    const Pair& pair = pairs_[std::size_t(i)];
    const Segment s1 = robot_segment(robot, pair.first);
    const Segment s2 = pair.obstacle < 0 ? robot_segment(robot, pair.second)
                                         : obstacle_segment(obstacles_[std::size_t(pair.obstacle)]);
    double s, t;
    closest_parameters(s1.a, s1.u, s2.a, s2.u, s, t);
    const Eigen::Vector3d p1 = s1.a + s * s1.u, p2 = s2.a + t * s2.u;
    const Eigen::Vector3d r = p1 - p2;
    const double dist = r.norm();
    const Eigen::Vector3d n = dist > 1e-9 ? Eigen::Vector3d(r / dist) : Eigen::Vector3d(0, 0, 1);
    // J_d = n^T (J_p1 - J_p2), J_p = J_lin - [p - o]x J_ang, so n^T J_p = n^T J_lin - (n x (p - o))^T J_ang
    auto row = C.row(i);
    for (const Segment* seg : {&s1, &s2}) {
      if (!seg->robot) continue;
      const double sign = seg == &s1 ? 1.0 : -1.0;
      const Eigen::Vector3d m = n.cross((seg == &s1 ? p1 : p2) - seg->origin);
      robot.frame_jacobian(seg->frame, J6_);
      for (Index c = 0; c < nv; ++c) {
        row(c) += sign * (n.dot(J6_.col(c).head<3>()) - m.dot(J6_.col(c).tail<3>()));
      }
    }
    const Eigen::Vector3d w = s1.velocity(p1) - s2.velocity(p2);
    const double uu1 = s1.u.dot(s1.u), uu2 = s2.u.dot(s2.u), u12 = s1.u.dot(s2.u);
    const bool free1 = 0.0 < s && s < 1.0 && uu1 > kEps;
    const bool free2 = 0.0 < t && t < 1.0 && uu2 > kEps;
    const double g1 = -(w.dot(s1.u) + r.dot(s1.u_dot));
    const double g2 = -(w.dot(s2.u) + r.dot(s2.u_dot));
    double s_dot = 0.0, t_dot = 0.0;
    if (free1 && free2) {
      // [[uu1, -u12], [u12, -uu2]] [s_dot; t_dot] = [g1; g2]
      const double det = -uu1 * uu2 + u12 * u12;
      if (std::abs(det) > 1e-12 * uu1 * uu2) {
        s_dot = (-uu2 * g1 + u12 * g2) / det;
        t_dot = (uu1 * g2 - u12 * g1) / det;
      }
    } else if (free1) {
      s_dot = g1 / uu1;
    } else if (free2) {
      t_dot = -g2 / uu2;
    }
    const Eigen::Vector3d r_dot = w + s_dot * s1.u - t_dot * s2.u;
    const double n_rdot = n.dot(r_dot);
    double drift = n.dot(s1.drift(p1) - s2.drift(p2));
    drift += 2.0 * s_dot * n.dot(s1.u_dot) - 2.0 * t_dot * n.dot(s2.u_dot);
    if (dist > 1e-9) drift += (r_dot.dot(r_dot) - n_rdot * n_rdot) / dist;
    const double d = dist - s1.radius - s2.radius;
    d_(i) = d;
    d_dot_(i) = n_rdot;
    drift_(i) = drift;
    margins_(i) = d - p_.d_safe;
    if (d < p_.d_influence) {
      const double d_dot_min = -p_.xi * (d - p_.d_safe) / (p_.d_influence - p_.d_safe);
      lo(i) = kv * (d_dot_min - n_rdot) - drift;
    } else {
      lo(i) = -inf;
    }
  }
}

}  // namespace hqp
