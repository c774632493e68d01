// Gaze: a ray of a head frame pointed at a world target (2 rows, the stereographic image
// coordinates of the target). The C++ twin of hqp.tasks.gaze.GazeTask.kinematics (whose
// docstring derives every term), with its rows [J | 0] x = a_fb(e, de/dt) - drift.
#pragma once

#include <Eigen/Core>

#include "model/robot.hpp"
#include "tasks/reference.hpp"

namespace hqp {

class GazeKernel {
 public:
  using Index = Eigen::Index;

  /// `axis`: the unit gaze ray in the frame's coordinates; `plane`: the rows (u, w) that
  /// complete it to a right-handed frame (GazeTask._P).
  GazeKernel(int frame, const Eigen::Vector3d& axis, const Eigen::Matrix<double, 2, 3>& plane,
             const PDGains& gains);

  Index rows() const { return 2; }
  void set_gains(const PDGains& gains) { gains_ = gains; }
  /// The target point [m] (world), its velocity and acceleration.
  void set_goal(const Eigen::Vector3d& position, const Eigen::Vector3d& velocity,
                const Eigen::Vector3d& acceleration);

  /// The rows into A (2, n) and b (2,); no allocation once sized. Returns nullptr, or the
  /// reason the rows are undefined (the target at the frame's origin or exactly behind the
  /// ray; GazeTask raises InvalidInput there).
  const char* write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                    Eigen::Ref<Eigen::VectorXd> b);

  const Eigen::Vector2d& error() const { return e_; }
  const Eigen::Vector2d& rate() const { return rate_; }
  const Eigen::Vector2d& drift() const { return drift_; }
  const Eigen::Vector2d& reference_acceleration() const { return a_; }

 private:
  int frame_;
  Eigen::Vector3d axis_;
  Eigen::Matrix<double, 2, 3> P_;
  PDGains gains_;
  Eigen::Vector3d goal_ = Eigen::Vector3d::Zero(), goal_v_ = Eigen::Vector3d::Zero(),
                  goal_a_ = Eigen::Vector3d::Zero();
  Eigen::Vector2d e_ = Eigen::Vector2d::Zero(), rate_ = Eigen::Vector2d::Zero(),
                  drift_ = Eigen::Vector2d::Zero(), a_ = Eigen::Vector2d::Zero();
  RobotCore::Matrix6Xd J6_;
  Eigen::Matrix3Xd Jp_;
};

}  // namespace hqp
