// Non-negative least squares with an updated Cholesky factor; see nnls.hpp.
#include "solver/nnls.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hqp {

namespace {
// a column whose part orthogonal to the passive columns is at most 1e-10 of its norm is
// rejected as dependent
constexpr double kDependent = 1e-10;
}  // namespace

void Nnls::reserve(Index m, Index n) {
  Q_.reserve(m, m);
  R_.reserve(m, m);
  qtb_.reserve(m);
  res_.reserve(m);
  col_.reserve(m);
  x_.reserve(n);
  z_.reserve(n);
  w_.reserve(n);
  in_.reserve(n);
  idx_.reserve(n);
  skip_.reserve(n);
}

void Nnls::rotate(Index i, Index k, double c, double s, Index first_col) {
  // rows i, k of Q^T A[:, P] (R from first_col on), of Q^T b and of Q^T (columns of Q)
  MapM R_ = this->R_.mat();
  MapV qtb_ = this->qtb_.vec();
  MapM Q_ = this->Q_.mat();
  for (Index col = first_col; col < np_; ++col) {
    const double t1 = R_(i, col), t2 = R_(k, col);
    R_(i, col) = c * t1 + s * t2;
    R_(k, col) = -s * t1 + c * t2;
  }
  const double b1 = qtb_(i), b2 = qtb_(k);
  qtb_(i) = c * b1 + s * b2;
  qtb_(k) = -s * b1 + c * b2;
  auto qi = Q_.col(i), qk = Q_.col(k);
  for (Index r = 0; r < m_; ++r) {
    const double t1 = qi(r), t2 = qk(r);
    qi(r) = c * t1 + s * t2;
    qk(r) = -s * t1 + c * t2;
  }
}

bool Nnls::add(const CMatRef& A, Index j) {
  const Index np = np_;
  if (np >= m_) return false;
  MapV col_ = this->col_.vec(m_);
  col_.noalias() = Q_.mat().transpose() * A.col(j);
  const double anorm = A.col(j).norm();
  const double rest = col_.tail(m_ - np).norm();
  if (!(anorm > 0.0) || rest <= kDependent * anorm) return false;
  // rotate col_'s entries below np into entry np, from the bottom up
  for (Index i = m_ - 1; i > np; --i) {
    const double a = col_(i - 1), b = col_(i);
    if (b == 0.0) continue;
    const double r = std::hypot(a, b);
    const double c = a / r, s = b / r;
    col_(i - 1) = r;
    col_(i) = 0.0;
    rotate(i - 1, i, c, s, np);  // R has no entries below row np-1 yet: only Q, Q^T b move
  }
  MapM R_ = this->R_.mat();
  R_.col(np).head(np + 1) = col_.head(np + 1);
  R_.col(np).segment(np + 1, m_ - np - 1).setZero();
  idx_.vec()(np) = int(j);
  ++np_;
  return true;
}

void Nnls::remove(Index q) {
  const Index np = np_;
  MapM R_ = this->R_.mat();
  MapI idx_ = this->idx_.vec();
  // drop column q; the columns after it shift left, leaving one subdiagonal entry each,
  // which rotations of neighbouring rows remove
  for (Index k = q; k + 1 < np; ++k) {
    R_.col(k).head(k + 2) = R_.col(k + 1).head(k + 2);
    idx_(k) = idx_(k + 1);
  }
  --np_;
  for (Index k = q; k < np_; ++k) {
    const double a = R_(k, k), b = R_(k + 1, k);
    if (b == 0.0) continue;
    const double r = std::hypot(a, b);
    rotate(k, k + 1, a / r, b / r, k);
    R_(k + 1, k) = 0.0;
  }
}

void Nnls::solve_passive() {
  const Index np = np_;
  MapV z_ = this->z_.vec();
  z_.setZero();
  if (!np) return;
  MapV col_ = this->col_.vec(np);
  col_ = qtb_.vec().head(np);
  const MapI idx_ = this->idx_.vec();
  R_.mat().topLeftCorner(np, np).triangularView<Eigen::Upper>().solveInPlace(col_);
  for (Index a = 0; a < np; ++a) z_(idx_(a)) = col_(a);
}

double Nnls::update_residual(const CMatRef& A, const CVecRef& b) {
  MapV res_ = this->res_.vec();
  res_.noalias() = b - A * x_.vec();
  residual_ = res_.norm();
  return residual_;
}

bool Nnls::solve(const CMatRef& A, const CVecRef& b, double res_tol, int max_outer,
                 const CMapI* warm) {
  const Index m = A.rows(), n = A.cols();
  n_ = n;
  m_ = m;
  np_ = 0;
  steps_ = 0;
  Q_.mat(m, m).setIdentity();
  R_.mat(m, m);
  qtb_.vec(m) = b;
  MapV x_ = this->x_.vec(n);
  x_.setZero();
  MapV z_ = this->z_.vec(n);
  MapV w_ = this->w_.vec(n);
  const MapV res_ = this->res_.vec(m);
  MapI in_ = this->in_.vec(n);
  in_.setZero();
  const MapI idx_ = this->idx_.vec(n);
  MapI skip_ = this->skip_.vec(n);
  skip_.setZero();
  const double eps = std::numeric_limits<double>::epsilon();
  const double top = n && m ? A.cwiseAbs().colwise().sum().maxCoeff() : 0.0;
  const double tol = 10.0 * double(std::max(m, n)) * eps * top;
  auto remove_nonpositive = [&]() {
    // drop every passive column at or below the tolerance (Lawson-Hanson's step 11)
    for (Index a = np_ - 1; a >= 0; --a) {
      const Index j = idx_(a);
      if (x_(j) <= tol) {
        in_(j) = 0;
        x_(j) = 0.0;
        remove(a);
      }
    }
  };
  if (warm != nullptr && warm->size() == n) {
    // warm start: the given columns as far as independent, then pruned until the least
    // squares point on them is positive (Lawson-Hanson's invariant holds from there on)
    for (Index j = 0; j < n; ++j) {
      if ((*warm)(j) && add(A, j)) in_(j) = 1;
    }
    for (int pass = 0; np_ > 0 && pass <= int(n); ++pass) {
      solve_passive();
      bool positive = true;
      for (Index a = 0; a < np_; ++a) positive = positive && z_(idx_(a)) > tol;
      if (positive) {
        x_ = z_;
        break;
      }
      for (Index a = np_ - 1; a >= 0; --a) {
        const Index j = idx_(a);
        if (z_(j) <= tol) {
          in_(j) = 0;
          remove(a);
        }
      }
      if (np_ == 0) x_.setZero();
    }
  }
  for (int outer = 0; outer < max_outer; ++outer) {
    if (update_residual(A, b) <= res_tol) return true;
    w_.noalias() = A.transpose() * res_;
    Index jmax = -1;
    double wmax = tol;
    for (Index j = 0; j < n; ++j) {
      if (!in_(j) && !skip_(j) && w_(j) > wmax) {
        wmax = w_(j);
        jmax = j;
      }
    }
    if (jmax < 0) break;
    ++steps_;
    if (!add(A, jmax)) {
      skip_(jmax) = 1;
      continue;
    }
    in_(jmax) = 1;
    solve_passive();
    if (z_(jmax) <= 0.0) {
      // the entering column would not move: reject it for this step (Lawson-Hanson)
      in_(jmax) = 0;
      remove(np_ - 1);
      skip_(jmax) = 1;
      continue;
    }
    skip_.setZero();
    for (int inner = 0; inner < 3 * int(n) + 3; ++inner) {
      double alpha = 2.0;
      for (Index a = 0; a < np_; ++a) {
        const Index j = idx_(a);
        if (z_(j) <= 0.0) alpha = std::min(alpha, x_(j) / (x_(j) - z_(j)));
      }
      if (alpha > 1.0) break;
      for (Index a = 0; a < np_; ++a) {
        const Index j = idx_(a);
        x_(j) += alpha * (z_(j) - x_(j));
      }
      remove_nonpositive();
      solve_passive();
    }
    for (Index a = 0; a < np_; ++a) x_(idx_(a)) = z_(idx_(a));
  }
  return update_residual(A, b) <= res_tol;
}

}  // namespace hqp
