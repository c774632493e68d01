// Robot-model entry points of the native core (pinocchio).
#pragma once

#include <Eigen/Core>
#include <string>

namespace hqp {

/// Mass matrix and bias forces of a URDF model at (q, v), straight from pinocchio's C++ API
/// (tested against the Python bindings: the link to libpinocchio is the wheel's own).
struct ModelCheck {
  int nq = 0;
  int nv = 0;
  double mass = 0.0;
  Eigen::MatrixXd M;  ///< (nv, nv) joint-space inertia
  Eigen::VectorXd h;  ///< (nv,) Coriolis, centrifugal and gravity terms
};

ModelCheck check_urdf_model(const std::string& urdf_path, bool free_flyer,
                            const Eigen::Ref<const Eigen::VectorXd>& q,
                            const Eigen::Ref<const Eigen::VectorXd>& v);

}  // namespace hqp
