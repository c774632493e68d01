// Orientation tracking; see orientation.hpp.
#include "tasks/orientation.hpp"

#include <pinocchio/spatial/explog.hpp>

#include <cmath>

namespace hqp {

namespace {

/// beta(theta) and gamma = beta'(theta) / theta of Jlog3(e) = I + [e]x / 2 + beta [e]x^2.
void jlog3_coefficients(double th, double& beta, double& gamma) {
  if (th < 1e-2) {
    const double t2 = th * th;
    beta = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0;
    gamma = 1.0 / 360.0 + t2 / 7560.0 + t2 * t2 / 201600.0;
  } else {
    const double s = std::sin(th), c = std::cos(th);
    beta = 1.0 / (th * th) - (1.0 + c) / (2.0 * th * s);
    gamma = (-2.0 / (th * th * th) + (th + s) / (2.0 * th * th * (1.0 - c))) / th;
  }
}

}  // namespace

Eigen::Vector3d jlog3_rate_times(const Eigen::Vector3d& e, const Eigen::Vector3d& de,
                                 const Eigen::Vector3d& xi) {
  const double ee = e(0) * e(0) + e(1) * e(1) + e(2) * e(2);
  const double ed = e(0) * de(0) + e(1) * de(1) + e(2) * de(2);
  const double ex = e(0) * xi(0) + e(1) * xi(1) + e(2) * xi(2);
  const double dx = de(0) * xi(0) + de(1) * xi(1) + de(2) * xi(2);
  double beta, gamma;
  jlog3_coefficients(std::sqrt(ee), beta, gamma);
  const double g = gamma * ed;
  const double ce = g * ex + beta * dx;         // coefficient of e
  const double cx = -g * ee - 2.0 * beta * ed;  // coefficient of xi
  const double cd = beta * ex;                  // coefficient of de
  Eigen::Vector3d out;
  out(0) = 0.5 * (de(1) * xi(2) - de(2) * xi(1)) + ce * e(0) + cd * de(0) + cx * xi(0);
  out(1) = 0.5 * (de(2) * xi(0) - de(0) * xi(2)) + ce * e(1) + cd * de(1) + cx * xi(1);
  out(2) = 0.5 * (de(0) * xi(1) - de(1) * xi(0)) + ce * e(2) + cd * de(2) + cx * xi(2);
  return out;
}

OrientationTracking::OrientationTracking(int frame, const PDGains& gains)
    : frame_(frame), gains_(gains) {}

void OrientationTracking::set_goal(const Eigen::Matrix3d& rotation,
                                   const Eigen::Vector3d& velocity,
                                   const Eigen::Vector3d& acceleration) {
  goal_ = rotation;
  goal_w_ = velocity;
  goal_a_ = acceleration;
}

void orientation_kinematics(const RobotCore& robot, int frame, const Eigen::Matrix3d& goal,
                            const Eigen::Vector3d& goal_w, const Eigen::Vector3d& goal_a,
                            RobotCore::Matrix6Xd& J6, Eigen::Ref<Eigen::MatrixXd> J,
                            Eigen::Vector3d& e, Eigen::Vector3d& de, Eigen::Vector3d& drift) {
  const Eigen::Index nv = robot.nv();
  if (J6.cols() != nv) J6.resize(6, nv);
  const Eigen::Matrix3d R = robot.frame_placement(frame).rotation();
  const RobotCore::Vector6d vel = robot.frame_velocity(frame);
  const RobotCore::Vector6d acc = robot.frame_drift(frame);
  const Eigen::Vector3d w = vel.tail<3>();
  const Eigen::Matrix3d Rt = R.transpose();
  const Eigen::Matrix3d E = goal.transpose() * R;
  e = pinocchio::log3(E);
  Eigen::Matrix3d Jlog;
  pinocchio::Jlog3(E, Jlog);
  const Eigen::Vector3d xi = Rt * (w - goal_w);
  const Eigen::Matrix3d JR = Jlog * Rt;
  de = Jlog * xi;
  drift = JR * (acc.tail<3>() + w.cross(goal_w) - goal_a) + jlog3_rate_times(e, de, xi);
  robot.frame_jacobian(frame, J6);
  J.noalias() = JR * J6.bottomRows<3>();
}

void OrientationTracking::write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                                Eigen::Ref<Eigen::VectorXd> b) {
  const Eigen::Index nv = robot.nv();
  A.setZero();
  Eigen::Vector3d de, drift;
  orientation_kinematics(robot, frame_, goal_, goal_w_, goal_a_, J6_, A.leftCols(nv), e_, de,
                         drift);
  pd_feedback(gains_, e_, de, a_);
  b = a_ - drift;
}

}  // namespace hqp
