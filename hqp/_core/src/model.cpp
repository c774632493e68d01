// The robot model side of the native core (pinocchio's C++ API). Part 1 of the native core
// links pinocchio and exposes what settles the build; the control step comes in part 2.
#include "model.hpp"

#include <pinocchio/algorithm/center-of-mass.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <stdexcept>

namespace hqp {

ModelCheck check_urdf_model(const std::string& urdf_path, bool free_flyer,
                            const Eigen::Ref<const Eigen::VectorXd>& q,
                            const Eigen::Ref<const Eigen::VectorXd>& v) {
  pinocchio::Model model;
  if (free_flyer) {
    pinocchio::urdf::buildModel(urdf_path, pinocchio::JointModelFreeFlyer(), model);
  } else {
    pinocchio::urdf::buildModel(urdf_path, model);
  }
  if (q.size() != model.nq || v.size() != model.nv) {
    throw std::invalid_argument("q or v: expected sizes (" + std::to_string(model.nq) + ", " +
                                std::to_string(model.nv) + ")");
  }
  pinocchio::Data data(model);
  ModelCheck out;
  out.nq = model.nq;
  out.nv = model.nv;
  out.mass = pinocchio::computeTotalMass(model);
  pinocchio::crba(model, data, q);
  data.M.triangularView<Eigen::StrictlyLower>() =
      data.M.transpose().triangularView<Eigen::StrictlyLower>();
  out.M = data.M;
  out.h = pinocchio::nonLinearEffects(model, data, q, v);
  return out;
}

}  // namespace hqp
