// The native robot model; see robot.hpp.
#include "model/robot.hpp"

#include <pinocchio/algorithm/center-of-mass.hpp>
#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <stdexcept>

namespace hqp {

RobotCore::RobotCore(const std::string& urdf_path, const std::string& root_joint,
                     const std::vector<ExtraFrame>& extra_frames) {
  try {
    if (root_joint.empty()) {
      pinocchio::urdf::buildModel(urdf_path, model_);
    } else {
      pinocchio::urdf::buildModel(urdf_path, pinocchio::JointModelFreeFlyer(), root_joint,
                                  model_);
    }
  } catch (const std::exception& e) {
    throw std::invalid_argument(urdf_path + ": " + e.what());
  }
  for (const ExtraFrame& f : extra_frames) {
    if (model_.existFrame(f.name)) {
      throw std::invalid_argument(urdf_path + ": frame '" + f.name + "' already exists");
    }
    if (!model_.existFrame(f.parent)) {
      throw std::invalid_argument(urdf_path + ": parent frame '" + f.parent + "' of '" +
                                  f.name + "' missing");
    }
    const auto parent_id = model_.getFrameId(f.parent);
    const pinocchio::Frame& parent = model_.frames[parent_id];
    model_.addFrame(pinocchio::Frame(f.name, parent.parentJoint, parent_id,
                                     parent.placement * f.placement,
                                     pinocchio::FrameType::OP_FRAME));
  }
  data_ = pinocchio::Data(model_);
  mass_ = pinocchio::computeTotalMass(model_);
  q_ = pinocchio::neutral(model_);
  v_ = Eigen::VectorXd::Zero(model_.nv);
  M_ = Eigen::MatrixXd::Zero(model_.nv, model_.nv);
  update(q_, v_);
}

void RobotCore::update(const Eigen::Ref<const Eigen::VectorXd>& q,
                       const Eigen::Ref<const Eigen::VectorXd>& v) {
  q_ = q;
  v_ = v;
  pinocchio::computeAllTerms(model_, data_, q_, v_);
  pinocchio::updateFramePlacements(model_, data_);
  M_.triangularView<Eigen::Upper>() = data_.M.triangularView<Eigen::Upper>();
  M_.triangularView<Eigen::StrictlyLower>() = data_.M.transpose().triangularView<Eigen::StrictlyLower>();
  centroidal_drift_.noalias() = data_.dAg * v_;
  com_drift_ = centroidal_drift_.head<3>() / data_.mass[0];
}

int RobotCore::frame_id(const std::string& name) const {
  if (!model_.existFrame(name)) return -1;
  return int(model_.getFrameId(name));
}

void RobotCore::frame_jacobian(int frame, Eigen::Ref<Matrix6Xd> J) const {
  J.setZero();
  pinocchio::getFrameJacobian(model_, data_, pinocchio::FrameIndex(frame),
                              pinocchio::LOCAL_WORLD_ALIGNED, J);
}

RobotCore::Vector6d RobotCore::frame_velocity(int frame) const {
  return pinocchio::getFrameVelocity(model_, data_, pinocchio::FrameIndex(frame),
                                     pinocchio::LOCAL_WORLD_ALIGNED)
      .toVector();
}

RobotCore::Vector6d RobotCore::frame_drift(int frame) const {
  return pinocchio::getFrameClassicalAcceleration(model_, data_, pinocchio::FrameIndex(frame),
                                                  pinocchio::LOCAL_WORLD_ALIGNED)
      .toVector();
}

}  // namespace hqp
