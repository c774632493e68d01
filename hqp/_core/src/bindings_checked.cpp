// hqp._core._ext_checked: the same solver, built with Eigen's run-time allocation check
// (EIGEN_RUNTIME_NO_MALLOC; eigen_assert throws), for the no-allocation test.
#include "bindings_solver.hpp"

NB_MODULE(_ext_checked, m) {
  m.doc() = "hqp's native solver with Eigen's heap-allocation check (tests only).";
  hqp::bind_solver(m);
}
