// Gaze kernel; see gaze.hpp.
#include "tasks/gaze.hpp"

#include <cmath>

namespace hqp {

namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& a) {
  Eigen::Matrix3d S;
  S << 0.0, -a(2), a(1), a(2), 0.0, -a(0), -a(1), a(0), 0.0;
  return S;
}

}  // namespace

GazeKernel::GazeKernel(int frame, const Eigen::Vector3d& axis,
                       const Eigen::Matrix<double, 2, 3>& plane, const PDGains& gains)
    : frame_(frame), axis_(axis), P_(plane), gains_(gains) {}

void GazeKernel::set_goal(const Eigen::Vector3d& position, const Eigen::Vector3d& velocity,
                          const Eigen::Vector3d& acceleration) {
  goal_ = position;
  goal_v_ = velocity;
  goal_a_ = acceleration;
}

const char* GazeKernel::write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                              Eigen::Ref<Eigen::VectorXd> b) {
  const Index nv = robot.nv();
  if (J6_.cols() != nv) {
    J6_.resize(6, nv);
    Jp_.resize(3, nv);
  }
  const pinocchio::SE3& M = robot.frame_placement(frame_);
  const Eigen::Matrix3d Rt = M.rotation().transpose();
  const Eigen::Vector3d o = M.translation();
  robot.frame_jacobian(frame_, J6_);
  const RobotCore::Vector6d vel = robot.frame_velocity(frame_);
  const RobotCore::Vector6d acc = robot.frame_drift(frame_);
  const Eigen::Vector3d w = vel.tail<3>();
  const Eigen::Vector3d r = goal_ - o;
  const Eigen::Vector3d dr = goal_v_ - vel.head<3>();
  const Eigen::Vector3d p = Rt * r;
  const Eigen::Vector3d wv = dr + r.cross(w);  // R dp/dt
  const Eigen::Vector3d dp = Rt * wv;
  // J_p = R^T ([r]x J_ang - J_lin)
  const Eigen::Matrix3d RtS = Rt * skew(r);
  Jp_.noalias() = RtS * J6_.bottomRows<3>();
  Jp_.noalias() -= Rt * J6_.topRows<3>();
  const Eigen::Vector3d ddp0 =
      Rt * (goal_a_ - acc.head<3>() + dr.cross(w) + r.cross(acc.tail<3>()) - w.cross(wv));
  const double norm = p.norm();
  if (norm < 1e-9) return "the target is at the head frame's origin";
  const Eigen::Vector3d d = p / norm;
  const double n = norm + axis_.dot(p);
  if (n < 1e-12 * norm) return "the target is exactly behind the gaze ray";
  const Eigen::Vector3d grad_n = d + axis_;
  const Eigen::Vector2d Pp = P_ * p, Pdp = P_ * dp;
  const double dn = grad_n.dot(dp);
  const double ddp = d.dot(dp);
  const double hess = (dp.dot(dp) - ddp * ddp) / norm;
  e_ = 2.0 * Pp / n;
  const Eigen::Matrix<double, 2, 3> Df = 2.0 * (P_ / n - Pp * grad_n.transpose() / (n * n));
  rate_ = Df * dp;
  drift_ = Df * ddp0 + 2.0 * (-2.0 * Pdp * dn / (n * n) - Pp * hess / (n * n) +
                              2.0 * Pp * dn * dn / (n * n * n));
  A.setZero();
  A.leftCols(nv).noalias() = Df * Jp_;
  pd_feedback(gains_, e_, rate_, a_);
  b = a_ - drift_;
  return nullptr;
}

}  // namespace hqp
