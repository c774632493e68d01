// Physics rows of the native step: the equation of motion's map of x, the floating-base
// dynamics (an equality level), the torque limits and the contacts (condition rows and
// wrench-cone limits). The C++ twins of hqp.tasks.dynamics, hqp.tasks.torque_limits and
// hqp.tasks.contact.
//
// x = [qdd (nv) | f_1 | ... | f_k]: a surface contact slot holds the wrench [force; torque]
// at the frame origin in world axes (6), a point contact the force (3).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "model/robot.hpp"

namespace hqp {

struct ContactSlotC {
  int frame = -1;
  int size = 6;       ///< 6: surface, 3: point
  Eigen::Index start = 0;
};

struct LayoutC {
  Eigen::Index nv = 0;
  std::vector<ContactSlotC> slots;
  Eigen::Index n() const {
    Eigen::Index n = nv;
    for (const ContactSlotC& s : slots) n += s.size;
    return n;
  }
};

/// G = [M | -J_1^T ... -J_k^T] (nv, n): M qdd - sum_c J_c^T f_c = S^T tau - h. `J6` is a
/// (6, nv) workspace.
void contact_dynamics(const RobotCore& robot, const LayoutC& layout, Eigen::Ref<Eigen::MatrixXd> G,
                      RobotCore::Matrix6Xd& J6);

/// The wrench cone in the contact frame's axes, the normal bound inserted after the
/// friction pyramid: (17, 6) for a surface (pyramid 4, normal 1, CoP 4, yaw torque 8),
/// (5, 3) for a point (hqp.tasks.contact.Contact.local_limits).
Eigen::MatrixXd contact_local_limits(int size, double mu, double half_length, double half_width);

class ContactKernel {
 public:
  ContactKernel(const ContactSlotC& slot, double mu, double half_length, double half_width,
                double f_min, double f_max, double kp, double kd);
  /// Active; the kp term's reference is the frame's placement at the next write (as
  /// Contact.activate() without a reference).
  void activate() { active_ = true; has_reference_ = false; }
  /// Active with the kp term's reference placement (world).
  void activate(const pinocchio::SE3& reference) { activate(); set_reference(reference); }
  /// Released: the slot is held at zero.
  void deactivate() { active_ = false; has_reference_ = false; }
  /// The upper bound of the normal force (a contact unloading lowers it step by step).
  void set_max_normal_force(double f_max);
  double max_normal_force() const { return f_max_; }
  Eigen::Index rows() const { return slot_.size; }
  Eigen::Index limit_rows() const { return local_.rows(); }
  /// Condition rows (size, n): J_c qdd = -drift - kd v - kp e, or f_c = 0 when inactive.
  void write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> b);
  /// Limit rows (17 or 5, n) with their bounds (infinite when inactive).
  void write_limits(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> C,
                    Eigen::Ref<Eigen::VectorXd> lo, Eigen::Ref<Eigen::VectorXd> up) const;

 private:
  void set_reference(const pinocchio::SE3& T) { reference_ = T; has_reference_ = true; }
  ContactSlotC slot_;
  Eigen::MatrixXd local_;
  double f_min_, f_max_, kp_, kd_;
  bool active_ = true;
  bool has_reference_ = false;
  pinocchio::SE3 reference_;
  RobotCore::Matrix6Xd J6_;
};

}  // namespace hqp
