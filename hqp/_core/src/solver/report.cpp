#include "solver/report.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hqp {

namespace {

// dst (m, n) = [rows a0..a0+na of A; rows c0..c0+nc of C whose state is > 0] / scale.
MapM stack_rows(const MatrixXd& A, Index a0, Index na, const MatrixXd& C, Index c0, Index nc,
                const IVec& state, double scale, WorkM& dst) {
  Index m = na;
  for (Index i = 0; i < nc; ++i) m += state(c0 + i) > 0 ? 1 : 0;
  MapM out = dst.mat(m, A.cols());
  out.topRows(na) = A.middleRows(a0, na) / scale;
  Index r = na;
  for (Index i = 0; i < nc; ++i) {
    if (state(c0 + i) > 0) out.row(r++) = C.row(c0 + i) / scale;
  }
  return out;
}

}  // namespace

void Report::reserve(Index tasks, Index levels, Index rows_max, Index n) {
  n_ = n;
  sigma_.setConstant(tasks, std::numeric_limits<double>::quiet_NaN());
  status_.setConstant(tasks, -1);
  yields_.setConstant(tasks, -2);
  guess_.setConstant(tasks, -3);
  store_.resize(std::size_t(std::max<Index>(levels, 1)));
  for (WorkM& z : store_) z.reserve(n, n);
  base_of_.assign(std::size_t(std::max<Index>(levels, 1)), -1);
  rows_max = std::max<Index>(rows_max, 1);
  M_.reserve(rows_max, n);
  P_.reserve(rows_max, n);
  r0_.reserve(rows_max);
  rp_.reserve(rows_max);
  ws_.reserve(1);
  support_.reserve(rows_max);
  null_qr_.reserve(rows_max, n);
  reach_qr_.reserve(rows_max, n);
  sv_.reserve(rows_max, n);
}

CMapM Report::basis(int j) const {
  const int s = j < 0 ? -1 : base_of_[std::size_t(j)];
  if (s < 0) return CMapM(nullptr, n_, n_);  // the identity: callers test s < 0 first
  const WorkM& z = store_[std::size_t(s)];
  return CMapM(const_cast<WorkM&>(z).data(), n_, z.cols());
}

void Report::project(const CMatRef& M, int j, MapM out) const {
  const WorkM& z = store_[std::size_t(base_of_[std::size_t(j)])];
  support_.project(M, CMapM(const_cast<WorkM&>(z).data(), n_, z.cols()), out);
}

void Report::compute(const std::vector<LevelData>& levels,
                     const std::vector<LevelResult>& results,
                     const std::vector<int>& level_index, const std::vector<TaskRows>& tasks,
                     const VectorXd& residuals) {
  const int nb = int(level_index.size());
  sigma_.setConstant(std::numeric_limits<double>::quiet_NaN());
  status_.setConstant(-1);
  yields_.setConstant(-2);
  int above = -1;  // store_ index of Z_{k-1} (-1: the identity)
  int used = 0;    // store_ entries in use
  for (int k = 0; k < nb; ++k) {
    const LevelData& lv = levels[std::size_t(k)];
    const LevelResult& res = results[std::size_t(k)];
    const IVec& state = res.state;
    const Index zcols = above < 0 ? n_ : store_[std::size_t(above)].cols();
    for (std::size_t i = 0; i < tasks.size(); ++i) {
      const TaskRows& t = tasks[i];
      if (t.built != k || t.neq + t.nin == 0) continue;
      double sigma = std::numeric_limits<double>::quiet_NaN();
      if (t.neq > 0 && full_) {
        const MapM M = stack_rows(lv.A, t.eq0, t.neq, lv.C, t.in0, t.nin, state, t.sqrt_w, M_);
        const Index m = M.rows();
        if (m > zcols) {
          sigma = 0.0;
        } else if (above < 0) {
          sigma = sv_.compute(M)(m - 1);
        } else {
          MapM P = P_.mat(m, zcols);
          support_.compute(M);
          project(M, k - 1, P);
          sigma = sv_.compute(P)(m - 1);
        }
      } else if (t.neq > 0) {
        sigma = res.sigma_min;
      }
      sigma_[Index(i)] = sigma;
      int status = 0;
      if (residuals[Index(i)] > tol_) {
        status = 1;
      } else if (t.neq > 0 && std::isfinite(sigma) && sigma < singular_) {
        status = 2;
      }
      status_[Index(i)] = status;
      if (status == 1 && full_) yields_[Index(i)] = yields_to(Index(i), k, t, lv, res, level_index);
    }
    if (!full_ || k + 1 >= nb) continue;
    // Z_k = Z_{k-1} N, N a basis of the null space of the level's rows times Z_{k-1}
    base_of_[std::size_t(k)] = above;
    const MapM M = stack_rows(lv.A, 0, lv.A.rows(), lv.C, 0, lv.C.rows(), state, 1.0, M_);
    if (M.rows() == 0 || zcols == 0) continue;
    if (above < 0) {
      null_qr_.compute_relative(M, 1e-9);
    } else {
      MapM P = P_.mat(M.rows(), zcols);
      support_.compute(M);
      project(M, k - 1, P);
      null_qr_.compute_relative(P, 1e-9);
    }
    if (null_qr_.rank() == 0) continue;
    const CMapM N = null_qr_.null();
    WorkM& next = store_[std::size_t(used)];
    if (above < 0) {
      next.mat(n_, N.cols()) = N;
    } else {
      next.mat(n_, N.cols()).noalias() = basis(k - 1) * N;
    }
    above = used++;
    base_of_[std::size_t(k)] = above;
  }
}

double Report::reachable(int j, double scale) {
  // min_y ||r0 + P y|| for P = M Z_j (m, c): the part of r0 outside the range of P, from
  // the pivoted QR P Pi = Q R: the norm of the last m - rank entries of Q^T r0
  const CMapM M(M_.data(), M_.rows(), M_.cols());
  const CMapV r0(r0_.data(), r0_.size());
  const int s = j < 0 ? -1 : base_of_[std::size_t(j)];
  const Index m = M.rows();
  const Index c = s < 0 ? n_ : store_[std::size_t(s)].cols();
  if (c == 0 || m == 0) return r0.norm();
  MapM P = reach_qr_.input(m, c);
  if (s < 0) {
    P = M;
  } else {
    project(M, j, P);
  }
  reach_qr_.factor();
  const CMapM R = reach_qr_.matrixQR();
  const CMapV tau = reach_qr_.hCoeffs();
  const Index d = std::min(m, c);
  const double top = std::max(std::abs(R(0, 0)), scale) * 1e-9;
  Index rank = 0;
  while (rank < d && std::abs(R(rank, rank)) > top) ++rank;
  MapV rp = rp_.vec(m);
  rp = r0;
  MapV ws = ws_.vec(1);
  for (Index i = 0; i < rank; ++i) {
    rp.tail(m - i).applyHouseholderOnTheLeft(R.col(i).tail(m - i - 1), tau(i), ws.data());
  }
  return rp.tail(m - rank).norm();
}

int Report::yields_to(Index i, int k, const TaskRows& t, const LevelData& lv,
                      const LevelResult& res, const std::vector<int>& level_index) {
  Index m = t.neq;
  for (Index r = 0; r < t.nin; ++r) m += res.violation_in(t.in0 + r) != 0.0 ? 1 : 0;
  MapM M = M_.mat(m, n_);
  MapV r0 = r0_.vec(m);
  M.topRows(t.neq) = lv.A.middleRows(t.eq0, t.neq) / t.sqrt_w;
  r0.head(t.neq) = res.residual_eq.segment(t.eq0, t.neq) / t.sqrt_w;
  Index row = t.neq;
  for (Index r = 0; r < t.nin; ++r) {
    const double v = res.violation_in(t.in0 + r);
    if (v == 0.0) continue;
    M.row(row) = lv.C.row(t.in0 + r) / t.sqrt_w;
    r0(row++) = v / t.sqrt_w;
  }
  const double scale = std::max(1.0, m ? M.cwiseAbs().maxCoeff() : 0.0);
  support_.compute(M);
  auto blocked = [&](int j) { return reachable(j, scale) > tol_; };
  int first = -2;
  const int guess = guess_[i];
  if (guess >= -1 && guess < k) {
    if (blocked(guess) && (guess == -1 || !blocked(guess - 1))) {
      first = guess;
    } else if (guess + 1 < k && !blocked(guess) && blocked(guess + 1)) {
      first = guess + 1;
    }
  }
  if (first == -2) {
    int lo = -1, hi = k;  // the answer lies in [lo, hi]
    while (lo < hi) {
      const int mid = lo + (hi - lo) / 2;
      if (blocked(mid)) {
        hi = mid;
      } else {
        lo = mid + 1;
      }
    }
    first = lo;
  }
  guess_[i] = first;
  if (first == -1) return -1;
  if (first < k) return level_index[std::size_t(first)];
  return t.level;
}

}  // namespace hqp
