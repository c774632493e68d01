// The basis algorithm of the native solver; see hierarchy.hpp. Each step names the step
// of hqp.solver.basis.BasisAlgorithm it follows.
#include "solver/hierarchy.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace hqp {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bool within(const VectorXd& cx, const CVecRef& lo, const CVecRef& up, const CVecRef& los,
            const CVecRef& ups) {
  for (Index i = 0; i < cx.size(); ++i) {
    if (cx(i) < lo(i) - kFeasTol * los(i) || cx(i) > up(i) + kFeasTol * ups(i)) return false;
  }
  return true;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double mth_singular(const VectorXd& s, Index m, Index r, double thr) {
  if (m == 0) return kInf;
  if (m > r || m > s.size()) return 0.0;
  const double v = s(m - 1);
  return v > thr ? v : 0.0;
}

}  // namespace

void LevelData::set_norm(Index n) {
  A.setIdentity(n, n);
  b.setZero(n);
  C.resize(0, n);
  lo.resize(0);
  up.resize(0);
  kind = LevelKind::kNorm;
  finish();
  a_scale = 1.0;
}

void LevelData::finish() {
  const Index mi = C.rows();
  los.resize(mi);
  ups.resize(mi);
  bounded.resize(mi);
  for (Index i = 0; i < mi; ++i) {
    los(i) = std::min(std::max(std::abs(lo(i)), 1.0), 1e300);
    ups(i) = std::min(std::max(std::abs(up(i)), 1.0), 1e300);
    bounded(i) = (lo(i) > -kInf) || (up(i) < kInf);
  }
  a_scale = A.size() ? A.cwiseAbs().maxCoeff() : 0.0;
  c_scale = C.size() ? C.cwiseAbs().maxCoeff() : 0.0;
}

void Hierarchy::resize_levels(std::size_t count) {
  if (levels_.size() != count) levels_.resize(count);
  if (slots_.size() != count) slots_.resize(count);
}

void Hierarchy::reset() {
  for (Slot& slot : slots_) {
    slot.has_guess = false;
    slot.has_point = false;
    slot.warm_skip = 0;
    slot.needed_qp = false;
    slot.qp.reset();
  }
}

bool Hierarchy::warm_slot(Slot& slot) {
  if (slot.warm_skip == 0) return true;
  --slot.warm_skip;
  return false;
}

std::string Hierarchy::solve(Index n, Index user_levels) {
  const double rank_tol = settings_.rank_tol;
  const Index NL = Index(levels_.size());
  if (Index(slots_.size()) != NL) slots_.resize(NL);
  if (Index(results_.size()) != user_levels) results_.resize(user_levels);
  if (n != n_) {
    reset();
    n_ = n;
  }
  qp_count_ = 0;
  final_seconds_ = 0.0;
  x_.resize(n);
  x_.setZero();
  Index total_in = 0;
  for (const LevelData& lv : levels_) total_in += lv.C.rows();
  if (G_.rows() != total_in || G_.cols() != n) G_.resize(total_in, n);
  gl_.resize(total_in);
  gu_.resize(total_in);
  gls_.resize(total_in);
  gus_.resize(total_in);
  gid_.resize(total_in);
  gtmp_.resize(total_in);
  Index p = 0;
  Index off = 0;
  const MatrixXd* Z = nullptr;  // nullptr: identity
  Index r = n;
  enum class Null { kNone, kEmpty, kFact, kViolated };

  for (Index k = 0; k < NL; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    const LevelData& lv = levels_[k];
    Slot& slot = slots_[k];
    const Index me = lv.A.rows(), mi = lv.C.rows();
    slot.projected = false;
    slot.has_fact = false;
    slot.Zb = Z;
    if (r == 0 || me + mi == 0) {
      if (k < user_levels) results_[k].seconds = seconds_since(t0);
      off += mi;
      continue;
    }
    const bool carried = p > 0;
    auto G = G_.topRows(p);
    auto gl = gl_.head(p);
    auto gu = gu_.head(p);
    auto gls = gls_.head(p);
    auto gus = gus_.head(p);
    slot.Ak.resize(me, r);
    if (Z)
      slot.Ak.noalias() = lv.A * (*Z);
    else
      slot.Ak = lv.A;
    slot.projected = true;
    slot.bk.resize(me);
    slot.bk = lv.b;
    slot.bk.noalias() -= lv.A * x_;
    // 1. least squares on the equality rows
    const bool ws = settings_.warm_start && warm_slot(slot);
    bool have_warm = false;
    if (ws && (mi || carried)) {
      have_warm = slot.has_guess && slot.memo_s.size() == mi && slot.memo_w.size() == total_in &&
                  slot.has_point && slot.point.size() == n;
      if (have_warm) {
        slot.s = slot.memo_s;
        slot.w.resize(p);
        for (Index j = 0; j < p; ++j) slot.w(j) = slot.memo_w(gid_(j));
      }
    }
    bool deferred;
    if (ws) {
      deferred = have_warm && (slot.s.any() || slot.w.any());
    } else {
      deferred = (mi > 0 || carried) && slot.needed_qp && slot.nq_mi == mi && slot.nq_r == r &&
                 slot.nq_p == p;
    }
    bool y_none = true;
    Null null = Null::kNone;
    slot.y.resize(r);
    if (deferred) {
      // the previous solve needed this level's inequalities: straight to its active set
    } else if (lv.kind == LevelKind::kNorm) {
      if (Z)
        slot.y.noalias() = Z->transpose() * slot.bk;
      else
        slot.y = slot.bk;
      y_none = false;
      null = Null::kEmpty;
    } else if (me) {
      slot.fact.compute(slot.Ak, rank_tol, lv.a_scale);
      slot.has_fact = true;
      slot.fact.lstsq(slot.bk, slot.y);
      y_none = false;
      null = Null::kFact;
    }
    slot.xl.resize(n);
    slot.xl = x_;
    if (!y_none) {
      if (Z)
        slot.xl.noalias() += (*Z) * slot.y;
      else
        slot.xl += slot.y;
    }
    // 2. does the least-squares point satisfy the inequalities?
    bool feasible = !deferred;
    slot.cx.resize(mi);
    if (mi && feasible) {
      slot.cx.noalias() = lv.C * slot.xl;
      feasible = within(slot.cx, lv.lo, lv.up, lv.los, lv.ups);
    }
    if (feasible && carried) {
      slot.gxl.resize(p);
      slot.gxl.noalias() = G * slot.xl;
      feasible = within(slot.gxl, gl, gu, gls, gus);
    }
    bool has_violated = false;
    bool qp_point = false;
    slot.violated.resize(mi);
    slot.violated.setZero();
    if (!feasible) {
      slot.Ck.resize(mi, r);
      if (Z)
        slot.Ck.noalias() = lv.C * (*Z);
      else
        slot.Ck = lv.C;
      slot.gx.resize(p);
      slot.gx.noalias() = G * x_;
      slot.cx0.resize(mi);
      slot.cx0.noalias() = lv.C * x_;
      slot.lo_r = lv.lo - slot.cx0;
      slot.up_r = lv.up - slot.cx0;
      slot.glr = gl - slot.gx;
      slot.gur = gu - slot.gx;
      const double scale = std::max(lv.a_scale, lv.c_scale);
      const LevelRows rows{slot.Ak, slot.bk, slot.Ck, slot.lo_r, slot.up_r, lv.los, lv.ups};
      const CarriedRows held{G, slot.glr, slot.gur, gls, gus, Z};
      bool y_ok = false;
      // 3a. the previous solve's active set (or the least-squares point's), verified
      if (ws) {
        slot.ref.resize(r);
        slot.tmp.resize(n);
        if (!have_warm) {
          slot.tmp = slot.xl - x_;
          if (Z)
            slot.ref.noalias() = Z->transpose() * slot.tmp;
          else
            slot.ref = slot.tmp;
          slot.qlo.resize(mi);
          slot.qup.resize(p);
          if (mi) slot.qlo.noalias() = slot.Ck * slot.ref;
          if (carried) {
            if (Z) {
              slot.zref.resize(n);
              slot.zref.noalias() = (*Z) * slot.ref;
              slot.qup.noalias() = G * slot.zref;
            } else {
              slot.qup.noalias() = G * slot.ref;
            }
          }
          guess_from_point(mi ? &slot.qlo : nullptr, slot.lo_r, slot.up_r, lv.los, lv.ups,
                           carried ? &slot.qup : nullptr, slot.glr, slot.gur, gls, gus,
                           -kFeasTol, slot.s, slot.w);
        } else {
          slot.tmp = slot.point - x_;
          if (Z)
            slot.ref.noalias() = Z->transpose() * slot.tmp;
          else
            slot.ref = slot.tmp;
        }
        y_ok = slot.as.solve(rows, held, slot.s, slot.w, rank_tol, scale, kMaxIter, &slot.ref,
                             slot.y);
      }
      bool ok = true;
      if (!y_ok) {
        // 3b. QP in the reduced coordinates (and the level's slacks): G Z formed here only
        ++qp_count_;
        slot.Gk.resize(p, r);
        if (Z)
          slot.Gk.noalias() = G * (*Z);
        else
          slot.Gk = G;
        qp_point = true;
        const Index nq = r + mi;
        slot.H.resize(nq, nq);
        slot.H.setZero();
        slot.H.topLeftCorner(r, r).noalias() = slot.Ak.transpose() * slot.Ak;
        slot.g.resize(nq);
        slot.g.setZero();
        slot.g.head(r).noalias() = slot.Ak.transpose() * slot.bk;
        slot.g.head(r) *= -1.0;
        slot.Cq.resize(mi + p, nq);
        slot.Cq.setZero();
        slot.qlo.resize(mi + p);
        slot.qup.resize(mi + p);
        if (mi) {
          slot.H.bottomRightCorner(mi, mi).setIdentity();
          slot.Cq.topLeftCorner(mi, r) = slot.Ck;
          slot.Cq.block(0, r, mi, mi).setIdentity();
          slot.Cq.block(0, r, mi, mi) *= -1.0;
          slot.qlo.head(mi) = slot.lo_r;
          slot.qup.head(mi) = slot.up_r;
        }
        if (carried) {
          slot.Cq.bottomLeftCorner(p, r) = slot.Gk;
          slot.qlo.tail(p) = slot.glr;
          slot.qup.tail(p) = slot.gur;
        }
        ok = slot.qp.solve(slot.H, slot.g, slot.Cq, slot.qlo, slot.qup, slot.v);
        slot.y = slot.v.head(r);
        if (ws && slot.y.allFinite()) {
          // polish: the QP point's active set, solved exactly if it verifies
          slot.qlo.resize(mi);
          slot.qup.resize(p);
          if (mi) slot.qlo.noalias() = slot.Ck * slot.y;
          if (carried) slot.qup.noalias() = slot.Gk * slot.y;
          guess_from_point(mi ? &slot.qlo : nullptr, slot.lo_r, slot.up_r, lv.los, lv.ups,
                           carried ? &slot.qup : nullptr, slot.glr, slot.gur, gls, gus,
                           kActiveTol, slot.s, slot.w);
          slot.ref = slot.y;
          if (slot.as.solve(rows, held, slot.s, slot.w, rank_tol, scale, kPolishIter, &slot.ref,
                            slot.v)) {
            slot.y = slot.v;
            ok = true;
          } else {
            slot.warm_skip = kWarmSkip;
            slot.has_guess = false;
          }
        }
      }
      (void)ok;
      if (ws) {
        slot.memo_s = slot.s;
        slot.memo_w.resize(total_in);
        slot.memo_w.setZero();
        for (Index j = 0; j < p; ++j) slot.memo_w(gid_(j)) = slot.w(j);
        slot.has_guess = true;  // (as the reference: kept even after a failed polish)
        slot.point.resize(n);
        slot.point = x_;
        if (Z)
          slot.point.noalias() += (*Z) * slot.y;
        else
          slot.point += slot.y;
        slot.has_point = true;
      }
      if (!slot.y.allFinite()) {
        return "level " + std::to_string(k) +
               ": the native QP (DAQP) returned a non-finite solution";
      }
      slot.xl = x_;
      if (Z)
        slot.xl.noalias() += (*Z) * slot.y;
      else
        slot.xl += slot.y;
      if (mi) {
        slot.cx.noalias() = lv.C * slot.xl;
        for (Index i = 0; i < mi; ++i) {
          const bool v = slot.cx(i) > lv.up(i) + kFixTol * lv.ups(i) ||
                         slot.cx(i) < lv.lo(i) - kFixTol * lv.los(i);
          slot.violated(i) = v;
          has_violated = has_violated || v;
        }
      }
    }
    if (qp_point) {
      slot.needed_qp = true;
      slot.nq_mi = mi;
      slot.nq_r = r;
      slot.nq_p = p;
    } else {
      slot.needed_qp = false;
    }
    // 4. shrink the basis: equality rows and violated rows become equalities
    if (has_violated) {
      const Index nv = slot.violated.sum();
      slot.E.resize(me + nv, r);
      if (me) slot.E.topRows(me) = slot.Ak;
      double cmax = 0.0;
      for (Index i = 0, j = me; i < mi; ++i) {
        if (!slot.violated(i)) continue;
        if (Z)
          slot.E.row(j).noalias() = lv.C.row(i) * (*Z);
        else
          slot.E.row(j) = lv.C.row(i);
        cmax = std::max(cmax, lv.C.row(i).cwiseAbs().maxCoeff());
        ++j;
      }
      slot.null_qr.compute(slot.E, rank_tol, std::max(lv.a_scale, cmax));
      null = Null::kViolated;
    } else if (deferred) {
      if (lv.kind == LevelKind::kNorm) {
        null = Null::kEmpty;
      } else if (me) {
        slot.fact.compute(slot.Ak, rank_tol, lv.a_scale);
        slot.has_fact = true;
        null = Null::kFact;
      } else {
        null = Null::kNone;
      }
    }
    x_ = slot.xl;
    if (null != Null::kNone) {
      if (null == Null::kEmpty) {
        slot.Z.resize(n, 0);
      } else {
        PivotedQR& f = null == Null::kFact ? slot.fact : slot.null_qr;
        const MatrixXd& N = f.null();
        slot.Z.resize(n, N.cols());
        if (Z)
          slot.Z.noalias() = (*Z) * N;
        else
          slot.Z = N;
      }
      Z = &slot.Z;
      r = slot.Z.cols();
    }
    // carried rows: widen to contain x (absorbs the QP tolerance); add this level's
    if (carried && qp_point) {
      auto gx = gtmp_.head(p);
      gx.noalias() = G * x_;
      for (Index j = 0; j < p; ++j) {
        if (gx(j) < gl_(j)) gl_(j) = gx(j) - kCarryMargin * gls_(j);
        if (gx(j) > gu_(j)) gu_(j) = gx(j) + kCarryMargin * gus_(j);
      }
    }
    for (Index i = 0; i < mi; ++i) {
      if (!lv.bounded(i) || slot.violated(i)) continue;
      const double ck = slot.cx(i);
      G_.row(p) = lv.C.row(i);
      gl_(p) = std::min(lv.lo(i), ck) - kCarryMargin * lv.los(i);
      gu_(p) = std::max(lv.up(i), ck) + kCarryMargin * lv.ups(i);
      gls_(p) = lv.los(i);
      gus_(p) = lv.ups(i);
      gid_(p) = int(off + i);
      ++p;
    }
    off += mi;
    const double dt = seconds_since(t0);
    if (k < user_levels)
      results_[k].seconds = dt;
    else
      final_seconds_ += dt;
  }
  if (!x_.allFinite()) return "the native solver returned a non-finite solution";
  for (Index k = 0; k < user_levels; ++k) report(k);
  return std::string();
}

void Hierarchy::report(Index k) {
  const LevelData& lv = levels_[k];
  LevelResult& out = results_[k];
  const Index me = lv.A.rows(), mi = lv.C.rows();
  out.residual_eq.resize(me);
  out.residual_eq.noalias() = lv.A * x_;
  out.residual_eq -= lv.b;
  out.violation_in.resize(mi);
  out.state.resize(mi);
  Slot& slot = slots_[k];
  slot.cx.resize(mi);
  if (mi) slot.cx.noalias() = lv.C * x_;
  for (Index i = 0; i < mi; ++i) {
    const double above = slot.cx(i) - lv.up(i);
    const double below = slot.cx(i) - lv.lo(i);
    out.violation_in(i) = above > 0.0 ? above : (below < 0.0 ? below : 0.0);
    const double tu = kRowTol * lv.ups(i), tl = kRowTol * lv.los(i);
    const bool active = above >= -tu || below <= tl;
    const bool violated = above > tu || below < -tl;
    out.state(i) = violated ? 2 : (active ? 1 : 0);
  }
  out.cost = out.residual_eq.squaredNorm() + out.violation_in.squaredNorm();
  out.satisfied = out.cost <= kSatisfiedCost;
  out.sigma_min = settings_.compute_sigma ? sigma_level(k)
                                          : std::numeric_limits<double>::quiet_NaN();
}

double Hierarchy::sigma_level(Index k) {
  // the m-th singular value of [A; C_active] Zb (hqp.solver.report.sigma_level)
  const LevelData& lv = levels_[k];
  Slot& slot = slots_[k];
  const LevelResult& out = results_[k];
  const Index me = lv.A.rows();
  Index n_act = 0;
  for (Index i = 0; i < out.state.size(); ++i) n_act += out.state(i) != 0;
  const Index m = me + n_act;
  if (m == 0) return kInf;
  if (!slot.projected) return 0.0;
  const Index r = slot.Ak.cols();
  if (m > r) return 0.0;
  double scale = lv.a_scale;
  const VectorXd* s;
  if (n_act) {
    slot.Msig.resize(m, r);
    if (me) slot.Msig.topRows(me) = slot.Ak;
    double cmax = 0.0;
    for (Index i = 0, j = me; i < out.state.size(); ++i) {
      if (!out.state(i)) continue;
      if (slot.Zb)
        slot.Msig.row(j).noalias() = lv.C.row(i) * (*slot.Zb);
      else
        slot.Msig.row(j) = lv.C.row(i);
      cmax = std::max(cmax, lv.C.row(i).cwiseAbs().maxCoeff());
      ++j;
    }
    scale = std::max(scale, cmax);
    s = &slot.sv.compute(slot.Msig, settings_.rank_tol, scale);
  } else if (slot.has_fact) {
    slot.svals.resize(std::min(slot.fact.rows(), slot.fact.cols()));
    slot.fact.singular_values(slot.svals, settings_.rank_tol, scale);
    s = &slot.svals;
  } else {
    s = &slot.sv.compute(slot.Ak, settings_.rank_tol, scale);
  }
  const double s0 = s->size() ? (*s)(0) : 0.0;
  return mth_singular(*s, m, r, settings_.rank_tol * std::max(s0, scale));
}

}  // namespace hqp
