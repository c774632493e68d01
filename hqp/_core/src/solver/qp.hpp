// The compiled QP of the native solver's cold and degenerate levels: DAQP (vendored C
// sources), with the Python daqp backend's settings and the hierarchy's retries on
// relaxed bounds (hqp/solver/backends/daqp.py, hqp.solver.qp.solve_qp); where nothing finite
// comes back, ProxQP's header-only dense solver (proxsuite wheel) as the last resort.
#pragma once

#include <vector>

#include "solver/linalg.hpp"

namespace hqp {

/// What the level QPs of this process tried and what converged (a diagnostic of the retry
/// cascade: relaxed bounds x DAQP tolerances x proximal weights, then ProxQP). Counters are
/// relaxed atomics: cheap, and safe with steps in several threads.
struct QPStats {
  static constexpr int kMargins = 3, kTols = 2, kEps = 5;
  static constexpr int kAttempts = kMargins * kTols * kEps;
  /// DAQP calls per (margin, primal_tol, eps_prox) attempt, in the order tried; the last
  /// entry is ProxQP's.
  long long calls[kAttempts + 1];
  long long successes[kAttempts + 1];
  long long nanoseconds[kAttempts + 1];
};
QPStats qp_stats();
void reset_qp_stats();

class LevelQP {
 public:
  /// Capacity for n variables and m inequality rows (DAQP allocates its own workspace per
  /// call, outside this storage; the ProxQP last resort allocates).
  void reserve(Index n, Index m);
  /// min 0.5 v^T H v + g^T v  s.t.  lo <= C v <= up (C may have no rows). Returns whether
  /// DAQP converged; v (n,) holds its point (NaN when nothing finite came back). `quick`:
  /// the cheap attempts only and no ProxQP (hqp.solver.qp.solve_qp's `quick`: the hierarchy's
  /// first pass, whose failure sends the solve to the absorbing pass).
  bool solve(const CMatRef& H, const CVecRef& g, const CMatRef& C, const CVecRef& lo,
             const CVecRef& up, VecRef v, bool quick = false);
  /// Forget the relaxation memory.
  void reset() { sticky_ = -1; }

 private:
  using RowMap = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
  bool daqp(int margin_index, int n_eps, VecRef v);
  bool proxqp(VecRef v);
  // fixed-capacity storage (linalg.hpp's Work); H_ and A_ hold row-major matrices
  WorkM H_, A_, g_, lo_, up_, bu_, bl_, lam_, v2_;
  Index n_ = 0, m_ = 0;
  std::vector<int> sense_;
  int sticky_ = -1;    // index of the relaxation that last succeeded on this slot
  int sticky_left_ = 0;
};

}  // namespace hqp
