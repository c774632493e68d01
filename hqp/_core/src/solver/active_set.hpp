// Active-set warm start of one level problem, verified by its optimality conditions: the
// C++ twin of hqp/solver/active_set.py (see its module docstring for the method).
//
//   min_v ||A v - b||^2 + ||dist(C v, [lo, up])||^2   s.t.  gl <= G v <= gu
//
// A guess holds s (mc,) per level row (+1 violated above, -1 below, 0 inside) and w (p,) per
// carried row (+1 held at gu, -1 at gl, 0 free).
#pragma once

#include <vector>

#include <Eigen/Cholesky>

#include "solver/linalg.hpp"
#include "solver/nnls.hpp"

namespace hqp {

constexpr double kFeasTol = 1e-9;
constexpr double kDualTol = 1e-9;
constexpr int kMaxIter = 6;
/// A held carried row within this (times its scale) of its bound takes a multiplier in
/// absorbed(); a dependent held row further inside its band is inactive
/// (hqp.solver.active_set.AT_BOUND_TOL).
constexpr double kAtBoundTol = 1e-7;
/// A held carried row whose multiplier exceeds this (relative to the dual scale of
/// kDualTol) is active over the level's whole optimal set (hqp.solver.active_set.ABSORB_TOL).
constexpr double kAbsorbTol = 1e-6;

struct LevelRows {
  CMatRef A;
  CVecRef b;
  CMatRef C;
  CVecRef lo, up, los, ups;
};

/// Rows carried from the levels above, gl <= G Z v <= gu: G over the full variables and the
/// basis Z of the level's reduced coordinates v (nullptr: the identity). The product G Z is
/// never formed here: held rows are projected one by one, G Z v as G (Z v).
struct CarriedRows {
  CMatRef G;
  CVecRef gl, gu, gls, gus;
  const WorkM* Z = nullptr;
};

class ActiveSetSolver {
 public:
  /// Capacity for ma equality rows, mc inequality rows and up to p carried rows over nv
  /// reduced coordinates (the basis Z of n rows), at most max_iter guesses per solve.
  void reserve(Index ma, Index mc, Index p, Index nv, Index n, int max_iter);
  /// Solve from the guess (s (mc,), w (p,)), updated in place to the last guess tried.
  /// Returns true and v (nv,) when a guess verified; `ref` (nv,; nullptr: none) picks the
  /// minimiser closest to it where the rows leave directions free.
  bool solve(const LevelRows& L, const CarriedRows& K, IVecRef s, IVecRef w, double rank_tol,
             double scale, int max_iter, const double* ref, VecRef v);
  /// After a solve() that returned true with v: the held carried rows whose multipliers,
  /// one dual solution by non-negative least squares over the held rows at their bound
  /// (kAtBoundTol), exceed kAbsorbTol
  /// (hqp.solver.active_set.held_multipliers). Sets absorbed (p,) to 1 on those rows, 0
  /// elsewhere; returns how many, or -1 (absorbed zeroed) where the optimality conditions
  /// do not hold to kDualTol.
  Index absorbed(const CVecRef& v, IVecRef absorbed);

 private:
  bool signed_multipliers(Index nheld, double dtol);
  PivotedQR kqr_;
  LeastSquares ls_;
  // fixed-capacity storage (linalg.hpp's Work), shaped at each guess
  WorkM M_, Kh_, MQ_;
  WorkM zv_;
  WorkM d_, kh_, ksc_, vp_, rhs_, zr_, t_, cv_, gv_, grad_, res_, mu_, tmp_;
  WorkI held_, wp_, s_new_, w_new_, dep_g_, free_, inside_;
  WorkI seen_;  // the guesses tried: (mc + p, max_iter + 1)
  // NNLS workspace
  Nnls nnls_;
  WorkM nn_A_, nn_b_;
  WorkI nn_warm_, nn_memo_;  // per held row / per carried row: positive at the last call
  WorkI at_;  // absorbed(), signed_multipliers(): positions of the held rows at their bound
};

/// The active set of a point: level rows by the side they violate, carried rows held when
/// within active_tol * scale of a bound (hqp.solver.active_set.guess_from_point).
/// s (mc,) and w (p,) are given at their sizes (cv, gv: nullptr where mc, p are 0).
void guess_from_point(const double* cv, const CVecRef& lo, const CVecRef& up,
                      const CVecRef& los, const CVecRef& ups, const double* gv,
                      const CVecRef& gl, const CVecRef& gu, const CVecRef& gls,
                      const CVecRef& gus, double active_tol, IVecRef s, IVecRef w);

}  // namespace hqp
