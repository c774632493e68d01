// Centre-of-pressure kernel; see cop.hpp.
#include "tasks/cop.hpp"

#include <cmath>
#include <stdexcept>

namespace hqp {

CoPKernel::CoPKernel(const std::vector<ContactSlotC>& slots, double height, double scale)
    : slots_(slots), height_(height), scale_(scale) {
  if (slots_.empty()) throw std::invalid_argument("cop: no contact slots");
}

void CoPKernel::write(const RobotCore& robot, Eigen::Ref<Eigen::MatrixXd> A,
                      Eigen::Ref<Eigen::VectorXd> b) const {
  double h = height_;
  if (std::isnan(h)) {
    h = 0.0;
    for (const ContactSlotC& s : slots_) h += robot.frame_placement(s.frame).translation()(2);
    h /= double(slots_.size());
  }
  A.setZero();
  b.setZero();
  const double gx = goal_(0), gy = goal_(1);
  for (const ContactSlotC& s : slots_) {
    const Eigen::Vector3d p = robot.frame_placement(s.frame).translation();
    const Index i = s.start;
    // rows g fz - n: fz = e_z, nx = [h - p_z, 0, p_x, 0, -1, 0], ny = [0, h - p_z, p_y, 1, 0, 0]
    A(0, i + 0) = scale_ * (-(h - p(2)));
    A(0, i + 2) = scale_ * (gx - p(0));
    A(1, i + 1) = scale_ * (-(h - p(2)));
    A(1, i + 2) = scale_ * (gy - p(1));
    if (s.size == 6) {
      A(0, i + 4) = scale_ * 1.0;
      A(1, i + 3) = scale_ * -1.0;
    }
  }
}

}  // namespace hqp
