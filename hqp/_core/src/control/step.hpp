// The native control step: one call from the state to the torques. The robot model's one
// pinocchio pass, every task kernel writing its rows straight into the solver's level
// matrices (weights applied as sqrt(w), as hqp.stack.Stack.build), the strict hierarchy
// solved in place, and the actuated torques tau = S (M qdd + h - sum_c J_c^T f_c).
//
// The structure (which kernels at which level) is fixed when the step is built; goals,
// contact activation and the joint-limit braking change between steps through the kernels'
// setters.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "model/robot.hpp"
#include "solver/hierarchy.hpp"
#include "tasks/joint_limits.hpp"
#include "tasks/orientation.hpp"
#include "tasks/physics.hpp"
#include "tasks/vector_tracking.hpp"

namespace hqp {

class NativeStep {
 public:
  using Index = Eigen::Index;
  enum class Kind { kDynamics, kTorqueLimits, kContact, kContactLimits, kJointLimits,
                    kTracking, kOrientation };

  NativeStep(std::unique_ptr<RobotCore> robot, Index nv_base, LayoutC layout, int n_levels,
             const Settings& settings);

  // the kernels, in their level's row order; each returns its handle
  int add_dynamics(int level, double weight);
  int add_torque_limits(int level, double weight, const Eigen::VectorXd& tau_max);
  int add_contact(int level, double weight, const ContactKernel& kernel);
  int add_contact_limits(int level, double weight, int contact);
  int add_joint_limits(int level, double weight, const JointLimitParams& params,
                       const Eigen::VectorXd& max_acceleration, const Eigen::VectorXd& braking);
  int add_tracking(int level, double weight, const VectorTracking& kernel);
  int add_orientation(int level, double weight, const OrientationTracking& kernel);

  VectorTracking& tracking(int handle);
  OrientationTracking& orientation(int handle);
  ContactKernel& contact(int handle);
  void set_braking(int handle, const Eigen::VectorXd& braking);

  /// One control step at (q, v) with the period dt; "" on success, else the failure. No
  /// heap allocation once the first step has sized everything.
  std::string step(const Eigen::Ref<const Eigen::VectorXd>& q,
                   const Eigen::Ref<const Eigen::VectorXd>& v, double dt);

  Index n() const { return n_; }
  const RobotCore& robot() const { return *robot_; }
  const Hierarchy& hierarchy() const { return hierarchy_; }
  /// The built levels (non-empty ones, in order) of the last step.
  int level_count() const { return int(used_.size()); }
  const LevelData& level(int k) const { return hierarchy_.levels()[std::size_t(k)]; }
  int level_index(int k) const { return used_[std::size_t(k)]; }
  const Eigen::VectorXd& x() const { return hierarchy_.x(); }
  const Eigen::VectorXd& tau() const { return tau_; }

 private:
  struct Entry {
    Kind kind;
    int level;
    double sqrt_w;
    int index;  // into the kernel list of its kind
    Index neq = 0, nin = 0, eq0 = 0, in0 = 0;
  };
  struct JointLimitEntry {
    JointLimitParams params;
    Eigen::VectorXd A, B, lb, ub;
  };
  int add(Kind kind, int level, double weight, int index, Index neq, Index nin);
  void layout_levels();

  std::unique_ptr<RobotCore> robot_;
  Index nv_base_, na_, n_;
  LayoutC layout_;
  int n_levels_;
  Hierarchy hierarchy_;
  std::vector<Entry> entries_;
  std::vector<ContactKernel> contacts_;
  std::vector<VectorTracking> tracking_;
  std::vector<OrientationTracking> orientation_;
  std::vector<JointLimitEntry> joint_limits_;
  std::vector<Eigen::VectorXd> tau_max_;
  std::vector<int> used_;          // built level k -> stack level index
  std::vector<int> built_of_;      // stack level index -> built level (-1: empty)
  bool laid_out_ = false;
  Eigen::MatrixXd G_;
  RobotCore::Matrix6Xd J6_;
  Eigen::VectorXd tau_;
};

}  // namespace hqp
