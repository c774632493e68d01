// Centre of pressure (ZMP) of the support driven to a goal point: the C++ twin of
// hqp.tasks.cop.CoPTask.rows (support_wrench_rows). With F_z = fz . x and the CoP numerators
// c_x F_z = nx . x, c_y F_z = ny . x on the plane z = h, the rows over the wrench slots are
// s [g_x fz - nx; g_y fz - ny] x = 0 (s = 1 / (m g)).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "model/robot.hpp"
#include "tasks/physics.hpp"

namespace hqp {

class CoPKernel {
 public:
  using Index = Eigen::Index;

  /// `height`: the plane's height [m], NaN: the mean height of the slots' frames at each
  /// state; `scale`: the rows' factor.
  CoPKernel(const std::vector<ContactSlotC>& slots, double height, double scale);

  Index rows() const { return 2; }
  void set_goal(const Eigen::Vector2d& goal) { goal_ = goal; }
  void write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
             Eigen::Ref<Eigen::VectorXd> b) const;

 private:
  std::vector<ContactSlotC> slots_;
  double height_, scale_;
  Eigen::Vector2d goal_ = Eigen::Vector2d::Zero();
};

}  // namespace hqp
