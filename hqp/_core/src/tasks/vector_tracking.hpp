// Vector tracking tasks of the native step: a frame's origin (PositionTask), the centre of
// gravity (CoMTask, seed 003 eq. 24) and joint positions (PostureTask, eq. 26 with its
// normalising scale), on selected coordinates. The C++ twin of
// hqp.tasks.tracking.VectorTrackingTask.rows:
//
//   e = W (x - x_goal), de/dt = W (xd - xd_goal), drift = W (dJ v - xdd_goal), J = W J_x
//   rows [J | 0] x = a_fb(e, de/dt) - drift
//
// And the centroidal momentum h = A_g v (CentroidalMomentumTask, a velocity-level task):
// e = 0, de/dt = S h - h_goal, J = S A_g, drift = S dA_g v - hdot_goal, with kp = 0 and
// kv its gain (the goal's "position" is h_goal, its "velocity" hdot_goal).
#pragma once

#include <Eigen/Core>

#include "model/robot.hpp"
#include "tasks/reference.hpp"

namespace hqp {

class VectorTracking {
 public:
  using Index = Eigen::Index;
  enum class Kind { kFramePosition, kCenterOfMass, kJoints, kCentroidal };

  /// `select`: the frame's or CoM's world axes (0-2), or the joints' indices into q for
  /// kJoints with `v_index` their indices into v. `scale` (empty: none) is W's diagonal.
  VectorTracking(Kind kind, int frame, const Eigen::VectorXi& select,
                 const Eigen::VectorXi& v_index, const Eigen::VectorXd& scale,
                 const PDGains& gains);

  Index rows() const { return select_.size(); }
  void set_gains(const PDGains& gains) { gains_ = gains; }
  /// Goal and its feedforward velocity and acceleration, each (rows,).
  void set_goal(const Eigen::Ref<const Eigen::VectorXd>& position,
                const Eigen::Ref<const Eigen::VectorXd>& velocity,
                const Eigen::Ref<const Eigen::VectorXd>& acceleration);

  /// The task's rows at the updated model into A (rows, n) and b (rows,); no allocation.
  void write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
             Eigen::Ref<Eigen::VectorXd> b);

  const Eigen::VectorXd& error() const { return e_; }
  /// de/dt at the last write (the momentum error of the centroidal kind, whose e is zero).
  const Eigen::VectorXd& rate() const { return rate_; }
  const Eigen::VectorXd& reference_acceleration() const { return a_; }

 private:
  Kind kind_;
  int frame_;
  Eigen::VectorXi select_, v_index_;
  Eigen::VectorXd scale_;
  PDGains gains_;
  Eigen::VectorXd goal_, goal_v_, goal_a_;
  Eigen::VectorXd e_, rate_, drift_, a_;
  RobotCore::Matrix6Xd J6_;
};

}  // namespace hqp
