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
  /// Positions after DAQP's attempts: ProxQP's last resort, then the primal active-set
  /// method from the known feasible point (PrimalQP).
  static constexpr int kProxQP = kAttempts, kPrimal = kAttempts + 1, kSlots = kAttempts + 2;
  /// Calls per attempt: DAQP's (margin, primal_tol, eps_prox) in the order tried, then
  /// ProxQP's and PrimalQP's.
  long long calls[kSlots];
  long long successes[kSlots];
  long long nanoseconds[kSlots];
  /// Iterations per attempt (DAQP's; ProxQP's inner ones; PrimalQP's working-set changes).
  long long iterations[kSlots];
  /// DAQP calls that failed, by exit flag: index -flag (1 infeasible, 2 cycling,
  /// 3 unbounded, 4 iteration limit, ...; 0: a non-finite point with a success flag).
  static constexpr int kFlags = 9;
  long long failures[kFlags];
};
QPStats qp_stats();
void reset_qp_stats();

using CRowMatRef =
    Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;

/// A primal active-set method for a convex QP started at a feasible point:
///
///   min 0.5 v^T H v + g^T v   s.t.  lo <= C v <= up,
///
/// H symmetric positive semidefinite. The working set W holds rows at one of their bounds
/// (a row dependent on W to rounding may enter; the pivoted QR's rank sets the null space).
/// Each iteration minimises the objective on {C_W p = 0} (the minimum-norm step of the
/// reduced Newton system through a pivoted QR, or, where the reduced gradient has a part
/// the reduced Hessian does not reach, that part as a descent direction of zero curvature),
/// moves as far as the first row it meets allows (ties to the smallest index) and adds that
/// row; a step of zero length ends in the multipliers of W, the most negative dropped
/// (after n changes without progress, the one of the smallest row index: Bland's rule, so
/// that a degenerate vertex cannot cycle). Every iterate is feasible, so it never reports a
/// feasible problem infeasible (DAQP's dual iterations do, on the hierarchy's thin feasible
/// sets: docs/design/control.md). The hierarchy knows a feasible point of each level QP (the
/// levels above's solution, the level's slacks at their clamp), which is where it starts.
/// Returns true only where the KKT conditions hold at the returned v (the multipliers of W
/// non-negative within 1e-9 of |H v + g|). Fixed-capacity storage: no allocation once
/// reserved.
class PrimalQP {
 public:
  void reserve(Index n, Index m);
  /// Solve from the feasible v (n,) (rows violated by rounding are clipped by the ratio
  /// test); v holds the last iterate. At most `max_iter` working-set changes.
  bool solve(const CRowMatRef& H, const CVecRef& g, const CRowMatRef& C, const CVecRef& lo,
             const CVecRef& up, VecRef v, int max_iter);
  /// Working-set changes of the last solve.
  int iterations() const { return iterations_; }

 private:
  PivotedQR wqr_;    // of C_W (k, n)
  LeastSquares ls_;  // the reduced Newton step
  WorkM cw_, z_, hz_, hr_, gr_, u_, res_, p_, grad_, cp_, cv_, t_, nu_, rn_;
  WorkI work_, side_;  // the working rows (k,); per row 0 free, +1 at up, -1 at lo
  int iterations_ = 0;
};

class LevelQP {
 public:
  /// Capacity for n variables and m inequality rows (DAQP allocates its own workspace per
  /// call, outside this storage; the ProxQP last resort allocates).
  void reserve(Index n, Index m);
  /// min 0.5 v^T H v + g^T v  s.t.  lo <= C v <= up (C may have no rows). Returns whether
  /// DAQP converged; v (n,) holds its point (NaN when nothing finite came back). `quick`:
  /// the cheap attempts only and no ProxQP (hqp.solver.qp.solve_qp's `quick`: the hierarchy's
  /// first pass, whose failure sends the solve to the absorbing pass).
  /// `start` (n,; nullptr: none): a point feasible for the rows, from which PrimalQP solves
  /// the QP where DAQP's first attempt fails (not in a quick solve), before the relaxed attempts.
  bool solve(const CMatRef& H, const CVecRef& g, const CMatRef& C, const CVecRef& lo,
             const CVecRef& up, VecRef v, bool quick = false, const double* start = nullptr);
  /// Forget the relaxation memory.
  void reset() { sticky_ = -1; }
  /// The work budget the next solves draw on (nullptr: unbounded): a DAQP iteration costs
  /// 1, a PrimalQP iteration kPrimalWork. Where it runs out, no further attempt starts;
  /// with a feasible start (the absorbing pass), the PrimalQP iterate reached (feasible, its
  /// cost no higher than the start's) is the answer and cut() is true.
  void set_budget(long long* budget) { budget_ = budget; }
  /// Whether the last solve stopped on the work budget, or returned a feasible PrimalQP
  /// iterate short of optimality because every attempt failed.
  bool cut() const { return cut_; }
  /// Work units of one PrimalQP iteration (a pivoted QR of the working rows against a DAQP
  /// iteration's rank-one update of its factor).
  static constexpr long long kPrimalWork = 25;

 private:
  using RowMap = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
  bool daqp(int margin_index, int n_eps, VecRef v);
  bool proxqp(VecRef v);
  // fixed-capacity storage (linalg.hpp's Work); H_ and A_ hold row-major matrices
  WorkM H_, A_, g_, lo_, up_, bu_, bl_, lam_, v2_, keep_;
  PrimalQP primal_;
  Index n_ = 0, m_ = 0;
  std::vector<int> sense_;
  int sticky_ = -1;    // index of the relaxation that last succeeded on this slot
  int sticky_left_ = 0;
  long long* budget_ = nullptr;
  bool cut_ = false;
  /// Whether the budget is spent (never, without one).
  bool spent() const { return budget_ != nullptr && *budget_ <= 0; }
};

}  // namespace hqp
