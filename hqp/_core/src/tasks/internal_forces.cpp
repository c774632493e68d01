// Internal forces kernel; see internal_forces.hpp.
#include "tasks/internal_forces.hpp"

#include <stdexcept>

namespace hqp {

InternalForcesKernel::InternalForcesKernel(const ContactSlotC& first, const ContactSlotC& second,
                                           const Eigen::VectorXi& components)
    : first_(first), second_(second), select_(components) {
  if (first.size != second.size) throw std::invalid_argument("internal forces: mixed contact kinds");
  const int count = first.size == 6 ? 6 : 1;
  for (Index i = 0; i < select_.size(); ++i) {
    if (select_(i) < 0 || select_(i) >= count)
      throw std::invalid_argument("internal forces: component out of range");
  }
  goal_.setZero(select_.size());
}

void InternalForcesKernel::set_goal(const Eigen::Ref<const Eigen::VectorXd>& goal) {
  if (goal.size() != rows()) throw std::invalid_argument("internal forces: goal of the wrong size");
  goal_ = goal;
}

const char* InternalForcesKernel::write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                                        Eigen::Ref<Eigen::VectorXd> b) const {
  const Eigen::Vector3d p1 = robot.frame_placement(first_.frame).translation();
  const Eigen::Vector3d p2 = robot.frame_placement(second_.frame).translation();
  const Eigen::Vector3d diff = p2 - p1;
  const double L = diff.norm();
  if (L < 1e-9) return "the two contact frames coincide";
  const Eigen::Vector3d d = diff / L;
  Eigen::Vector3d sh(-d(1), d(0), 0.0);  // z x d
  if (sh.norm() < 1e-6) sh = Eigen::Vector3d(0.0, -d(2), d(1));  // x x d (a vertical line)
  sh /= sh.norm();
  const Eigen::Vector3d sv = d.cross(sh);
  const int k = first_.size;
  A.setZero();
  for (Index i = 0; i < rows(); ++i) {
    // row i of B^+ = column c of B over its squared norm, split over the two slots
    auto r1 = A.row(i).segment(first_.start, k);
    auto r2 = A.row(i).segment(second_.start, k);
    const int c = select_(i);
    if (k == 3) {  // point contacts: tension only, B = [-d; d]
      r1 = -d.transpose() / 2.0;
      r2 = d.transpose() / 2.0;
      continue;
    }
    if (c == 0) {
      r1.head<3>() = -d.transpose() / 2.0;
      r2.head<3>() = d.transpose() / 2.0;
    } else if (c <= 2) {  // shear: F_1 = -s, F_2 = s, tau_1 = tau_2 = -(L/2) d x s
      const Eigen::Vector3d& s = c == 1 ? sh : sv;
      const Eigen::Vector3d tau = -0.5 * L * d.cross(s);
      const double norm2 = 2.0 * s.squaredNorm() + 2.0 * tau.squaredNorm();
      r1.head<3>() = -s.transpose() / norm2;
      r1.tail<3>() = tau.transpose() / norm2;
      r2.head<3>() = s.transpose() / norm2;
      r2.tail<3>() = tau.transpose() / norm2;
    } else {  // moments: tau_1 = -e, tau_2 = e
      const Eigen::Vector3d& e = c == 3 ? d : (c == 4 ? sh : sv);
      r1.tail<3>() = -e.transpose() / 2.0;
      r2.tail<3>() = e.transpose() / 2.0;
    }
  }
  b = goal_;
  return nullptr;
}

}  // namespace hqp
