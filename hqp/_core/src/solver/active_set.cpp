// Active-set warm start of one level problem; see active_set.hpp and
// hqp/solver/active_set.py (the reference this code follows step by step).
#include "solver/active_set.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hqp {

namespace {

bool all_finite(const VectorXd& v) { return v.allFinite(); }

double max_abs(const MatrixXd& M) { return M.size() ? M.cwiseAbs().maxCoeff() : 0.0; }

}  // namespace

bool ActiveSetSolver::signed_multipliers(Index nheld, double dtol) {
  // Non-negative least squares: min ||B mu + grad||, mu >= 0, with B = K^T diag(sign), warm
  // started from the columns that were positive at the last call on the same carried rows
  const Index nv = Kh_.cols();
  nn_A_.resize(nv, nheld);
  for (Index j = 0; j < nheld; ++j) {
    nn_A_.col(j) = Kh_.row(j).transpose() * (wp_(j) > 0 ? 1.0 : -1.0);
  }
  nn_b_.resize(nv);
  nn_b_ = -grad_;
  const Index p = nn_memo_.size();
  const bool warm = p > 0;
  if (warm) {
    nn_warm_.resize(nheld);
    for (Index j = 0; j < nheld; ++j) nn_warm_(j) = nn_memo_(held_(j));
  }
  const double res_tol = dtol * std::max(1.0, std::sqrt(double(grad_.size())));
  const bool ok = nnls_.solve(nn_A_, nn_b_, res_tol, int(50 * nheld), warm ? &nn_warm_ : nullptr);
  if (warm) {
    nn_memo_.setZero();
    for (Index j = 0; j < nheld; ++j) nn_memo_(held_(j)) = nnls_.passive()(j);
  }
  return ok;
}

bool ActiveSetSolver::solve(const LevelRows& L, const CarriedRows& K, IVec& s, IVec& w,
                            double rank_tol, double scale, int max_iter, const VectorXd* ref,
                            VectorXd& v) {
  const Index nv = L.A.cols();
  const Index ma = L.A.rows();
  const Index mc = L.C.rows();
  const Index p = K.G.rows();
  if (nn_memo_.size() != p) nn_memo_.setZero(p);
  // a stale guess may hold a row at a bound that is now infinite: release it
  for (Index i = 0; i < mc; ++i) {
    if ((s(i) > 0 && !std::isfinite(L.up(i))) || (s(i) < 0 && !std::isfinite(L.lo(i)))) s(i) = 0;
  }
  for (Index i = 0; i < p; ++i) {
    if ((w(i) > 0 && !std::isfinite(K.gu(i))) || (w(i) < 0 && !std::isfinite(K.gl(i)))) w(i) = 0;
  }
  if (int(seen_s_.size()) < max_iter + 1) {
    seen_s_.resize(max_iter + 1);
    seen_w_.resize(max_iter + 1);
  }
  int n_seen = 0;
  v.resize(nv);
  for (int it = 0; it <= max_iter; ++it) {
    bool cycled = false;
    for (int j = 0; j < n_seen; ++j) {
      if (seen_s_[j].size() == s.size() && seen_w_[j].size() == w.size() && seen_s_[j] == s &&
          seen_w_[j] == w) {
        cycled = true;
        break;
      }
    }
    if (cycled) break;
    seen_s_[n_seen].resize(s.size());
    seen_s_[n_seen] = s;
    seen_w_[n_seen].resize(w.size());
    seen_w_[n_seen] = w;
    ++n_seen;
    // stacked least-squares rows M v ~ d
    Index nsel = 0;
    for (Index i = 0; i < mc; ++i) nsel += (s(i) != 0);
    M_.resize(ma + nsel, nv);
    d_.resize(ma + nsel);
    if (ma) {
      M_.topRows(ma) = L.A;
      d_.head(ma) = L.b;
    }
    for (Index i = 0, j = ma; i < mc; ++i) {
      if (s(i)) {
        M_.row(j) = L.C.row(i);
        d_(j) = s(i) > 0 ? L.up(i) : L.lo(i);
        ++j;
      }
    }
    const Index mrows = M_.rows();
    // held carried rows K v = k
    Index nheld = 0;
    for (Index i = 0; i < p; ++i) nheld += (w(i) != 0);
    held_.resize(nheld);
    wp_.resize(nheld);
    for (Index i = 0, j = 0; i < p; ++i) {
      if (w(i)) {
        held_(j) = int(i);
        wp_(j) = w(i) > 0;
        ++j;
      }
    }
    Index rk = 0;
    dep_g_.resize(0);
    Index ndep = 0;
    if (nheld) {
      Kh_.resize(nheld, nv);
      kh_.resize(nheld);
      for (Index j = 0; j < nheld; ++j) {
        if (K.Z)
          Kh_.row(j).noalias() = K.G.row(held_(j)) * (*K.Z);
        else
          Kh_.row(j) = K.G.row(held_(j));
        kh_(j) = wp_(j) ? K.gu(held_(j)) : K.gl(held_(j));
      }
      kqr_.compute_relative(Kh_, rank_tol);
      rk = kqr_.rank();
      vp_.resize(nv);
      kqr_.particular(kh_, vp_);
      ndep = nheld - rk;
      dep_g_.resize(ndep);
      for (Index j = 0; j < ndep; ++j) dep_g_(j) = held_(kqr_.pivot(rk + j));
      const Index nf = nv - rk;
      // Q = [Q1 Q2] of the held rows' QR, applied as reflectors (never formed)
      if (mrows && nf > 0) {
        MQ_.resize(mrows, nv);
        MQ_ = M_;
        kqr_.apply_q_right(MQ_);  // M Q; its last nf columns are M Q2
        rhs_.resize(mrows);
        rhs_ = d_;
        rhs_.noalias() -= M_ * vp_;
        t_.resize(nf);
        if (ref == nullptr) {
          ls_.solve(MQ_.rightCols(nf), rhs_, rank_tol, scale, t_);
        } else {
          tmp_.resize(nv);
          tmp_ = *ref;
          kqr_.apply_qt(tmp_);
          zr_.resize(nf);
          zr_ = tmp_.tail(nf);
          rhs_.noalias() -= MQ_.rightCols(nf) * zr_;
          ls_.solve(MQ_.rightCols(nf), rhs_, rank_tol, scale, t_);
          t_ += zr_;
        }
        tmp_.resize(nv);
        tmp_.head(rk).setZero();
        tmp_.tail(nf) = t_;
        kqr_.apply_q(tmp_);
        v = vp_ + tmp_;
      } else if (nf > 0 && ref != nullptr) {
        tmp_.resize(nv);
        tmp_ = *ref;
        kqr_.apply_qt(tmp_);
        tmp_.head(rk).setZero();
        kqr_.apply_q(tmp_);
        v = vp_ + tmp_;
      } else {
        v = vp_;
      }
    } else if (mrows) {
      if (ref == nullptr) {
        ls_.solve(M_, d_, rank_tol, scale, v);
      } else {
        rhs_.resize(mrows);
        rhs_ = d_;
        rhs_.noalias() -= M_ * (*ref);
        t_.resize(nv);
        ls_.solve(M_, rhs_, rank_tol, scale, t_);
        v = *ref + t_;
      }
    } else {
      if (ref == nullptr)
        v.setZero();
      else
        v = *ref;
    }
    if (!all_finite(v)) break;
    // primal checks and the next guess
    bool ok = true;
    s_new_.resize(mc);
    s_new_ = s;
    if (mc) {
      cv_.resize(mc);
      cv_.noalias() = L.C * v;
      for (Index i = 0; i < mc; ++i) {
        const double tl = kFeasTol * L.los(i), tu = kFeasTol * L.ups(i);
        const bool out_up = cv_(i) > L.up(i) + tu;
        const bool out_lo = cv_(i) < L.lo(i) - tl;
        const bool bad = s(i) == 0 ? (out_up || out_lo)
                                   : (s(i) > 0 ? cv_(i) < L.up(i) - tu : cv_(i) > L.lo(i) + tl);
        if (bad) {
          ok = false;
          s_new_(i) = int(out_up) - int(out_lo);
        }
      }
    }
    w_new_.resize(p);
    w_new_ = w;
    if (p) {
      gv_.resize(p);
      if (K.Z) {
        zv_.resize(K.Z->rows());
        zv_.noalias() = (*K.Z) * v;
        gv_.noalias() = K.G * zv_;
      } else {
        gv_.noalias() = K.G * v;
      }
      free_.resize(p);
      for (Index i = 0; i < p; ++i) free_(i) = (w(i) == 0);
      for (Index j = 0; j < ndep; ++j) free_(dep_g_(j)) = 1;
      bool any_change = false;
      for (Index i = 0; i < p; ++i) {
        const bool over = gv_(i) > K.gu(i) + kFeasTol * K.gus(i);
        const bool under = gv_(i) < K.gl(i) - kFeasTol * K.gls(i);
        if ((over || under) && free_(i)) {
          any_change = true;
          w_new_(i) = int(over) - int(under);
        }
      }
      if (rk && nheld) {
        grad_.resize(nv);
        res_.resize(mrows);
        if (mrows) {
          res_.noalias() = M_ * v;
          res_ -= d_;
          grad_.noalias() = M_.transpose() * res_;
        } else {
          grad_.setZero();
        }
        tmp_.resize(nv);
        tmp_ = -grad_;
        kqr_.apply_qt(tmp_);  // -(Q^T grad); its first rk entries are -(Q1^T grad)
        mu_.resize(nheld);
        kqr_.multipliers(tmp_.head(rk), mu_);
        const double dtol =
            M_.size() ? kDualTol * std::max(1.0, max_abs(M_) * std::max(1.0, d_.cwiseAbs().maxCoeff()))
                      : kDualTol;
        bool bad_mu = false;
        for (Index j = 0; j < nheld; ++j) {
          if (wp_(j) ? mu_(j) < -dtol : mu_(j) > dtol) bad_mu = true;
        }
        if (bad_mu && !(rk < nheld && signed_multipliers(nheld, dtol))) {
          any_change = true;
          // recompute mu: signed_multipliers used grad_ but not mu_
          for (Index j = 0; j < nheld; ++j) {
            if (wp_(j) ? mu_(j) < -dtol : mu_(j) > dtol) w_new_(held_(j)) = 0;
          }
        }
      }
      if (any_change) ok = false;
    }
    if (ok) return true;
    s = s_new_;
    w = w_new_;
  }
  return false;
}

void guess_from_point(const VectorXd* cv, const CVecRef& lo, const CVecRef& up,
                      const CVecRef& los, const CVecRef& ups, const VectorXd* gv,
                      const CVecRef& gl, const CVecRef& gu, const CVecRef& gls,
                      const CVecRef& gus, double active_tol, IVec& s, IVec& w) {
  const Index mc = cv ? cv->size() : 0;
  s.resize(mc);
  for (Index i = 0; i < mc; ++i) {
    const double c = (*cv)(i);
    const bool hi = c >= up(i) - active_tol * ups(i);
    const bool lw = c <= lo(i) + active_tol * los(i);
    s(i) = int(hi) - int(lw);
    if (hi && lw) s(i) = c >= 0.5 * (lo(i) + up(i)) ? 1 : -1;
  }
  const Index p = gv ? gv->size() : 0;
  w.resize(p);
  for (Index i = 0; i < p; ++i) {
    const double g = (*gv)(i);
    const bool hi = g >= gu(i) - active_tol * gus(i);
    const bool lw = g <= gl(i) + active_tol * gls(i);
    w(i) = int(hi) - int(lw);
    if (hi && lw) w(i) = g >= 0.5 * (gl(i) + gu(i)) ? 1 : -1;
  }
}

}  // namespace hqp
