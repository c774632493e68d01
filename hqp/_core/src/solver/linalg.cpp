// Small dense factorisations of the native solver; see linalg.hpp.
#include "solver/linalg.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace hqp {

void set_malloc_allowed(bool allowed) {
#ifdef EIGEN_RUNTIME_NO_MALLOC
  Eigen::internal::set_is_malloc_allowed(allowed);
#else
  (void)allowed;
#endif
}

// ---------------------------------------------------------------------------------------
// RowSupport

void RowSupport::compute(const CMatRef& M) {
  const Index m = M.rows(), c = M.cols();
  reserve(m);
  blocks_.clear();
  // first and last nonzero column of each row, column by column (M is column-major)
  MapI first = col_.vec(m);
  MapI last = last_.vec(m);
  first.setConstant(-1);
  last.setConstant(-1);
  for (Index j = 0; j < c; ++j) {
    const double* colj = M.col(j).data();
    for (Index i = 0; i < m; ++i) {
      if (colj[i] != 0.0) {
        if (first(i) < 0) first(i) = int(j);
        last(i) = int(j);
      }
    }
  }
  for (Index i = 0; i < m; ++i) {
    const Index f = first(i), l = last(i);
    const bool single = f >= 0 && f == l;
    if (!blocks_.empty()) {
      Block& b = blocks_.back();
      if (single && b.gather) {
        ++b.nr;
        continue;
      }
      if (!b.gather && !single && f == first(i - 1) && l == last(i - 1)) {
        ++b.nr;
        continue;
      }
    }
    if (single) {
      blocks_.push_back({i, 1, f, 1, true});
    } else {
      blocks_.push_back({i, 1, f < 0 ? 0 : f, f < 0 ? 0 : l - f + 1, false});
    }
  }
}

void RowSupport::project(const CMatRef& M, const CMapM& Z, MapM out) const {
  const Eigen::Map<const IVec> col = col_.vec();
  for (const Block& b : blocks_) {
    if (b.gather) {
      for (Index i = b.r0; i < b.r0 + b.nr; ++i) {
        out.row(i) = M(i, col(i)) * Z.row(col(i));
      }
    } else if (b.nc == 0) {
      out.middleRows(b.r0, b.nr).setZero();
    } else if (b.nc <= 4) {
      // a few columns: scaled rows of Z summed (no kernel set-up for a tiny product)
      for (Index i = b.r0; i < b.r0 + b.nr; ++i) {
        out.row(i) = M(i, b.c0) * Z.row(b.c0);
        for (Index j = b.c0 + 1; j < b.c0 + b.nc; ++j) {
          if (M(i, j) != 0.0) out.row(i) += M(i, j) * Z.row(j);
        }
      }
    } else {
      out.middleRows(b.r0, b.nr).noalias() =
          M.block(b.r0, b.c0, b.nr, b.nc) * Z.middleRows(b.c0, b.nc);
    }
  }
}

// ---------------------------------------------------------------------------------------
// ColPivQR: Eigen 3.4's ColPivHouseholderQR::computeInPlace, on this object's storage

void ColPivQR::reserve(Index rows, Index cols) {
  qr_.reserve(rows, cols);
  hc_.reserve(std::min(rows, cols));
  temp_.reserve(cols + 1);
  nu_.reserve(cols);
  nd_.reserve(cols);
  perm_.reserve(cols);
}

void ColPivQR::factor() {
  MapM qr = qr_.mat();
  const Index rows = qr.rows(), cols = qr.cols();
  const Index size = std::min(rows, cols);
  MapV hc = hc_.vec(size);
  MapV temp = temp_.vec(cols + 1);
  MapV nu = nu_.vec(cols), nd = nd_.vec(cols);
  MapI perm = perm_.vec(cols);
  for (Index k = 0; k < cols; ++k) {
    perm(k) = int(k);
    nd(k) = qr.col(k).norm();
    nu(k) = nd(k);
  }
  if (size == 0) return;
  // (Eigen also counts the nonzero pivots here; the callers decide the rank themselves)
  const double eps = std::numeric_limits<double>::epsilon();
  const double norm_downdate_threshold = std::sqrt(eps);
  for (Index k = 0; k < size; ++k) {
    Index biggest;
    nu.tail(cols - k).maxCoeff(&biggest);
    biggest += k;
    if (k != biggest) {
      qr.col(k).swap(qr.col(biggest));
      std::swap(nu(k), nu(biggest));
      std::swap(nd(k), nd(biggest));
      std::swap(perm(k), perm(biggest));
    }
    double beta;
    qr.col(k).tail(rows - k).makeHouseholderInPlace(hc(k), beta);
    qr(k, k) = beta;
    qr.bottomRightCorner(rows - k, cols - k - 1)
        .applyHouseholderOnTheLeft(qr.col(k).tail(rows - k - 1), hc(k), &temp(k + 1));
    for (Index j = k + 1; j < cols; ++j) {
      if (nu(j) != 0.0) {
        double t = std::abs(qr(k, j)) / nu(j);
        t = (1.0 + t) * (1.0 - t);
        t = t < 0.0 ? 0.0 : t;
        const double t2 = t * Eigen::numext::abs2(nu(j) / nd(j));
        if (t2 <= norm_downdate_threshold) {
          nd(j) = qr.col(j).tail(rows - k - 1).norm();
          nu(j) = nd(j);
        } else {
          nu(j) *= std::sqrt(t);
        }
      }
    }
  }
}

// ---------------------------------------------------------------------------------------
// PivotedQR

void PivotedQR::reserve(Index m, Index r, Index right_rows) {
  const Index d = std::min(m, r);
  qr_.reserve(r, m);
  lqr_.reserve(m, d);
  N_.reserve(r, r);
  Rsq_.reserve(d, m);
  ws_.reserve(1);
  wsn_.reserve(r);
  wsr_.reserve(right_rows);
  z_.reserve(d);
  c_.reserve(m);
  sv_.reserve(d, m);
}

void PivotedQR::factor(const CMatRef& M) {
  m_ = M.rows();
  r_ = M.cols();
  n_ready_ = false;
  MapM Mt = qr_.input(r_, m_);
  Mt.noalias() = M.transpose();
  qr_.factor();  // (for an empty M: the identity permutation)
}

void PivotedQR::compute(const CMatRef& M, double rank_tol, double scale) {
  factor(M);
  rank_ = 0;
  const Index d = std::min(m_, r_);
  if (d == 0) return;
  const CMapM R = qr_.matrixQR();
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
  const CMapM R = qr_.matrixQR();
  const double top = std::abs(R(0, 0));
  for (Index i = 0; i < d; ++i) {
    if (std::abs(R(i, i)) > rank_tol * top) ++rank_;
  }
}

CMapM PivotedQR::null() {
  if (!n_ready_) {
    const Index c = r_ - rank_;
    MapM N = N_.mat(r_, c);
    N.setZero();
    N.bottomRows(c).setIdentity();
    if (m_ && r_) {
      const CMapM QR = qr_.matrixQR();
      const CMapV tau = qr_.hCoeffs();
      MapV wsn = wsn_.vec(c);
      for (Index i = std::min<Index>(rank_, tau.size()) - 1; i >= 0; --i) {
        N.bottomRows(r_ - i).applyHouseholderOnTheLeft(QR.col(i).tail(r_ - i - 1), tau(i),
                                                       wsn.data());
      }
    }
    n_ready_ = true;
  }
  return CMapM(N_.data(), N_.rows(), N_.cols());
}

void PivotedQR::apply_q(VecRef v) {
  if (!m_ || !r_) return;
  const CMapM QR = qr_.matrixQR();
  const CMapV tau = qr_.hCoeffs();
  MapV ws = ws_.vec(1);
  for (Index i = std::min<Index>(rank_, tau.size()) - 1; i >= 0; --i) {
    v.tail(r_ - i).applyHouseholderOnTheLeft(QR.col(i).tail(r_ - i - 1), tau(i), ws.data());
  }
}

void PivotedQR::apply_qt(VecRef v) {
  if (!m_ || !r_) return;
  const CMapM QR = qr_.matrixQR();
  const CMapV tau = qr_.hCoeffs();
  MapV ws = ws_.vec(1);
  for (Index i = 0; i < std::min<Index>(rank_, tau.size()); ++i) {
    v.tail(r_ - i).applyHouseholderOnTheLeft(QR.col(i).tail(r_ - i - 1), tau(i), ws.data());
  }
}

void PivotedQR::apply_q_right(MatRef A) {
  if (!m_ || !r_) return;
  const CMapM QR = qr_.matrixQR();
  const CMapV tau = qr_.hCoeffs();
  MapV wsr = wsr_.vec(A.rows());
  for (Index i = 0; i < std::min<Index>(rank_, tau.size()); ++i) {
    A.rightCols(r_ - i).applyHouseholderOnTheRight(QR.col(i).tail(r_ - i - 1), tau(i),
                                                    wsr.data());
  }
}

void PivotedQR::lstsq(const CVecRef& rhs, VecRef y) {
  const Index k = rank_;
  if (k == 0) {
    y.setZero();
    return;
  }
  const CMapM R = qr_.matrixQR();
  MapV c = c_.vec(m_);
  for (Index i = 0; i < m_; ++i) c(i) = rhs(qr_.perm(i));
  MapV z = z_.vec(k);
  if (m_ == k) {
    // square lower-triangular R11^T: one triangular solve
    z = c.head(k);
    R.topLeftCorner(k, k).transpose().triangularView<Eigen::Lower>().solveInPlace(z);
  } else {
    // more rows than rank: least squares on the (m, k) trapezoid L = R[:k, :]^T, of full
    // column rank k (a second pivoted QR; its reflectors applied by hand, no temporaries)
    MapM L = lqr_.input(m_, k);
    L.noalias() = R.topRows(k).transpose();
    L.triangularView<Eigen::StrictlyUpper>().setZero();
    lqr_.factor();
    const CMapM QR2 = lqr_.matrixQR();
    const CMapV tau = lqr_.hCoeffs();
    MapV ws = ws_.vec(1);
    for (Index i = 0; i < k; ++i) {
      c.tail(m_ - i).applyHouseholderOnTheLeft(QR2.col(i).tail(m_ - i - 1), tau(i), ws.data());
    }
    QR2.topLeftCorner(k, k).triangularView<Eigen::Upper>().solveInPlace(c.head(k));
    for (Index i = 0; i < k; ++i) z(lqr_.perm(i)) = c(i);
  }
  y.head(k) = z;
  y.tail(r_ - k).setZero();
  apply_q(y);
}

void PivotedQR::particular(const CVecRef& kv, VecRef y) {
  const Index k = rank_;
  if (k == 0) {
    y.setZero();
    return;
  }
  MapV z = z_.vec(k);
  for (Index i = 0; i < k; ++i) z(i) = kv(qr_.perm(i));
  qr_.matrixQR().topLeftCorner(k, k).transpose().triangularView<Eigen::Lower>().solveInPlace(z);
  y.head(k) = z;
  y.tail(r_ - k).setZero();
  apply_q(y);
}

void PivotedQR::multipliers(const CVecRef& cv, VecRef mu) {
  const Index k = rank_;
  mu.setZero();
  if (k == 0) return;
  MapV z = z_.vec(k);
  z = cv;
  qr_.matrixQR().topLeftCorner(k, k).triangularView<Eigen::Upper>().solveInPlace(z);
  for (Index i = 0; i < k; ++i) mu(qr_.perm(i)) = z(i);
}

void PivotedQR::singular_values(VecRef s, double rank_tol, double scale) {
  const Index d = std::min(m_, r_);
  if (d == 0) return;
  MapM Rsq = Rsq_.mat(d, m_);
  Rsq = qr_.matrixQR().topRows(d).triangularView<Eigen::Upper>();
  sv_.compute(Rsq, s, rank_tol, scale);
}

// ---------------------------------------------------------------------------------------
// TriangularSingularValues

void TriangularSingularValues::reserve(Index d, Index c) {
  G_.reserve(d, d);
  diag_.reserve(d);
  sub_.reserve(d);
  hc_.reserve(d);
  work_.reserve(d, d);
  pre_.reserve(c, d);
}

bool TriangularSingularValues::eigenvalues(Index d) {
  // Eigen 3.4's SelfAdjointEigenSolver::compute(G, EigenvaluesOnly), on this storage
  MapM mat = G_.mat();
  MapV diag = diag_.vec(d);
  if (d == 1) {
    diag(0) = mat(0, 0);
    return true;
  }
  mat.triangularView<Eigen::StrictlyUpper>().setZero();
  double scale = mat.cwiseAbs().maxCoeff();
  if (scale == 0.0) scale = 1.0;
  mat.triangularView<Eigen::Lower>() /= scale;
  MapV sub = sub_.vec(d - 1);
  MapV hc = hc_.vec(d - 1);
  // (the generic branch of tridiagonalization_inplace(mat, diag, sub, hc, false), whose
  // selector needs a plain matrix type)
  Eigen::internal::tridiagonalization_inplace(mat, hc);
  diag = mat.diagonal();
  sub = mat.diagonal<-1>();
  constexpr int kMaxIterations = Eigen::SelfAdjointEigenSolver<MatrixXd>::m_maxIterations;
  const Eigen::ComputationInfo info =
      Eigen::internal::computeFromTridiagonal_impl(diag, sub, kMaxIterations, false, mat);
  diag *= scale;
  return info == Eigen::Success;
}

void TriangularSingularValues::jacobi(const CMatRef& T, VecRef s) {
  // Eigen 3.4's JacobiSVD<MatrixXd, ColPivHouseholderQRPreconditioner>::compute(T) without
  // U and V, on this storage
  const Index d = T.rows(), c = T.cols();
  const double precision = 2.0 * std::numeric_limits<double>::epsilon();
  const double considerAsZero = (std::numeric_limits<double>::min)();
  double scale = T.cwiseAbs().template maxCoeff<Eigen::PropagateNaN>();
  if (!std::isfinite(scale)) {
    s.setConstant(std::numeric_limits<double>::quiet_NaN());
    return;
  }
  if (scale == 0.0) scale = 1.0;
  MapM W = work_.mat(d, d);
  if (d != c) {
    // the R-SVD step: T^T P = Q R, then the SVD of R[:d, :d]^T (upper triangle)
    MapM At = pre_.input(c, d);
    At.noalias() = T.transpose() / scale;
    pre_.factor();
    W = pre_.matrixQR().topLeftCorner(d, d).transpose().triangularView<Eigen::Lower>();
  } else {
    W = T / scale;
  }
  double maxDiagEntry = W.cwiseAbs().diagonal().maxCoeff();
  bool finished = false;
  while (!finished) {
    finished = true;
    for (Index p = 1; p < d; ++p) {
      for (Index q = 0; q < p; ++q) {
        const double threshold = std::max(considerAsZero, precision * maxDiagEntry);
        if (std::abs(W(p, q)) > threshold || std::abs(W(q, p)) > threshold) {
          finished = false;
          Eigen::JacobiRotation<double> j_left, j_right;
          Eigen::internal::real_2x2_jacobi_svd(W, p, q, &j_left, &j_right);
          W.applyOnTheLeft(p, q, j_left);
          W.applyOnTheRight(p, q, j_right);
          maxDiagEntry = std::max(maxDiagEntry, std::max(std::abs(W(p, p)), std::abs(W(q, q))));
        }
      }
    }
  }
  for (Index i = 0; i < d; ++i) s(i) = std::abs(W(i, i));
  s.head(d) *= scale;
  for (Index i = 0; i < d; ++i) {
    Index pos;
    const double top = s.segment(i, d - i).maxCoeff(&pos);
    if (top == 0.0) break;
    if (pos) std::swap(s(i), s(i + pos));
  }
}

void TriangularSingularValues::compute(const CMatRef& T, VecRef s, double rank_tol,
                                       double scale) {
  const Index d = T.rows();
  if (d == 0) return;
  MapM G = G_.mat(d, d);
  G.noalias() = T * T.transpose();
  const bool ok = eigenvalues(d);
  const MapV lam = diag_.vec();  // ascending
  for (Index i = 0; i < d; ++i) s(i) = std::sqrt(std::max(lam(d - 1 - i), 0.0));
  if (ok && s(d - 1) >= 1e-6 * s(0)) return;
  if (ok && rank_tol > 0.0 && T.cols() == d &&
      T.diagonal().cwiseAbs().minCoeff() <= rank_tol * std::max(s(0), scale)) {
    s(d - 1) = 0.0;
    return;
  }
  jacobi(T, s);
}

// ---------------------------------------------------------------------------------------
// LeastSquares, SingularValues

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

void SingularValues::reserve(Index m, Index r) {
  const Index d = std::min(m, r);
  qr_.reserve(r, m);
  R_.reserve(d, d);
  s_.reserve(m);
  sv_.reserve(d, d);
}

CMapV SingularValues::compute(const CMatRef& M, double rank_tol, double scale) {
  const Index m = M.rows();
  MapV s = s_.vec(m);
  if (m == 0) return CMapV(s.data(), 0);
  MapM Mt = qr_.input(M.cols(), m);
  Mt.noalias() = M.transpose();
  qr_.factor();
  MapM R = R_.mat(m, m);
  R = qr_.matrixQR().topRows(m).triangularView<Eigen::Upper>();
  sv_.compute(R, s, rank_tol, scale);
  return CMapV(s.data(), m);
}

void WeakFilter::reserve(Index m, Index r) {
  G_.reserve(m, m);
  V_.reserve(m, m);
  z_.reserve(r);
  c_.reserve(m);
}

int WeakFilter::apply(const CMatRef& M, VecRef rhs, const CMapM* Z, const CVecRef& x0,
                      const CVecRef& b, double threshold, double rank_tol, double scale) {
  const Index m = M.rows();
  if (m == 0) return 0;
  MapV centred = c_.vec(m);
  if (Z) {
    MapV z = z_.vec(Z->cols());
    z.noalias() = Z->transpose() * x0;
    centred = rhs;
    centred.noalias() += M * z;
  } else {
    centred = b;
  }
  MapM G = G_.mat(m, m);
  MapM V = V_.mat(m, m);
  G.noalias() = M * M.transpose();
  V.setIdentity();
  // cyclic Jacobi: rotate every off-diagonal entry away until none exceeds eps relative to
  // its diagonal pair (high relative accuracy), or is negligible against the whole matrix
  const double eps = std::numeric_limits<double>::epsilon();
  const double top = G.diagonal().cwiseAbs().maxCoeff();
  const double negligible = std::numeric_limits<double>::min() + eps * eps * top;
  for (int sweep = 0; sweep < 64; ++sweep) {
    bool rotated = false;
    for (Index p = 0; p < m; ++p) {
      for (Index q = p + 1; q < m; ++q) {
        const double apq = std::abs(G(q, p));
        if (apq <= negligible || apq <= eps * std::sqrt(std::abs(G(p, p) * G(q, q)))) continue;
        Eigen::JacobiRotation<double> J;
        J.makeJacobi(G, p, q);
        G.applyOnTheLeft(p, q, J.adjoint());
        G.applyOnTheRight(p, q, J);
        V.applyOnTheRight(p, q, J);
        rotated = true;
      }
    }
    if (!rotated) break;
  }
  const double t2 = threshold * threshold;
  const double s_max = std::sqrt(std::max(G.diagonal().maxCoeff(), 0.0));
  const double floor = std::max(rank_tol, kWeakCountFloor) * std::max(s_max, scale);
  int count = 0;
  for (Index i = 0; i < m; ++i) {
    const double lam = std::max(G(i, i), 0.0);
    if (G(i, i) >= t2) continue;
    const double c = V.col(i).dot(centred);
    rhs.noalias() -= ((1.0 - lam / t2) * c) * V.col(i);
    if (lam > floor * floor) ++count;
  }
  return count;
}

}  // namespace hqp
