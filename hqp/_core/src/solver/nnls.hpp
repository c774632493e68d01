// Non-negative least squares, min ||A x - b|| subject to x >= 0 (Lawson and Hanson, "Solving
// Least Squares Problems", 1974, ch. 23), with the QR factorisation of the passive columns
// updated by Givens rotations as columns enter and leave (O(m^2) per step instead of a
// refactorisation; A itself, not its Gram matrix, so dependent columns are recognised to
// about 1e-10), and an optional warm start from a previous passive set.
//
// The active-set warm start asks it whether multipliers of the right signs exist at a
// degenerate vertex (hqp/solver/active_set.py, `_signed_multipliers`, which calls SciPy's
// nnls): `solve` stops as soon as the residual meets the caller's tolerance.
#pragma once

#include "solver/linalg.hpp"

namespace hqp {

class Nnls {
 public:
  using Index = Eigen::Index;
  using MatrixXd = Eigen::MatrixXd;
  using VectorXd = Eigen::VectorXd;
  using CMatRef = Eigen::Ref<const MatrixXd>;
  using CVecRef = Eigen::Ref<const VectorXd>;

  /// Solve for A (m, n), b (m,). Stops early, returning true, once ||A x - b|| <= res_tol
  /// (res_tol < 0: never early, the full solve). `warm` (n,) non-zero entries name the
  /// columns tried first as passive (nullptr: a cold start from x = 0). At most max_outer
  /// column entries. Returns whether the final residual is <= res_tol.
  bool solve(const CMatRef& A, const CVecRef& b, double res_tol, int max_outer,
             const CMapI* warm = nullptr);
  /// Capacity for A up to (m, n): no allocation in solve() within it.
  void reserve(Index m, Index n);

  CMapV x() const { return x_.vec(); }
  double residual() const { return residual_; }
  /// The passive set of the last solve: 1 where x > 0 (n,).
  CMapI passive() const { return in_.vec(); }
  int steps() const { return steps_; }

 private:
  bool add(const CMatRef& A, Index j);  // append column j to the factor; false if dependent
  void remove(Index q);                 // remove the passive column at position q
  void rotate(Index i, Index k, double c, double s, Index first_col);  // rows i, k of Q^T
  void solve_passive();                 // z on the passive set
  double update_residual(const CMatRef& A, const CVecRef& b);

  // fixed-capacity storage (linalg.hpp's Work), shaped at each solve
  WorkM Q_, R_;  // Q^T A[:, P] = [R; 0]: Q (m, m), R (m, m), np columns used
  WorkM qtb_, x_, z_, w_, res_, col_;
  WorkI in_, idx_, skip_;  // passive flags, passive order, rejected as dependent
  Index m_ = 0, n_ = 0, np_ = 0;
  double residual_ = 0.0;
  int steps_ = 0;
};

}  // namespace hqp
