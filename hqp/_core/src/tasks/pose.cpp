// Pose and hybrid kernels; see pose.hpp.
#include "tasks/pose.hpp"

#include <stdexcept>

#include "tasks/orientation.hpp"

namespace hqp {

PoseKernel::PoseKernel(int frame, const Eigen::VectorXi& linear, const Eigen::VectorXi& angular,
                       bool world_rotation, const PDGains& gains, const PDGains& angular_gains,
                       Index force_start, const Eigen::VectorXi& force_index)
    : frame_(frame), linear_(linear), angular_(angular), world_(world_rotation), gains_(gains),
      angular_gains_(angular_gains), force_start_(force_start), force_index_(force_index) {
  for (const Eigen::VectorXi* axes : {&linear_, &angular_}) {
    for (Index i = 0; i < axes->size(); ++i) {
      if ((*axes)(i) < 0 || (*axes)(i) > 2) throw std::invalid_argument("pose: axis out of range");
    }
  }
  for (Index i = 0; i < force_index_.size(); ++i) {
    if (force_index_(i) < 0 || force_index_(i) > 5 || force_start_ < 0)
      throw std::invalid_argument("pose: force component out of range");
  }
  const Index m = motion_rows();
  e_.setZero(m);
  rate_.setZero(m);
  drift_.setZero(m);
  a_.setZero(m);
  force_.setZero(force_index_.size());
}

void PoseKernel::set_goal(const Eigen::Matrix4d& placement, const Vector6d& velocity,
                          const Vector6d& acceleration) {
  goal_R_ = placement.topLeftCorner<3, 3>();
  goal_p_ = placement.topRightCorner<3, 1>();
  goal_v_ = velocity;
  goal_a_ = acceleration;
}

void PoseKernel::set_force(const Eigen::Ref<const Eigen::VectorXd>& force) {
  if (force.size() != force_index_.size()) throw std::invalid_argument("pose: force of the wrong size");
  force_ = force;
}

void PoseKernel::write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                       Eigen::Ref<Eigen::VectorXd> b) {
  const Index nv = robot.nv();
  if (J6_.cols() != nv) {
    J6_.resize(6, nv);
    Jr_.resize(3, nv);
  }
  A.setZero();
  const Index nl = linear_.size(), na = angular_.size(), nm = nl + na;
  if (nl) {
    robot.frame_jacobian(frame_, J6_);
    const Eigen::Vector3d p = robot.frame_placement(frame_).translation();
    const Vector6d vel = robot.frame_velocity(frame_);
    const Vector6d acc = robot.frame_drift(frame_);
    for (Index i = 0; i < nl; ++i) {
      const int k = linear_(i);
      e_(i) = p(k) - goal_p_(k);
      rate_(i) = vel(k) - goal_v_(k);
      drift_(i) = acc(k) - goal_a_(k);
      A.row(i).head(nv) = J6_.row(k);
    }
  }
  if (na) {
    Eigen::Vector3d e, de, dr;
    orientation_kinematics(robot, frame_, goal_R_, goal_v_.tail<3>(), goal_a_.tail<3>(), J6_,
                           Jr_, e, de, dr);
    if (world_) {  // e_w = R_g e and its derivatives with the goal frame rotating at w_g
      const Eigen::Vector3d wg = goal_v_.tail<3>(), ag = goal_a_.tail<3>();
      const Eigen::Vector3d ew = goal_R_ * e, dew0 = goal_R_ * de;
      de = dew0 + wg.cross(ew);
      dr = goal_R_ * dr + 2.0 * wg.cross(dew0) + ag.cross(ew) + wg.cross(wg.cross(ew));
      e = ew;
      const Eigen::Matrix3d Rg = goal_R_;
      J6_.topRows<3>().noalias() = Rg * Jr_;  // J6_'s rows are free again: a workspace
      Jr_ = J6_.topRows<3>();
    }
    for (Index j = 0; j < na; ++j) {
      const int k = angular_(j);
      e_(nl + j) = e(k);
      rate_(nl + j) = de(k);
      drift_(nl + j) = dr(k);
      A.row(nl + j).head(nv) = Jr_.row(k);
    }
  }
  if (nl) pd_feedback(gains_, e_.head(nl), rate_.head(nl), a_.head(nl));
  if (na) pd_feedback(angular_gains_, e_.tail(na), rate_.tail(na), a_.tail(na));
  b.head(nm) = a_ - drift_;
  for (Index i = 0; i < force_index_.size(); ++i) {
    A(nm + i, force_start_ + force_index_(i)) = 1.0;
    b(nm + i) = force_(i);
  }
}

}  // namespace hqp
