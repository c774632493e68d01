// Internal forces between two contacts (the feet): the C++ twin of
// hqp.tasks.internal_forces.InternalForcesTask.rows. With B the basis of the internal
// wrenches of the two contacts (internal_basis: mutually orthogonal columns, so
// B^+ = diag(1 / |b_k|^2) B^T), the rows over the two wrench slots are S B^+ [w_1; w_2] =
// c_goal, S selecting the controlled components.
#pragma once

#include <Eigen/Core>

#include "model/robot.hpp"
#include "tasks/physics.hpp"

namespace hqp {

class InternalForcesKernel {
 public:
  using Index = Eigen::Index;

  /// Two slots of the same size; `components`: indices into
  /// hqp.tasks.internal_forces.COMPONENTS (0 only, tension, for point contacts).
  InternalForcesKernel(const ContactSlotC& first, const ContactSlotC& second,
                       const Eigen::VectorXi& components);

  Index rows() const { return select_.size(); }
  /// The goal of the selected components (rows,) [N, N m].
  void set_goal(const Eigen::Ref<const Eigen::VectorXd>& goal);
  /// Rows into A (rows, n), b (rows,); nullptr, or why they are undefined (the two contact
  /// origins coincide).
  const char* write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                    Eigen::Ref<Eigen::VectorXd> b) const;

 private:
  ContactSlotC first_, second_;
  Eigen::VectorXi select_;
  Eigen::VectorXd goal_;
};

}  // namespace hqp
