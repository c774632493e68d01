// Physics rows; see physics.hpp.
#include "tasks/physics.hpp"

#include <pinocchio/spatial/explog.hpp>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace hqp {

void contact_dynamics(const RobotCore& robot, const LayoutC& layout, Eigen::Ref<Eigen::MatrixXd> G,
                      RobotCore::Matrix6Xd& J6) {
  const Eigen::Index nv = layout.nv;
  if (J6.cols() != nv) J6.resize(6, nv);
  G.leftCols(nv) = robot.M();
  for (const ContactSlotC& s : layout.slots) {
    robot.frame_jacobian(s.frame, J6);
    G.middleCols(s.start, s.size) = -J6.topRows(s.size).transpose();
  }
}

Eigen::MatrixXd contact_local_limits(int size, double mu, double half_length, double half_width) {
  const double m = mu / std::sqrt(2.0);
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(size == 6 ? 17 : 5, size);
  const double friction[4][3] = {{1.0, 0.0, -m}, {-1.0, 0.0, -m}, {0.0, 1.0, -m}, {0.0, -1.0, -m}};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 3; ++j) L(i, j) = friction[i][j];
  L(4, 2) = 1.0;  // the normal force, bounded by [f_min, f_max]
  if (size != 6) return L;
  const double X = half_length, Y = half_width;
  // centre of pressure: cop_y = tau_x / f_z in [-Y, Y], cop_x = -tau_y / f_z in [-X, X]
  L.row(5) << 0.0, 0.0, -Y, 1.0, 0.0, 0.0;
  L.row(6) << 0.0, 0.0, -Y, -1.0, 0.0, 0.0;
  L.row(7) << 0.0, 0.0, -X, 0.0, 1.0, 0.0;
  L.row(8) << 0.0, 0.0, -X, 0.0, -1.0, 0.0;
  // yaw torque (Caron et al. 2015, Theorem 1), one pair of rows per sign pair
  int r = 9;
  for (double s1 : {1.0, -1.0}) {
    for (double s2 : {1.0, -1.0}) {
      L.row(r++) << s1 * Y, s2 * X, -m * (X + Y), -s1 * m, -s2 * m, -1.0;
      L.row(r++) << s1 * Y, s2 * X, -m * (X + Y), s1 * m, s2 * m, 1.0;
    }
  }
  return L;
}

ContactKernel::ContactKernel(const ContactSlotC& slot, double mu, double half_length,
                             double half_width, double f_min, double f_max, double kp, double kd)
    : slot_(slot), local_(contact_local_limits(slot.size, mu, half_length, half_width)),
      f_min_(f_min), f_max_(f_max), kp_(kp), kd_(kd) {}

void ContactKernel::set_max_normal_force(double f_max) {
  if (std::isnan(f_max) || f_max < f_min_)
    throw std::invalid_argument("contact: max_normal_force must be >= f_min and not NaN");
  f_max_ = f_max;
}

void ContactKernel::write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                          Eigen::Ref<Eigen::VectorXd> b) {
  const int k = slot_.size;
  const Eigen::Index nv = robot.nv();
  A.setZero();
  if (!active_) {
    A.middleCols(slot_.start, k).setIdentity();
    b.setZero();
    return;
  }
  if (J6_.cols() != nv) J6_.resize(6, nv);
  robot.frame_jacobian(slot_.frame, J6_);
  A.leftCols(nv) = J6_.topRows(k);
  b = -robot.frame_drift(slot_.frame).head(k);
  if (kd_ > 0.0) b -= kd_ * robot.frame_velocity(slot_.frame).head(k);
  if (kp_ > 0.0) {
    const pinocchio::SE3& T = robot.frame_placement(slot_.frame);
    if (!has_reference_) set_reference(T);
    Eigen::Matrix<double, 6, 1> e;
    e.head<3>() = T.translation() - reference_.translation();
    e.tail<3>() = pinocchio::log3(Eigen::Matrix3d(T.rotation() * reference_.rotation().transpose()));
    b -= kp_ * e.head(k);
  }
}

void ContactKernel::write_limits(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> C,
                                 Eigen::Ref<Eigen::VectorXd> lo,
                                 Eigen::Ref<Eigen::VectorXd> up) const {
  const double inf = std::numeric_limits<double>::infinity();
  const Eigen::Matrix3d Rt = robot.frame_placement(slot_.frame).rotation().transpose();
  C.setZero();
  C.middleCols(slot_.start, 3).noalias() = local_.leftCols(3) * Rt;
  if (slot_.size == 6) C.middleCols(slot_.start + 3, 3).noalias() = local_.rightCols(3) * Rt;
  if (active_) {
    up.setZero();
    lo.setConstant(-inf);
    lo(4) = f_min_;
    up(4) = f_max_;
  } else {
    lo.setConstant(-inf);
    up.setConstant(inf);
  }
}

}  // namespace hqp
