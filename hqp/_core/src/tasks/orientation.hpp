// Orientation of a frame, e = log3(R_goal^T R) (3 rows, goal axes): the C++ twin of
// hqp.tasks.orientation.orientation_kinematics and OrientationTask.rows. With
// xi = R^T (omega - omega_goal):
//   de/dt   = Jlog3(E) xi
//   d2e/dt2 = Jlog3(E) R^T J_ang qdd + Jlog3(E) R^T (a_ang + omega x omega_goal - alpha_goal)
//             + dJlog3/dt xi
#pragma once

#include <Eigen/Core>

#include "model/robot.hpp"
#include "tasks/reference.hpp"

namespace hqp {

/// d/dt Jlog3 along e(t) with rate de, applied to xi (hqp.tasks.orientation.jlog3_rate_times).
Eigen::Vector3d jlog3_rate_times(const Eigen::Vector3d& e, const Eigen::Vector3d& de,
                                 const Eigen::Vector3d& xi);

/// e = log3(R_goal^T R), de/dt, its Jacobian J (3, nv) and drift at the updated model
/// (hqp.tasks.orientation.orientation_kinematics): the goal's rotation, world angular
/// velocity and acceleration. `J6` is a (6, nv) workspace. No allocation.
void orientation_kinematics(const RobotCore& robot, int frame, const Eigen::Matrix3d& goal,
                            const Eigen::Vector3d& goal_w, const Eigen::Vector3d& goal_a,
                            RobotCore::Matrix6Xd& J6, Eigen::Ref<Eigen::MatrixXd> J,
                            Eigen::Vector3d& e, Eigen::Vector3d& de, Eigen::Vector3d& drift);

class OrientationTracking {
 public:
  OrientationTracking(int frame, const PDGains& gains);
  void set_gains(const PDGains& gains) { gains_ = gains; }
  /// Goal rotation R_world_goal, its world angular velocity and acceleration.
  void set_goal(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& velocity,
                const Eigen::Vector3d& acceleration);
  Eigen::Index rows() const { return 3; }
  void write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> b);
  const Eigen::Vector3d& error() const { return e_; }
  const Eigen::Vector3d& reference_acceleration() const { return a_; }

 private:
  int frame_;
  PDGains gains_;
  Eigen::Matrix3d goal_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d goal_w_ = Eigen::Vector3d::Zero(), goal_a_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d e_ = Eigen::Vector3d::Zero(), a_ = Eigen::Vector3d::Zero();
  RobotCore::Matrix6Xd J6_;
};

}  // namespace hqp
