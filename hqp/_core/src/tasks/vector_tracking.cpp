// Vector tracking kernels; see vector_tracking.hpp.
#include "tasks/vector_tracking.hpp"

#include <stdexcept>

namespace hqp {

VectorTracking::VectorTracking(Kind kind, int frame, const Eigen::VectorXi& select,
                               const Eigen::VectorXi& v_index, const Eigen::VectorXd& scale,
                               const PDGains& gains)
    : kind_(kind), frame_(frame), select_(select), v_index_(v_index), scale_(scale),
      gains_(gains) {
  const Index m = select_.size();
  if (kind_ == Kind::kJoints && v_index_.size() != m) {
    throw std::invalid_argument("joint task: q and v index lists differ in length");
  }
  if (scale_.size() != 0 && scale_.size() != m) {
    throw std::invalid_argument("tracking task: scale has the wrong length");
  }
  goal_ = goal_v_ = goal_a_ = Eigen::VectorXd::Zero(m);
  e_ = rate_ = drift_ = a_ = Eigen::VectorXd::Zero(m);
}

void VectorTracking::set_goal(const Eigen::Ref<const Eigen::VectorXd>& position,
                              const Eigen::Ref<const Eigen::VectorXd>& velocity,
                              const Eigen::Ref<const Eigen::VectorXd>& acceleration) {
  if (position.size() != rows() || velocity.size() != rows() || acceleration.size() != rows()) {
    throw std::invalid_argument("tracking task: goal of the wrong size");
  }
  goal_ = position;
  goal_v_ = velocity;
  goal_a_ = acceleration;
}

void VectorTracking::write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                           Eigen::Ref<Eigen::VectorXd> b) {
  const Index m = rows();
  const Index nv = robot.nv();
  A.setZero();
  auto J = A.leftCols(nv);
  switch (kind_) {
    case Kind::kFramePosition: {
      if (J6_.cols() != nv) J6_.resize(6, nv);
      robot.frame_jacobian(frame_, J6_);
      const pinocchio::SE3& T = robot.frame_placement(frame_);
      const RobotCore::Vector6d vel = robot.frame_velocity(frame_);
      const RobotCore::Vector6d acc = robot.frame_drift(frame_);
      for (Index i = 0; i < m; ++i) {
        const int k = select_(i);
        e_(i) = T.translation()(k) - goal_(i);
        rate_(i) = vel(k) - goal_v_(i);
        drift_(i) = acc(k) - goal_a_(i);
        J.row(i) = J6_.row(k);
      }
      break;
    }
    case Kind::kCenterOfMass: {
      for (Index i = 0; i < m; ++i) {
        const int k = select_(i);
        e_(i) = robot.com()(k) - goal_(i);
        rate_(i) = robot.com_velocity()(k) - goal_v_(i);
        drift_(i) = robot.com_drift()(k) - goal_a_(i);
        J.row(i) = robot.com_jacobian().row(k);
      }
      break;
    }
    case Kind::kJoints: {
      for (Index i = 0; i < m; ++i) {
        e_(i) = robot.q()(select_(i)) - goal_(i);
        rate_(i) = robot.v()(v_index_(i)) - goal_v_(i);
        drift_(i) = 0.0 - goal_a_(i);
        J(i, v_index_(i)) = 1.0;
      }
      break;
    }
    case Kind::kCentroidal: {
      for (Index i = 0; i < m; ++i) {
        const int k = select_(i);
        e_(i) = 0.0;
        rate_(i) = robot.centroidal_matrix().row(k).dot(robot.v()) - goal_(i);
        drift_(i) = robot.centroidal_drift()(k) - goal_v_(i);
        J.row(i) = robot.centroidal_matrix().row(k);
      }
      break;
    }
  }
  if (scale_.size()) {
    e_.array() *= scale_.array();
    rate_.array() *= scale_.array();
    drift_.array() *= scale_.array();
    J.array().colwise() *= scale_.array();
  }
  pd_feedback(gains_, e_, rate_, a_);
  b = a_ - drift_;
}

}  // namespace hqp
