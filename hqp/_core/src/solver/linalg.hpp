// Small dense factorisations of the native solver (Eigen), the C++ twins of
// hqp/solver/linalg.py. Every object is a workspace: sized once per shape, then recomputed
// in place without heap allocation while the shape holds.
#pragma once

#include "solver/malloc_check.hpp"

#include <Eigen/Core>
#include <Eigen/QR>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

namespace hqp {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;
using MatRef = Eigen::Ref<MatrixXd>;
using CMatRef = Eigen::Ref<const MatrixXd>;
using VecRef = Eigen::Ref<VectorXd>;
using CVecRef = Eigen::Ref<const VectorXd>;

/// Whether Eigen may allocate on the heap (checked build only; no-op otherwise).
void set_malloc_allowed(bool allowed);

/// Singular values of a matrix T (d, c), d <= c, largest first: eigenvalues of T T^T
/// (tridiagonal QR, O(d^3) once), and a Jacobi SVD of T only where the smallest is below
/// 1e-6 of the largest (where squaring would lose its digits: eps * s_max^2 / s_min).
class TriangularSingularValues {
 public:
  /// `rank_tol`, `scale`: a square triangular T whose smallest diagonal entry is at most
  /// rank_tol * max(s_max, scale) has s_min below that threshold too (s_min <= min |T_ii|):
  /// s(d-1) is then set to 0 without the Jacobi SVD (the rank decision the caller makes).
  void compute(const MatrixXd& T, VecRef s, double rank_tol = 0.0, double scale = 0.0);

 private:
  MatrixXd G_;
  Eigen::SelfAdjointEigenSolver<MatrixXd> eig_;
  Eigen::JacobiSVD<MatrixXd> svd_;
};

/// Rank-revealing QR of a matrix M (m, r) through M^T P = Q R (column pivoting on M^T, i.e.
/// on the rows of M, as LAPACK's dgeqp3 in the Python reference).
///
/// Rank: the number of |R_ii| above rank_tol * max(|R_00|, scale).
class PivotedQR {
 public:
  /// Factorise M. `scale`: the largest entry of the level's unprojected rows (0 if none).
  void compute(const CMatRef& M, double rank_tol, double scale);
  /// Factorise with the rank relative to |R_00| alone (the active-set solves).
  void compute_relative(const CMatRef& M, double rank_tol);

  Index rank() const { return rank_; }
  Index rows() const { return m_; }  ///< m
  Index cols() const { return r_; }  ///< r
  /// Orthonormal basis (r, r - rank) of the null space of M: Q's trailing columns, formed
  /// from the reflectors alone.
  const MatrixXd& null();
  /// v := Q v and v := Q^T v for v (r,).
  void apply_q(VecRef v);
  void apply_qt(VecRef v);
  /// A := A Q for A (rows, r).
  void apply_q_right(MatRef A);
  /// Least-squares solution y (r,) of M y ~ rhs, minimum norm up to the rank cut.
  void lstsq(const CVecRef& rhs, VecRef y);
  /// y (r,) = Q1 R11^-T k[piv[:rank]] (the minimum-norm point of the first `rank` pivoted
  /// rows of M held at k; the active-set solves).
  void particular(const CVecRef& k, VecRef y);
  /// mu[piv[:rank]] = R11^-1 c for c (rank,) (multipliers of the held rows).
  void multipliers(const CVecRef& c, VecRef mu);
  /// Index of the i-th pivoted row of M.
  Index pivot(Index i) const { return perm_(i); }
  /// Singular values of M (those of R), largest first, into s (min(m, r),).
  void singular_values(VecRef s, double rank_tol = 0.0, double scale = 0.0);
  /// The upper-left (rank, rank) block of R.
  Eigen::Block<const MatrixXd> R11() const {
    return qr_.matrixQR().topLeftCorner(rank_, rank_);
  }

 private:
  void factor(const CMatRef& M);
  Eigen::ColPivHouseholderQR<MatrixXd> qr_;
  MatrixXd Mt_;
  MatrixXd N_;
  MatrixXd L_;
  MatrixXd Rsq_;
  Eigen::ColPivHouseholderQR<MatrixXd> lqr_;
  TriangularSingularValues sv_;
  VectorXd ws_, wsn_, wsr_, z_, c_;  // ws_, wsn_, wsr_: Householder workspaces (vector, N_, rows)
  Eigen::VectorXi perm_;
  Index m_ = 0, r_ = 0, rank_ = 0;
  bool n_ready_ = false;
};


/// Minimum-norm least squares of M y ~ rhs (the C++ twin of hqp.solver.linalg.lstsq):
/// pivoted QR with the threshold rank_tol * max(|R_00|, scale).
class LeastSquares {
 public:
  void solve(const CMatRef& M, const CVecRef& rhs, double rank_tol, double scale, VecRef y);

 private:
  PivotedQR qr_;
};

/// Singular values of M (m, r), m <= r, largest first: those of the (m, m) triangular
/// factor of M^T.
class SingularValues {
 public:
  const VectorXd& compute(const CMatRef& M, double rank_tol = 0.0, double scale = 0.0);

 private:
  Eigen::ColPivHouseholderQR<MatrixXd> qr_;  // unblocked: no temporaries
  MatrixXd Mt_, R_;
  TriangularSingularValues sv_;
  VectorXd s_;
};

}  // namespace hqp
