// A call into the core from Python: the GIL released and, in the checked module, Eigen's
// run-time allocation check on (shared by the solver's, the step's and the law's bindings).
#pragma once

#include <nanobind/nanobind.h>

#include <string>
#include <utility>

#include "solver/linalg.hpp"

namespace hqp {

/// Runs `call` (returning "" or an error) with the GIL released and, in the checked module,
/// heap allocation forbidden when `forbid_malloc`; returns its error, or the checked build's
/// first assertion ("eigen assertion (N in this <what>): ...").
template <typename Call>
std::string released(bool forbid_malloc, const char* what, Call&& call) {
  std::string error;
  nanobind::gil_scoped_release release;
#ifdef HQP_CHECK_MALLOC
  AssertionLog& log = assertion_log();
  log.count = 0;
  log.first.clear();
  set_malloc_allowed(!forbid_malloc);
  error = std::forward<Call>(call)();
  set_malloc_allowed(true);
  if (log.count) {
    error = "eigen assertion (" + std::to_string(log.count) + " in this " + what + "): " +
            log.first;
  }
#else
  (void)forbid_malloc;
  (void)what;
  error = std::forward<Call>(call)();
#endif
  return error;
}

}  // namespace hqp
