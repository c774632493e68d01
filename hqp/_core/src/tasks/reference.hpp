// The saturated PD reference of seed 003 eq. 27-28 with feedforward: the C++ twin of
// hqp.tasks.reference.PDReference (same operations in the same order).
//
//   v_des = -(kp / kv) e, scaled to norm max_velocity when longer           (eq. 28)
//   a_fb  = -kv (de/dt - v_des), scaled to norm max_acceleration when longer (eq. 27)
#pragma once

#include <Eigen/Core>
#include <limits>

namespace hqp {

struct PDGains {
  double kp = 0.0;
  double kv = 0.0;
  double max_velocity = std::numeric_limits<double>::infinity();
  double max_acceleration = std::numeric_limits<double>::infinity();
};

/// a_fb(e, de/dt) into `out` (same size as e); no allocation.
void pd_feedback(const PDGains& gains, const Eigen::Ref<const Eigen::VectorXd>& error,
                 const Eigen::Ref<const Eigen::VectorXd>& rate, Eigen::Ref<Eigen::VectorXd> out);

}  // namespace hqp
