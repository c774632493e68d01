// The PD reference; see reference.hpp.
#include "tasks/reference.hpp"

#include <cmath>

namespace hqp {

void pd_feedback(const PDGains& gains, const Eigen::Ref<const Eigen::VectorXd>& error,
                 const Eigen::Ref<const Eigen::VectorXd>& rate, Eigen::Ref<Eigen::VectorXd> out) {
  const double inf = std::numeric_limits<double>::infinity();
  // out = v_des first, then a_fb
  if (gains.kv == 0.0) {
    out.setZero();
  } else {
    out = -(gains.kp / gains.kv) * error;
    if (gains.max_velocity < inf) {
      const double norm = std::sqrt(out.dot(out));
      if (norm > gains.max_velocity) out *= gains.max_velocity / norm;
    }
  }
  out = -gains.kv * (rate - out);
  if (gains.max_acceleration < inf) {
    const double norm = std::sqrt(out.dot(out));
    if (norm > gains.max_acceleration) out *= gains.max_acceleration / norm;
  }
}

}  // namespace hqp
