// Active-set warm start of one level problem; see active_set.hpp and
// hqp/solver/active_set.py (the reference this code follows step by step).
#include "solver/active_set.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hqp {

namespace {

double max_abs(const CMatRef& M) { return M.size() ? M.cwiseAbs().maxCoeff() : 0.0; }

}  // namespace

void ActiveSetSolver::reserve(Index ma, Index mc, Index p, Index nv, Index n, int max_iter) {
  const Index mr = ma + mc;  // rows of M: the level's equalities and its held inequalities
  M_.reserve(mr, nv);
  MQ_.reserve(mr, nv);
  Kh_.reserve(p, nv);
  zv_.reserve(n);
  d_.reserve(mr);
  rhs_.reserve(mr);
  res_.reserve(mr);
  kh_.reserve(p);
  ksc_.reserve(p);
  gv_.reserve(p);
  mu_.reserve(p);
  cv_.reserve(mc);
  vp_.reserve(nv);
  zr_.reserve(nv);
  t_.reserve(nv);
  grad_.reserve(nv);
  tmp_.reserve(nv);
  held_.reserve(p);
  wp_.reserve(p);
  w_new_.reserve(p);
  dep_g_.reserve(p);
  free_.reserve(p);
  inside_.reserve(p);
  s_new_.reserve(mc);
  seen_.reserve(mc + p, Index(max_iter) + 1);
  kqr_.reserve(p, nv, mr);
  ls_.reserve(mr, nv);
  nnls_.reserve(nv, p);
  nn_A_.reserve(nv, p);
  nn_b_.reserve(nv);
  nn_warm_.reserve(p);
  at_.reserve(p);
  nn_memo_.reserve(p);
}

bool ActiveSetSolver::signed_multipliers(Index nheld, double dtol) {
  // Non-negative least squares: min ||B mu + grad||, mu >= 0, with B = K^T diag(sign) over the
  // held rows at their bound (a dependent held row inside its band, inside_, takes none), warm
  // started from the columns that were positive at the last call on the same carried rows
  const MapM Kh = Kh_.mat();
  const MapI wp = wp_.vec(), held = held_.vec(), inside = inside_.vec();
  const MapV grad = grad_.vec();
  const Index nv = Kh.cols();
  MapI cols = at_.vec(nheld);
  Index ncol = 0;
  for (Index j = 0; j < nheld; ++j) {
    if (!inside(j)) cols(ncol++) = int(j);
  }
  MapM nn_A = nn_A_.mat(nv, ncol);
  for (Index c = 0; c < ncol; ++c) {
    const Index j = cols(c);
    nn_A.col(c) = Kh.row(j).transpose() * (wp(j) > 0 ? 1.0 : -1.0);
  }
  MapV nn_b = nn_b_.vec(nv);
  nn_b = -grad;
  MapI memo = nn_memo_.vec();
  const Index p = memo.size();
  const bool warm = p > 0;
  MapI nn_warm = nn_warm_.vec(ncol);
  const CMapI warm_start(nn_warm.data(), ncol);
  if (warm) {
    for (Index c = 0; c < ncol; ++c) nn_warm(c) = memo(held(cols(c)));
  }
  const double res_tol = dtol * std::max(1.0, std::sqrt(double(grad.size())));
  const bool ok = nnls_.solve(nn_A, nn_b, res_tol, int(50 * ncol), warm ? &warm_start : nullptr);
  if (warm) {
    memo.setZero();
    const CMapI passive = nnls_.passive();
    for (Index c = 0; c < ncol; ++c) memo(held(cols(c))) = passive(c);
  }
  return ok;
}

bool ActiveSetSolver::solve(const LevelRows& L, const CarriedRows& K, IVecRef s, IVecRef w,
                            double rank_tol, double scale, int max_iter, const double* ref_ptr,
                            VecRef v) {
  const Index nv = L.A.cols();
  const Index ma = L.A.rows();
  const Index mc = L.C.rows();
  const Index p = K.G.rows();
  if (nn_memo_.size() != p) nn_memo_.vec(p).setZero();
  const CMapV ref(ref_ptr, ref_ptr ? nv : 0);
  const bool has_ref = ref_ptr != nullptr;
  // a stale guess may hold a row at a bound that is now infinite: release it
  for (Index i = 0; i < mc; ++i) {
    if ((s(i) > 0 && !std::isfinite(L.up(i))) || (s(i) < 0 && !std::isfinite(L.lo(i)))) s(i) = 0;
  }
  for (Index i = 0; i < p; ++i) {
    if ((w(i) > 0 && !std::isfinite(K.gu(i))) || (w(i) < 0 && !std::isfinite(K.gl(i)))) w(i) = 0;
  }
  // the guesses tried, one column each: [s; w]
  Eigen::Map<Eigen::MatrixXi> seen = seen_.mat(mc + p, Index(max_iter) + 1);
  int n_seen = 0;
  for (int it = 0; it <= max_iter; ++it) {
    bool cycled = false;
    for (int j = 0; j < n_seen; ++j) {
      if (seen.col(j).head(mc) == s && seen.col(j).tail(p) == w) {
        cycled = true;
        break;
      }
    }
    if (cycled) break;
    seen.col(n_seen).head(mc) = s;
    seen.col(n_seen).tail(p) = w;
    ++n_seen;
    // stacked least-squares rows M v ~ d
    Index nsel = 0;
    for (Index i = 0; i < mc; ++i) nsel += (s(i) != 0);
    MapM M = M_.mat(ma + nsel, nv);
    MapV d = d_.vec(ma + nsel);
    if (ma) {
      M.topRows(ma) = L.A;
      d.head(ma) = L.b;
    }
    for (Index i = 0, j = ma; i < mc; ++i) {
      if (s(i)) {
        M.row(j) = L.C.row(i);
        d(j) = s(i) > 0 ? L.up(i) : L.lo(i);
        ++j;
      }
    }
    const Index mrows = M.rows();
    // held carried rows K v = k
    Index nheld = 0;
    for (Index i = 0; i < p; ++i) nheld += (w(i) != 0);
    MapI held = held_.vec(nheld);
    MapI wp = wp_.vec(nheld);
    for (Index i = 0, j = 0; i < p; ++i) {
      if (w(i)) {
        held(j) = int(i);
        wp(j) = w(i) > 0;
        ++j;
      }
    }
    Index rk = 0;
    Index ndep = 0;
    if (nheld) {
      MapM Kh = Kh_.mat(nheld, nv);
      MapV kh = kh_.vec(nheld);
      MapV ksc = ksc_.vec(nheld);
      for (Index j = 0; j < nheld; ++j) {
        if (K.Z)
          Kh.row(j).noalias() = K.G.row(held(j)) * K.Z->mat();
        else
          Kh.row(j) = K.G.row(held(j));
        kh(j) = wp(j) ? K.gu(held(j)) : K.gl(held(j));
        ksc(j) = wp(j) ? K.gus(held(j)) : K.gls(held(j));
      }
      kqr_.compute_relative(Kh, rank_tol);
      rk = kqr_.rank();
      MapV vp = vp_.vec(nv);
      kqr_.particular(kh, vp);
      ndep = nheld - rk;
      MapI dep_g = dep_g_.vec(ndep);
      for (Index j = 0; j < ndep; ++j) dep_g(j) = held(kqr_.pivot(rk + j));
      const Index nf = nv - rk;
      // Q = [Q1 Q2] of the held rows' QR, applied as reflectors (never formed)
      if (mrows && nf > 0) {
        MapM MQ = MQ_.mat(mrows, nv);
        MQ = M;
        kqr_.apply_q_right(MQ);  // M Q; its last nf columns are M Q2
        MapV rhs = rhs_.vec(mrows);
        rhs = d;
        rhs.noalias() -= M * vp;
        MapV t = t_.vec(nf);
        if (!has_ref) {
          ls_.solve(MQ.rightCols(nf), rhs, rank_tol, scale, t);
        } else {
          MapV tmp = tmp_.vec(nv);
          tmp = ref;
          kqr_.apply_qt(tmp);
          MapV zr = zr_.vec(nf);
          zr = tmp.tail(nf);
          rhs.noalias() -= MQ.rightCols(nf) * zr;
          ls_.solve(MQ.rightCols(nf), rhs, rank_tol, scale, t);
          t += zr;
        }
        MapV tmp = tmp_.vec(nv);
        tmp.head(rk).setZero();
        tmp.tail(nf) = t;
        kqr_.apply_q(tmp);
        v = vp + tmp;
      } else if (nf > 0 && has_ref) {
        MapV tmp = tmp_.vec(nv);
        tmp = ref;
        kqr_.apply_qt(tmp);
        tmp.head(rk).setZero();
        kqr_.apply_q(tmp);
        v = vp + tmp;
      } else {
        v = vp;
      }
    } else if (mrows) {
      if (!has_ref) {
        ls_.solve(M, d, rank_tol, scale, v);
      } else {
        MapV rhs = rhs_.vec(mrows);
        rhs = d;
        rhs.noalias() -= M * ref;
        MapV t = t_.vec(nv);
        ls_.solve(M, rhs, rank_tol, scale, t);
        v = ref + t;
      }
    } else {
      if (!has_ref)
        v.setZero();
      else
        v = ref;
    }
    if (!v.allFinite()) break;
    // primal checks and the next guess
    bool ok = true;
    MapI s_new = s_new_.vec(mc);
    s_new = s;
    if (mc) {
      MapV cv = cv_.vec(mc);
      cv.noalias() = L.C * v;
      for (Index i = 0; i < mc; ++i) {
        const double tl = kFeasTol * L.los(i), tu = kFeasTol * L.ups(i);
        const bool out_up = cv(i) > L.up(i) + tu;
        const bool out_lo = cv(i) < L.lo(i) - tl;
        const bool bad = s(i) == 0 ? (out_up || out_lo)
                                   : (s(i) > 0 ? cv(i) < L.up(i) - tu : cv(i) > L.lo(i) + tl);
        if (bad) {
          ok = false;
          s_new(i) = int(out_up) - int(out_lo);
        }
      }
    }
    MapI w_new = w_new_.vec(p);
    w_new = w;
    if (p) {
      MapV gv = gv_.vec(p);
      if (K.Z) {
        const CMapM Z = K.Z->mat();
        MapV zv = zv_.vec(Z.rows());
        zv.noalias() = Z * v;
        gv.noalias() = K.G * zv;
      } else {
        gv.noalias() = K.G * v;
      }
      MapI free = free_.vec(p);
      for (Index i = 0; i < p; ++i) free(i) = (w(i) == 0);
      for (Index j = 0; j < ndep; ++j) free(dep_g_.vec()(j)) = 1;
      bool any_change = false;
      for (Index i = 0; i < p; ++i) {
        const bool over = gv(i) > K.gu(i) + kFeasTol * K.gus(i);
        const bool under = gv(i) < K.gl(i) - kFeasTol * K.gls(i);
        if ((over || under) && free(i)) {
          any_change = true;
          w_new(i) = int(over) - int(under);
        }
      }
      if (rk && nheld) {
        MapV grad = grad_.vec(nv);
        MapV res = res_.vec(mrows);
        if (mrows) {
          res.noalias() = M * v;
          res -= d;
          grad.noalias() = M.transpose() * res;
        } else {
          grad.setZero();
        }
        MapV tmp = tmp_.vec(nv);
        tmp = -grad;
        kqr_.apply_qt(tmp);  // -(Q^T grad); its first rk entries are -(Q1^T grad)
        MapV mu = mu_.vec(nheld);
        kqr_.multipliers(tmp.head(rk), mu);
        const double dtol =
            M.size() ? kDualTol * std::max(1.0, max_abs(M) * std::max(1.0, d.cwiseAbs().maxCoeff()))
                     : kDualTol;
        bool bad_mu = false;
        for (Index j = 0; j < nheld; ++j) {
          if (wp(j) ? mu(j) < -dtol : mu(j) > dtol) bad_mu = true;
        }
        // a dependent held row further than kAtBoundTol from its bound is inactive at v
        MapI inside = inside_.vec(nheld);
        inside.setZero();
        for (Index j = 0; j < ndep; ++j) {
          const Index jj = kqr_.pivot(rk + j);
          const Index i = held(jj);
          const double k = wp(jj) ? K.gu(i) : K.gl(i);
          const double ks = wp(jj) ? K.gus(i) : K.gls(i);
          if (std::abs(gv(i) - k) > kAtBoundTol * ks) inside(jj) = 1;
        }
        if (bad_mu && !(rk < nheld && signed_multipliers(nheld, dtol))) {
          any_change = true;
          // release the rows of wrong-sign multipliers (mu_ is the triangular solve's) and
          // the inactive dependent rows
          for (Index j = 0; j < nheld; ++j) {
            if ((wp(j) ? mu(j) < -dtol : mu(j) > dtol) || inside(j)) w_new(held(j)) = 0;
          }
        }
      }
      if (any_change) ok = false;
    }
    if (ok) return true;
    s = s_new;
    w = w_new;
  }
  return false;
}

Index ActiveSetSolver::absorbed(const CVecRef& v, IVecRef absorbed) {
  absorbed.setZero();
  const Index nheld = held_.size();
  if (nheld == 0) return 0;
  // the last guess's rows (solve() returned on it): M v ~ d and the held rows Kh
  const MapM M = M_.mat();
  const MapV d = d_.vec();
  const MapM Kh = Kh_.mat();
  const MapI wp = wp_.vec(), held = held_.vec();
  const Index nv = Kh.cols();
  MapV grad = grad_.vec(nv);
  if (M.rows()) {
    MapV res = res_.vec(M.rows());
    res.noalias() = M * v;
    res -= d;
    grad.noalias() = M.transpose() * res;
  } else {
    grad.setZero();
  }
  const double scale =
      M.size() ? std::max(1.0, max_abs(M) * std::max(1.0, d.cwiseAbs().maxCoeff())) : 1.0;
  // a held row dependent on the others is only kept within its bounds (no multiplier):
  // only the rows at their bound enter the dual system (their positions in at_)
  const MapV kh = kh_.vec(), ksc = ksc_.vec();
  MapI at = at_.vec(nheld);
  Index nat = 0;
  for (Index j = 0; j < nheld; ++j) {
    if (std::abs(Kh.row(j).dot(v) - kh(j)) <= kAtBoundTol * ksc(j)) at(nat++) = int(j);
  }
  if (nat == 0) return 0;
  MapM nn_A = nn_A_.mat(nv, nat);
  for (Index c = 0; c < nat; ++c) {
    const Index j = at(c);
    nn_A.col(c) = Kh.row(j).transpose() * (wp(j) ? 1.0 : -1.0);
  }
  MapV nn_b = nn_b_.vec(nv);
  nn_b = -grad;
  nnls_.solve(nn_A, nn_b, -1.0, int(50 * nat));  // cold, to the end (SciPy's nnls)
  if (nnls_.residual() > kDualTol * scale * std::max(1.0, std::sqrt(double(nv)))) return -1;
  const CMapV mu = nnls_.x();
  Index count = 0;
  for (Index c = 0; c < nat; ++c) {
    if (mu(c) > kAbsorbTol * scale) {
      absorbed(held(at(c))) = 1;
      ++count;
    }
  }
  return count;
}

void guess_from_point(const double* cv, const CVecRef& lo, const CVecRef& up,
                      const CVecRef& los, const CVecRef& ups, const double* gv,
                      const CVecRef& gl, const CVecRef& gu, const CVecRef& gls,
                      const CVecRef& gus, double active_tol, IVecRef s, IVecRef w) {
  const Index mc = cv ? s.size() : 0;
  for (Index i = 0; i < mc; ++i) {
    const double c = cv[i];
    const bool hi = c >= up(i) - active_tol * ups(i);
    const bool lw = c <= lo(i) + active_tol * los(i);
    s(i) = int(hi) - int(lw);
    if (hi && lw) s(i) = c >= 0.5 * (lo(i) + up(i)) ? 1 : -1;
  }
  const Index p = gv ? w.size() : 0;
  for (Index i = 0; i < p; ++i) {
    const double g = gv[i];
    const bool hi = g >= gu(i) - active_tol * gus(i);
    const bool lw = g <= gl(i) + active_tol * gls(i);
    w(i) = int(hi) - int(lw);
    if (hi && lw) w(i) = g >= 0.5 * (gl(i) + gu(i)) ? 1 : -1;
  }
}

}  // namespace hqp
