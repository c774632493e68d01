// Viable joint position and velocity limits as acceleration bounds (Del Prete, RA-L 2018):
// the C++ twin of hqp.tasks.joint_limits.JointLimits.bounds, whose module docstring
// derives every bound (one-step position, viability, velocity, acceleration, the return
// from past a limit, crossed bounds at a state that is not viable).
#pragma once

#include <Eigen/Core>

namespace hqp {

struct JointLimitParams {
  Eigen::VectorXd q_lower, q_upper;  ///< position limits with the position margin applied
  Eigen::VectorXd v_max;             ///< velocity limits with the velocity scale applied
  double reserve = 0.0;              ///< the deceleration cap is min(A, reserve B)
  double velocity_time = 0.0;        ///< time constant of the velocity bound [s]
  double inactive_beyond = 1e4;      ///< bounds beyond this are dropped (infinite)
  bool acceleration_bounds = true;   ///< |qdd| <= A as well
  double approach_time = 0.0;        ///< time constant of the approach to the braking curve
  Eigen::VectorXd recovery;          ///< recovery deceleration (na,), or empty: the cap alone
};

/// lb <= qdd_a <= ub (each (na,)) at the actuated joints' (q, v), for the maximum
/// acceleration A and the braking deceleration B (each (na,)) and the period dt. No
/// allocation.
void joint_limit_bounds(const JointLimitParams& p, const Eigen::Ref<const Eigen::VectorXd>& q,
                        const Eigen::Ref<const Eigen::VectorXd>& v,
                        const Eigen::Ref<const Eigen::VectorXd>& A,
                        const Eigen::Ref<const Eigen::VectorXd>& B, double dt,
                        Eigen::Ref<Eigen::VectorXd> lb, Eigen::Ref<Eigen::VectorXd> ub);

}  // namespace hqp
