// DAQP calls of the native solver; see qp.hpp.
#include "solver/qp.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>

#include <proxsuite/proxqp/dense/dense.hpp>

extern "C" {
#include "api.h"
}

namespace hqp {

namespace {

constexpr double kDaqpInf = 1e30;
constexpr double kMargins[] = {0.0, 1e-9, 1e-7};  // bounds as given, then relaxed
constexpr int kRelaxSticky = 20;
constexpr double kEpsProx[] = {1e-6, 1e-4, 1e-2, 1.0, -1.0};
constexpr double kPrimalTol[] = {1e-10, 1e-8};
// a quick solve tries the first eps_prox only (hqp.solver.backends.daqp.QUICK_ATTEMPTS)
constexpr int kEpsQuick = 1;
// the statistics' layout is these tables' (qp_stats indexes attempts by their positions)
static_assert(std::size(kMargins) == QPStats::kMargins && std::size(kPrimalTol) == QPStats::kTols &&
              std::size(kEpsProx) == QPStats::kEps && kEpsQuick <= QPStats::kEps);
constexpr int kProxMaxOuter = 100;
constexpr int kProxMaxInner = 100;

double bound_scale(double b) { return std::isfinite(b) ? std::max(1.0, std::abs(b)) : 1.0; }

struct AtomicStats {
  std::atomic<long long> calls[QPStats::kSlots];
  std::atomic<long long> successes[QPStats::kSlots];
  std::atomic<long long> nanoseconds[QPStats::kSlots];
  std::atomic<long long> iterations[QPStats::kSlots];
  std::atomic<long long> failures[QPStats::kFlags];
};
AtomicStats g_stats{};

void count(int attempt, bool ok, std::chrono::steady_clock::time_point t0, long long iterations,
           int flag) {
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                      std::chrono::steady_clock::now() - t0).count();
  g_stats.calls[attempt].fetch_add(1, std::memory_order_relaxed);
  if (ok) g_stats.successes[attempt].fetch_add(1, std::memory_order_relaxed);
  g_stats.nanoseconds[attempt].fetch_add(ns, std::memory_order_relaxed);
  g_stats.iterations[attempt].fetch_add(iterations, std::memory_order_relaxed);
  if (!ok && attempt < QPStats::kAttempts) {  // (a DAQP call's exit flag)
    const int k = flag >= 1 ? 0 : std::min(-flag, QPStats::kFlags - 1);
    g_stats.failures[k].fetch_add(1, std::memory_order_relaxed);
  }
}

}  // namespace

QPStats qp_stats() {
  QPStats out{};
  for (int i = 0; i < QPStats::kSlots; ++i) {
    out.calls[i] = g_stats.calls[i].load(std::memory_order_relaxed);
    out.successes[i] = g_stats.successes[i].load(std::memory_order_relaxed);
    out.nanoseconds[i] = g_stats.nanoseconds[i].load(std::memory_order_relaxed);
    out.iterations[i] = g_stats.iterations[i].load(std::memory_order_relaxed);
  }
  for (int i = 0; i < QPStats::kFlags; ++i)
    out.failures[i] = g_stats.failures[i].load(std::memory_order_relaxed);
  return out;
}

void reset_qp_stats() {
  for (int i = 0; i < QPStats::kSlots; ++i) {
    g_stats.calls[i].store(0, std::memory_order_relaxed);
    g_stats.successes[i].store(0, std::memory_order_relaxed);
    g_stats.nanoseconds[i].store(0, std::memory_order_relaxed);
    g_stats.iterations[i].store(0, std::memory_order_relaxed);
  }
  for (int i = 0; i < QPStats::kFlags; ++i) g_stats.failures[i].store(0, std::memory_order_relaxed);
}

void PrimalQP::reserve(Index n, Index m) {
  // (the working set may hold up to m rows: rows dependent on it to rounding can enter)
  wqr_.reserve(m, n);
  ls_.reserve(n, n);
  cw_.reserve(m, n);
  z_.reserve(n, n);
  hz_.reserve(n, n);
  hr_.reserve(n, n);
  gr_.reserve(n);
  u_.reserve(n);
  res_.reserve(n);
  p_.reserve(n);
  grad_.reserve(n);
  cp_.reserve(m);
  cv_.reserve(m);
  t_.reserve(n);
  nu_.reserve(m);
  rn_.reserve(m);
  work_.reserve(m);
  side_.reserve(m);
}

bool PrimalQP::solve(const CRowMatRef& H, const CVecRef& g, const CRowMatRef& C,
                     const CVecRef& lo, const CVecRef& up, VecRef v, int max_iter) {
  constexpr double kInfBound = 1e20;  // beyond it a bound is absent (DAQP's 1e30, the callers' inf)
  constexpr double kStepTol = 1e-12;  // a step this small (relative to v) is no step
  constexpr double kRankTol = 1e-10;  // the reduced Newton system's rank cut
  constexpr double kDualTol = 1e-9;   // multipliers of W, relative to |H v + g|
  const Index n = H.rows(), m = C.rows();
  iterations_ = 0;
  MapI side = side_.vec(m);
  side.setZero();
  MapI work = work_.vec(m);
  Index k = 0;
  MapV rn = rn_.vec(m);
  for (Index i = 0; i < m; ++i) rn(i) = C.row(i).norm();
  MapV grad = grad_.vec(n), p = p_.vec(n), cp = cp_.vec(m), cv = cv_.vec(m);
  Index stalled = 0;  // working-set changes since the last step of positive length
  for (int it = 0; it < max_iter; ++it) {
    grad.noalias() = H * v;
    grad += g;
    // the null space of the working rows
    Index rank = 0;
    if (k) {
      MapM Cw = cw_.mat(k, n);
      for (Index j = 0; j < k; ++j) Cw.row(j) = C.row(work(j));
      wqr_.compute_relative(Cw, 1e-12);
      rank = wqr_.rank();
    }
    const Index nz = n - rank;
    bool ray = false;
    p.setZero();
    if (nz) {
      MapM Z = z_.mat(n, nz);
      if (k)
        Z = wqr_.null();
      else
        Z.setIdentity();
      MapM HZ = hz_.mat(n, nz), Hr = hr_.mat(nz, nz);
      HZ.noalias() = H * Z;
      Hr.noalias() = Z.transpose() * HZ;
      MapV gr = gr_.vec(nz), u = u_.vec(nz), res = res_.vec(nz);
      gr.noalias() = Z.transpose() * grad;
      MapV rhs = t_.vec(nz);
      rhs = -gr;
      ls_.solve(Hr, rhs, kRankTol, 0.0, u);
      res.noalias() = Hr * u;
      res += gr;
      if (res.norm() > 1e-9 * std::max(1.0, gr.norm())) {
        // a part of the reduced gradient out of the reduced Hessian's range: descent at
        // zero curvature along it (bounded by a row, or the problem is unbounded)
        ray = true;
        u = -res;
      }
      p.noalias() = Z * u;
    }
    const double vmax = v.size() ? v.cwiseAbs().maxCoeff() : 0.0;
    const double pmax = p.size() ? p.cwiseAbs().maxCoeff() : 0.0;
    if (!ray && pmax <= kStepTol * std::max(1.0, vmax)) {
      if (!k) return true;
      // multipliers nu of C_W^T nu = -grad (nu_j = side_j mu_j, mu_j >= 0 at the optimum)
      MapV t = t_.vec(n);
      t = -grad;
      wqr_.apply_qt(t);
      MapV nu = nu_.vec(k);
      nu.setZero();
      wqr_.multipliers(t.head(rank), nu);
      Index drop = -1;
      const double tol = -kDualTol * std::max(1.0, grad.norm());
      double worst = tol;
      for (Index j = 0; j < k; ++j) {
        const double mu = side(work(j)) * nu(j);
        // the most negative multiplier; after n changes without progress, Bland's rule
        // (the smallest row index) so that degenerate vertices cannot cycle
        if (stalled > n ? (mu < tol && (drop < 0 || work(j) < work(drop))) : mu < worst) {
          worst = mu;
          drop = j;
        }
      }
      if (drop < 0) return true;
      side(work(drop)) = 0;
      for (Index j = drop; j + 1 < k; ++j) work(j) = work(j + 1);
      --k;
      ++iterations_;
      ++stalled;
      continue;
    }
    // ratio test: the first row the step meets (ties: the smallest index)
    cp.noalias() = C * p;
    cv.noalias() = C * v;
    const double pn = p.norm();
    double alpha = ray ? std::numeric_limits<double>::infinity() : 1.0;
    Index block = -1;
    int block_side = 0;
    for (Index i = 0; i < m; ++i) {
      if (side(i)) continue;
      const double eps = kStepTol * rn(i) * pn;
      if (cp(i) > eps && up(i) < kInfBound) {
        const double a = std::max(0.0, (up(i) - cv(i)) / cp(i));
        if (a < alpha) {
          alpha = a;
          block = i;
          block_side = 1;
        }
      } else if (cp(i) < -eps && lo(i) > -kInfBound) {
        const double a = std::max(0.0, (lo(i) - cv(i)) / cp(i));
        if (a < alpha) {
          alpha = a;
          block = i;
          block_side = -1;
        }
      }
    }
    if (!std::isfinite(alpha)) return false;  // unbounded along a ray
    v += alpha * p;
    stalled = alpha > 0.0 ? 0 : stalled + 1;
    if (block >= 0) {
      side(block) = block_side;
      work(k++) = int(block);
      ++iterations_;
    }
  }
  return false;
}

void LevelQP::reserve(Index n, Index m) {
  H_.reserve(n, n);
  A_.reserve(m, n);
  g_.reserve(n);
  v2_.reserve(n);
  lo_.reserve(m);
  up_.reserve(m);
  bu_.reserve(m);
  bl_.reserve(m);
  lam_.reserve(std::max(m, Index(1)));
  keep_.reserve(n);
  sense_.reserve(std::size_t(m));
  primal_.reserve(n, m);
}

bool LevelQP::daqp(int margin_index, int n_eps, VecRef v) {
  const double margin = kMargins[margin_index];
  const int n = int(n_);
  const int m = int(m_);
  MapV bu = bu_.vec(m), bl = bl_.vec(m);
  const MapV lo = lo_.vec(), up = up_.vec();
  for (int i = 0; i < m; ++i) {
    double u = up(i), l = lo(i);
    if (margin > 0.0) {
      u += margin * bound_scale(u);
      l -= margin * bound_scale(l);
    }
    bu(i) = std::min(u, kDaqpInf);
    bl(i) = std::max(l, -kDaqpInf);
  }
  sense_.assign(std::size_t(m), 0);
  MapV lam = lam_.vec(std::max(m, 1));
  for (int it = 0; it < QPStats::kTols; ++it) {
    const double primal_tol = kPrimalTol[it];
    for (int ie = 0; ie < n_eps; ++ie) {
      if (spent()) {
        cut_ = true;
        v.setConstant(std::numeric_limits<double>::quiet_NaN());
        return false;
      }
      const double eps_prox = kEpsProx[ie];
      const auto t0 = std::chrono::steady_clock::now();
      DAQPProblem qp;
      qp.n = n;
      qp.m = m;
      qp.ms = 0;
      qp.H = H_.data();
      qp.f = g_.data();
      qp.A = m ? A_.data() : nullptr;
      qp.bupper = m ? bu.data() : nullptr;
      qp.blower = m ? bl.data() : nullptr;
      qp.sense = m ? sense_.data() : nullptr;
      qp.break_points = nullptr;
      qp.nh = 0;
      qp.problem_type = 0;
      DAQPSettings settings;
      daqp_default_settings(&settings);
      settings.primal_tol = primal_tol;
      settings.dual_tol = 1e-12;
      settings.iter_limit = budget_ ? int(std::min<long long>(2000, *budget_)) : 2000;
      settings.eta_prox = 1e-12;
      settings.eps_prox = eps_prox;
      DAQPResult res;
      res.x = v.data();
      res.lam = lam.data();
      daqp_quadprog(&res, &qp, &settings);
      if (budget_) *budget_ -= res.iter;
      const bool ok = res.exitflag >= 1 && v.allFinite();
      count((margin_index * QPStats::kTols + it) * QPStats::kEps + ie, ok, t0, res.iter,
            res.exitflag);
      if (ok) return true;
    }
  }
  v.setConstant(std::numeric_limits<double>::quiet_NaN());
  return false;
}

bool LevelQP::proxqp(VecRef v) {
  // the last resort: ProxQP (header-only, from the proxsuite wheel), an augmented-Lagrangian
  // method that keeps going on the nearly degenerate feasible sets where DAQP's dual steps
  // report infeasibility (in the Python reference, quadprog plays this part). It allocates
  // its own workspace at each call.
  namespace pq = proxsuite::proxqp;
  const auto t0 = std::chrono::steady_clock::now();
  const Index n = n_, m = m_;
  pq::dense::QP<double> qp(n, 0, m);
  qp.settings.eps_abs = 1e-9;
  qp.settings.eps_rel = 0.0;
  // bounded work: where it converges here it takes about 11 outer and 44 inner iterations
  // (tests/test_solver_native.py's screwgun sequence); where it does not (the thin feasible
  // sets of hand-reach `shared`, issue 17) it ran its 10000 outer iterations for up to
  // 1.35 million inner ones, 18 s in one control step, and returned MAX_ITER all the same
  qp.settings.max_iter = kProxMaxOuter;
  qp.settings.max_iter_in = kProxMaxInner;
  qp.settings.eps_primal_inf = 1e-12;
  qp.settings.eps_dual_inf = 1e-12;
  qp.settings.verbose = false;
  MatrixXd H = RowMap(H_.data(), n, n), C = RowMap(A_.data(), m, n);
  VectorXd g = g_.vec();
  VectorXd lo = lo_.vec().cwiseMax(-1e20), up = up_.vec().cwiseMin(1e20);
  qp.init(H, g, proxsuite::nullopt, proxsuite::nullopt, C, lo, up);
  qp.solve();
  const bool ok =
      qp.results.info.status == pq::QPSolverOutput::PROXQP_SOLVED && qp.results.x.allFinite();
  count(QPStats::kProxQP, ok, t0, qp.results.info.iter, 0);
  if (!ok) return false;
  v = qp.results.x;
  return true;
}

bool LevelQP::solve(const CMatRef& H, const CVecRef& g, const CMatRef& C, const CVecRef& lo,
                    const CVecRef& up, VecRef v, bool quick, const double* start) {
  const int n_eps = quick ? kEpsQuick : QPStats::kEps;
  // normalise the cost: the minimiser does not change, DAQP's tolerances then mean the same
  // thing for levels of any scale
  n_ = H.rows();
  m_ = C.rows();
  const double scale = H.size() ? H.cwiseAbs().maxCoeff() : 0.0;
  H_.vec(n_ * n_);
  RowMap Hr(H_.data(), n_, n_);
  Hr = H;
  MapV gv = g_.vec(n_);
  gv = g;
  if (scale > 0.0 && (scale < 0.1 || scale > 10.0)) {
    Hr /= scale;
    gv /= scale;
  }
  A_.vec(m_ * n_);
  RowMap(A_.data(), m_, n_) = C;
  lo_.vec(m_) = lo;
  up_.vec(m_) = up;
  const bool has_in = C.rows() > 0;
  cut_ = false;
  if (has_in && sticky_ >= 0 && !spent()) {
    const int i = sticky_;
    if (--sticky_left_ <= 0) sticky_ = -1;
    if (daqp(1 + i, n_eps, v)) return true;
    sticky_ = -1;
  }
  bool ok = daqp(0, n_eps, v);
  if (ok || !has_in) return ok;
  bool primal_point = false;  // v2_ holds a feasible PrimalQP iterate (not optimal)
  if (start && !quick) {  // the absorbing pass: the primal method from the feasible point
    const auto t0 = std::chrono::steady_clock::now();
    MapV vp = v2_.vec(n_);
    vp = CMapV(start, n_);
    const RowMap Hn(H_.data(), n_, n_), Cn(A_.data(), m_, n_);
    long long max_iter = 4 * (n_ + m_);
    if (budget_) max_iter = std::min(max_iter, std::max(0LL, *budget_ / kPrimalWork));
    const bool pok = primal_.solve(Hn, g_.vec(), Cn, lo_.vec(), up_.vec(), vp,
                                   int(max_iter)) && vp.allFinite();
    count(QPStats::kPrimal, pok, t0, primal_.iterations(), 0);
    if (budget_) *budget_ -= kPrimalWork * primal_.iterations();
    if (pok) {
      v = vp;
      return true;
    }
    if (spent() && vp.allFinite()) {  // the best point the budget reached: feasible
      v = vp;
      cut_ = true;
      return true;
    }
    primal_point = vp.allFinite();
    if (primal_point) {  // kept aside: the answer if every later attempt fails
      keep_.vec(n_) = vp;
    }
  }
  if (spent()) {
    cut_ = true;
    return false;
  }
  MapV v2 = v2_.vec(n_);
  for (int i = 0; i < QPStats::kMargins - 1; ++i) {
    if ((i && v.allFinite()) || spent()) break;
    if (daqp(1 + i, n_eps, v2)) {
      sticky_ = i;
      sticky_left_ = kRelaxSticky;
      v = v2;
      return true;
    }
    if (!v.allFinite()) v = v2;
  }
  if (spent()) cut_ = true;
  if (!quick && !spent() && !v.allFinite() && proxqp(v2)) {  // (no last resort in a quick solve)
    v = v2;
    return true;
  }
  if (primal_point && !v.allFinite()) {  // every attempt failed: the feasible primal iterate
    v = keep_.vec();
    cut_ = true;
    return true;
  }
  return false;
}

}  // namespace hqp
