// The robot model of the native control step: pinocchio's Model and Data, one pass per step.
// The C++ twin of hqp.model.RobotModel.update (same library, same calls, same conventions:
// free flyer [x y z qx qy qz qw], LOCAL_WORLD_ALIGNED frame quantities, [linear; angular]).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

namespace hqp {

/// A frame added to the URDF's: on its parent frame's joint, at `placement` in the parent.
struct ExtraFrame {
  std::string name;
  std::string parent;
  pinocchio::SE3 placement;
};

class RobotCore {
 public:
  using Index = Eigen::Index;
  using Vector6d = Eigen::Matrix<double, 6, 1>;
  using Matrix6Xd = Eigen::Matrix<double, 6, Eigen::Dynamic>;

  /// Build from a URDF; `root_joint` names the free flyer (empty: a fixed base).
  /// Throws std::invalid_argument naming what is wrong (file, frame).
  RobotCore(const std::string& urdf_path, const std::string& root_joint,
            const std::vector<ExtraFrame>& extra_frames);

  Index nq() const { return model_.nq; }
  Index nv() const { return model_.nv; }
  double mass() const { return mass_; }
  const pinocchio::Model& model() const { return model_; }
  const pinocchio::Data& data() const { return data_; }

  /// Every quantity of a control step at (q, v): joint and frame placements, velocities,
  /// accelerations at qdd = 0, Jacobians, M (symmetric), h, g, CoM, its Jacobian and
  /// drift, A_g and dA_g v. No heap allocation.
  void update(const Eigen::Ref<const Eigen::VectorXd>& q,
              const Eigen::Ref<const Eigen::VectorXd>& v);

  /// Frame index, -1 when the model has no frame of that name.
  int frame_id(const std::string& name) const;
  /// The frame's Jacobian (6, nv) into J, LOCAL_WORLD_ALIGNED, rows [linear; angular].
  void frame_jacobian(int frame, Eigen::Ref<Matrix6Xd> J) const;
  /// The frame's spatial velocity and classical acceleration at qdd = 0 (LWA).
  Vector6d frame_velocity(int frame) const;
  Vector6d frame_drift(int frame) const;
  const pinocchio::SE3& frame_placement(int frame) const { return data_.oMf[frame]; }

  const Eigen::VectorXd& q() const { return q_; }
  const Eigen::VectorXd& v() const { return v_; }
  const Eigen::MatrixXd& M() const { return M_; }
  const Eigen::VectorXd& h() const { return data_.nle; }
  const Eigen::VectorXd& g() const { return data_.g; }
  const Eigen::Vector3d& com() const { return data_.com[0]; }
  const Eigen::Vector3d& com_velocity() const { return data_.vcom[0]; }
  const Eigen::Vector3d& com_drift() const { return com_drift_; }
  const Eigen::Matrix3Xd& com_jacobian() const { return data_.Jcom; }
  const Matrix6Xd& centroidal_matrix() const { return data_.Ag; }
  const Vector6d& centroidal_drift() const { return centroidal_drift_; }

 private:
  pinocchio::Model model_;
  mutable pinocchio::Data data_;
  Eigen::VectorXd q_, v_;
  Eigen::MatrixXd M_;
  Vector6d centroidal_drift_;
  Eigen::Vector3d com_drift_;
  double mass_ = 0.0;
};

}  // namespace hqp
