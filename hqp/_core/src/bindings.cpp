// hqp._core._ext: the native core's Python module.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>

#include "bindings_law.hpp"
#include "bindings_model.hpp"
#include "bindings_solver.hpp"
#include "bindings_step.hpp"
#include "bindings_tasks.hpp"
#include "model.hpp"

namespace nb = nanobind;

NB_MODULE(_ext, m) {
  m.doc() = "hqp's native core: the strict lexicographic solver (and, from part 2, the step).";
  hqp::bind_solver(m);
  hqp::bind_model(m);
  hqp::bind_tasks(m);
  hqp::bind_step(m);
  hqp::bind_law(m);
  m.def(
      "check_urdf_model",
      [](const std::string& path, bool free_flyer, const Eigen::VectorXd& q,
         const Eigen::VectorXd& v) {
        hqp::ModelCheck r = hqp::check_urdf_model(path, free_flyer, q, v);
        return nb::make_tuple(r.nq, r.nv, r.mass, r.M, r.h);
      },
      nb::arg("urdf_path"), nb::arg("free_flyer"), nb::arg("q"), nb::arg("v"),
      "Mass matrix and bias forces of a URDF model from pinocchio's C++ API: (nq, nv, mass, "
      "M, h).");
}
