// Pose and hybrid force/position control of a frame: the C++ twins of
// hqp.tasks.pose.PoseTask and hqp.tasks.hybrid.HybridTask.
//
// Pose (6 rows): e = [p - p_goal; log3(R_goal^T R)], the translation's feedback with its
// gains, the rotation's with the angular ones. Hybrid: the motion-controlled translation
// axes of that error, then the motion-controlled rotation axes in world axes
// (e_w = R_g log3(R_g^T R), with the rotating goal's derivative terms), then one row per
// force-controlled component of the contact slot, S_f f = f_des.
#pragma once

#include <Eigen/Core>

#include "model/robot.hpp"
#include "tasks/reference.hpp"

namespace hqp {

class PoseKernel {
 public:
  using Index = Eigen::Index;
  using Vector6d = RobotCore::Vector6d;

  /// `linear`, `angular`: the motion-controlled world axes (0-2) of the translation and the
  /// rotation; `world_rotation`: the rotation error in world axes (HybridTask) instead of the
  /// goal's (PoseTask); `force_start`, `force_index`: the contact slot's first column and
  /// the force-controlled components in it (none for a pose).
  PoseKernel(int frame, const Eigen::VectorXi& linear, const Eigen::VectorXi& angular,
             bool world_rotation, const PDGains& gains, const PDGains& angular_gains,
             Index force_start, const Eigen::VectorXi& force_index);

  Index rows() const { return motion_rows() + force_index_.size(); }
  Index motion_rows() const { return linear_.size() + angular_.size(); }
  void set_gains(const PDGains& gains, const PDGains& angular_gains) {
    gains_ = gains;
    angular_gains_ = angular_gains;
  }
  /// Goal placement T_world_goal and its world velocity and acceleration [linear; angular].
  void set_goal(const Eigen::Matrix4d& placement, const Vector6d& velocity,
                const Vector6d& acceleration);
  /// The desired force components (force rows,).
  void set_force(const Eigen::Ref<const Eigen::VectorXd>& force);

  /// Rows into A (rows, n), b (rows,); no allocation once sized.
  void write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> b);

  /// e, de/dt, drift and a_fb of the motion rows at the last write.
  const Eigen::VectorXd& error() const { return e_; }
  const Eigen::VectorXd& rate() const { return rate_; }
  const Eigen::VectorXd& drift() const { return drift_; }
  const Eigen::VectorXd& reference_acceleration() const { return a_; }

 private:
  int frame_;
  Eigen::VectorXi linear_, angular_;
  bool world_;
  PDGains gains_, angular_gains_;
  Index force_start_;
  Eigen::VectorXi force_index_;
  Eigen::Matrix3d goal_R_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d goal_p_ = Eigen::Vector3d::Zero();
  Vector6d goal_v_ = Vector6d::Zero(), goal_a_ = Vector6d::Zero();
  Eigen::VectorXd force_;
  Eigen::VectorXd e_, rate_, drift_, a_;
  RobotCore::Matrix6Xd J6_;
  Eigen::Matrix3Xd Jr_;
};

}  // namespace hqp
