// Small dense factorisations of the native solver; see linalg.hpp.
#include "solver/linalg.hpp"

#include <algorithm>
#include <cmath>

namespace hqp {

void set_malloc_allowed(bool allowed) {
#ifdef EIGEN_RUNTIME_NO_MALLOC
  Eigen::internal::set_is_malloc_allowed(allowed);
#else
  (void)allowed;
#endif
}

void PivotedQR::factor(const CMatRef& M) {
  m_ = M.rows();
  r_ = M.cols();
  Mt_.resize(r_, m_);
  Mt_.noalias() = M.transpose();
  n_ready_ = false;
  perm_.resize(m_);
  if (m_ == 0 || r_ == 0) {
    for (Index i = 0; i < m_; ++i) perm_(i) = i;
    return;
  }
  qr_.compute(Mt_);
  const auto& P = qr_.colsPermutation().indices();
  for (Index i = 0; i < m_; ++i) perm_(i) = P(i);
}

void PivotedQR::compute(const CMatRef& M, double rank_tol, double scale) {
  factor(M);
  rank_ = 0;
  const Index d = std::min(m_, r_);
  if (d == 0) return;
  const auto& R = qr_.matrixQR();
  const double top = std::max(std::abs(R(0, 0)), scale);
  for (Index i = 0; i < d; ++i) {
    if (std::abs(R(i, i)) > rank_tol * top) ++rank_;
  }
}

void PivotedQR::compute_relative(const CMatRef& M, double rank_tol) {
  factor(M);
  rank_ = 0;
  const Index d = std::min(m_, r_);
  if (d == 0) return;
  const auto& R = qr_.matrixQR();
  const double top = std::abs(R(0, 0));
  for (Index i = 0; i < d; ++i) {
    if (std::abs(R(i, i)) > rank_tol * top) ++rank_;
  }
}

const MatrixXd& PivotedQR::null() {
  if (!n_ready_) {
    const Index c = r_ - rank_;
    N_.resize(r_, c);
    N_.setZero();
    N_.bottomRows(c).setIdentity();
    if (m_ && r_) {
      const auto& QR = qr_.matrixQR();
      const auto& tau = qr_.hCoeffs();
      wsn_.resize(c);
      for (Index i = tau.size() - 1; i >= 0; --i) {
        N_.bottomRows(r_ - i).applyHouseholderOnTheLeft(QR.col(i).tail(r_ - i - 1), tau(i),
                                                        wsn_.data());
      }
    }
    n_ready_ = true;
  }
  return N_;
}

void PivotedQR::apply_q(VecRef v) {
  if (!m_ || !r_) return;
  const auto& QR = qr_.matrixQR();
  const auto& tau = qr_.hCoeffs();
  ws_.resize(1);
  for (Index i = tau.size() - 1; i >= 0; --i) {
    v.tail(r_ - i).applyHouseholderOnTheLeft(QR.col(i).tail(r_ - i - 1), tau(i), ws_.data());
  }
}

void PivotedQR::apply_qt(VecRef v) {
  if (!m_ || !r_) return;
  const auto& QR = qr_.matrixQR();
  const auto& tau = qr_.hCoeffs();
  ws_.resize(1);
  for (Index i = 0; i < tau.size(); ++i) {
    v.tail(r_ - i).applyHouseholderOnTheLeft(QR.col(i).tail(r_ - i - 1), tau(i), ws_.data());
  }
}

void PivotedQR::apply_q_right(MatRef A) {
  if (!m_ || !r_) return;
  const auto& QR = qr_.matrixQR();
  const auto& tau = qr_.hCoeffs();
  wsr_.resize(A.rows());
  for (Index i = 0; i < tau.size(); ++i) {
    A.rightCols(r_ - i).applyHouseholderOnTheRight(QR.col(i).tail(r_ - i - 1), tau(i),
                                                    wsr_.data());
  }
}

void PivotedQR::lstsq(const CVecRef& rhs, VecRef y) {
  const Index k = rank_;
  if (k == 0) {
    y.setZero();
    return;
  }
  const auto& R = qr_.matrixQR();
  c_.resize(m_);
  for (Index i = 0; i < m_; ++i) c_(i) = rhs(perm_(i));
  z_.resize(k);
  if (m_ == k) {
    // square lower-triangular R11^T: one triangular solve
    z_ = c_.head(k);
    R.topLeftCorner(k, k).transpose().triangularView<Eigen::Lower>().solveInPlace(z_);
  } else {
    // more rows than rank: least squares on the (m, k) trapezoid L = R[:k, :]^T, of full
    // column rank k (a second pivoted QR; its reflectors applied by hand, no temporaries)
    L_.resize(m_, k);
    L_.noalias() = R.topRows(k).transpose();
    L_.triangularView<Eigen::StrictlyUpper>().setZero();
    lqr_.compute(L_);
    const auto& QR2 = lqr_.matrixQR();
    const auto& tau = lqr_.hCoeffs();
    ws_.resize(1);
    for (Index i = 0; i < k; ++i) {
      c_.tail(m_ - i).applyHouseholderOnTheLeft(QR2.col(i).tail(m_ - i - 1), tau(i), ws_.data());
    }
    QR2.topLeftCorner(k, k).triangularView<Eigen::Upper>().solveInPlace(c_.head(k));
    const auto& P2 = lqr_.colsPermutation().indices();
    for (Index i = 0; i < k; ++i) z_(P2(i)) = c_(i);
  }
  y.head(k) = z_;
  y.tail(r_ - k).setZero();
  apply_q(y);
}

void PivotedQR::particular(const CVecRef& kv, VecRef y) {
  const Index k = rank_;
  if (k == 0) {
    y.setZero();
    return;
  }
  z_.resize(k);
  for (Index i = 0; i < k; ++i) z_(i) = kv(perm_(i));
  qr_.matrixQR().topLeftCorner(k, k).transpose().triangularView<Eigen::Lower>().solveInPlace(z_);
  y.head(k) = z_;
  y.tail(r_ - k).setZero();
  apply_q(y);
}

void PivotedQR::multipliers(const CVecRef& c, VecRef mu) {
  const Index k = rank_;
  mu.setZero();
  if (k == 0) return;
  z_.resize(k);
  z_ = c;
  qr_.matrixQR().topLeftCorner(k, k).triangularView<Eigen::Upper>().solveInPlace(z_);
  for (Index i = 0; i < k; ++i) mu(perm_(i)) = z_(i);
}

void PivotedQR::singular_values(VecRef s, double rank_tol, double scale) {
  const Index d = std::min(m_, r_);
  if (d == 0) return;
  Rsq_.resize(d, m_);
  Rsq_ = qr_.matrixQR().topRows(d).triangularView<Eigen::Upper>();
  sv_.compute(Rsq_, s, rank_tol, scale);
}

void TriangularSingularValues::compute(const MatrixXd& T, VecRef s, double rank_tol,
                                       double scale) {
  const Index d = T.rows();
  if (d == 0) return;
  G_.resize(d, d);
  G_.noalias() = T * T.transpose();
  eig_.compute(G_, Eigen::EigenvaluesOnly);
  const VectorXd& lam = eig_.eigenvalues();  // ascending
  for (Index i = 0; i < d; ++i) s(i) = std::sqrt(std::max(lam(d - 1 - i), 0.0));
  if (eig_.info() == Eigen::Success && s(d - 1) >= 1e-6 * s(0)) return;
  if (eig_.info() == Eigen::Success && rank_tol > 0.0 && T.cols() == d &&
      T.diagonal().cwiseAbs().minCoeff() <= rank_tol * std::max(s(0), scale)) {
    s(d - 1) = 0.0;
    return;
  }
  {
    svd_.compute(T);
    s = svd_.singularValues();
  }
}

void LeastSquares::solve(const CMatRef& M, const CVecRef& rhs, double rank_tol, double scale,
                         VecRef y) {
  const Index m = M.rows(), r = M.cols();
  if (m == 0 || r == 0) {
    y.setZero();
    return;
  }
  const double top = M.cwiseAbs().maxCoeff();
  if (top == 0.0) {
    y.setZero();
    return;
  }
  qr_.compute(M, rank_tol, scale);
  qr_.lstsq(rhs, y);
}

const VectorXd& SingularValues::compute(const CMatRef& M, double rank_tol, double scale) {
  const Index m = M.rows();
  s_.resize(m);
  if (m == 0) return s_;
  Mt_.resize(M.cols(), m);
  Mt_.noalias() = M.transpose();
  qr_.compute(Mt_);
  R_.resize(m, m);
  R_ = qr_.matrixQR().topRows(m).triangularView<Eigen::Upper>();
  sv_.compute(R_, s_, rank_tol, scale);
  return s_;
}

}  // namespace hqp
