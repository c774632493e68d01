// hqp._core._ext_checked: the same solver and control step, built with Eigen's run-time
// allocation check (EIGEN_RUNTIME_NO_MALLOC; see solver/malloc_check.hpp), for the
// no-allocation tests.
#include "bindings_law.hpp"
#include "bindings_model.hpp"
#include "bindings_solver.hpp"
#include "bindings_step.hpp"
#include "bindings_tasks.hpp"

NB_MODULE(_ext_checked, m) {
  m.doc() = "hqp's native solver and step with Eigen's heap-allocation check (tests only).";
  hqp::bind_solver(m);
  hqp::bind_model(m);
  hqp::bind_tasks(m);
  hqp::bind_step(m);
  hqp::bind_law(m);
}
