// Capsule distance constraints (obstacle avoidance and self-collision): the C++ twin of
// hqp.tasks.collision (closest_parameters, _distance and _DistanceTask.rows; the module
// docstring derives the distance, its Jacobian and drift and the velocity-damper rows).
//
// One inequality row per pair: J_d qdd >= kv (d_dot_min - d_dot) - drift while
// d < d_influence (else -inf), d_dot_min = -xi (d - d_safe) / (d_influence - d_safe).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "model/robot.hpp"

namespace hqp {

/// A capsule fixed in a robot frame: the segment [a, b] in the frame's coordinates.
struct CapsuleC {
  int frame = -1;
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

/// A world obstacle (sphere: a = b): its segment [m], linear velocity [m/s] and radius.
struct ObstacleC {
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

struct DistanceParams {
  double d_safe = 0.05, d_influence = 0.2, xi = 0.3;
  double kv = 0.0;  ///< <= 0: 1 / dt
};

/// Parameters (s, t) in [0, 1] of the closest points of a1 + s u1 and a2 + t u2
/// (hqp.tasks.collision.closest_parameters).
void closest_parameters(const Eigen::Vector3d& a1, const Eigen::Vector3d& u1,
                        const Eigen::Vector3d& a2, const Eigen::Vector3d& u2, double& s,
                        double& t);

class DistanceKernel {
 public:
  using Index = Eigen::Index;

  explicit DistanceKernel(const DistanceParams& params);
  /// A pair of two robot capsules (self-collision); returns its row.
  int add_pair(const CapsuleC& first, const CapsuleC& second);
  /// A pair of a robot capsule and obstacle `obstacle` (see set_obstacle); returns its row.
  int add_obstacle_pair(const CapsuleC& capsule, int obstacle);
  /// The obstacle's segment, velocity and radius now (obstacles move between steps).
  void set_obstacle(int obstacle, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                    const Eigen::Vector3d& velocity, double radius);
  int obstacle_count() const { return int(obstacles_.size()); }

  Index rows() const { return Index(pairs_.size()); }
  /// The rows into C (rows, n), lo, up (rows,) for the period dt; no allocation once sized.
  void write(const RobotCore& robot, double dt, Eigen::Ref<Eigen::MatrixXd> C,
             Eigen::Ref<Eigen::VectorXd> lo, Eigen::Ref<Eigen::VectorXd> up);

  /// d - d_safe per pair at the last write (the task's error).
  const Eigen::VectorXd& margins() const { return margins_; }
  /// d, d_dot and drift per pair at the last write (for the finite-difference tests).
  const Eigen::VectorXd& distance() const { return d_; }
  const Eigen::VectorXd& rate() const { return d_dot_; }
  const Eigen::VectorXd& drift() const { return drift_; }

 private:
  struct Pair {
    CapsuleC first;
    CapsuleC second;   // a robot capsule when obstacle < 0
    int obstacle = -1;
  };
  DistanceParams p_;
  std::vector<Pair> pairs_;
  std::vector<ObstacleC> obstacles_;
  Eigen::VectorXd margins_, d_, d_dot_, drift_;
  RobotCore::Matrix6Xd J6_;
};

}  // namespace hqp
