// Eigen's run-time allocation check of the checked build (hqp._core._ext_checked): included
// before any Eigen header (linalg.hpp includes it first; the checked module's other units
// force-include it), so that every Eigen allocation in those units reports through it.
#pragma once

#ifdef HQP_CHECK_MALLOC
// The checked build (hqp._core._ext_checked): Eigen's run-time allocation check reports
// through eigen_assert, which here records the failure (count, first call stack) and lets
// the operation go on (throwing from inside Eigen's allocator would leave objects half
// resized), so a test can read what happened after the solve.
#include <execinfo.h>

#include <cstdlib>

#include <string>
namespace hqp {
struct AssertionLog {
  int count = 0;
  std::string first;
};
inline AssertionLog& assertion_log() {
  static thread_local AssertionLog log;
  return log;
}
inline void eigen_assert_failed(const char* what) {
  AssertionLog& log = assertion_log();
  if (log.count++ == 0) {
    void* frames[16];
    const int n = backtrace(frames, 16);
    char** names = backtrace_symbols(frames, n);
    log.first = what;
    for (int i = 1; names && i < n; ++i) log.first += std::string("\n  ") + names[i];
    free(names);
  }
}
}  // namespace hqp
#define eigen_assert(x)                                                  \
  do {                                                                   \
    if (!static_cast<bool>(x)) ::hqp::eigen_assert_failed(#x);           \
  } while (false)
#endif
