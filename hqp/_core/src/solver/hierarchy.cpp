// The basis algorithm of the native solver; see hierarchy.hpp. Each step names the step
// of hqp.solver.basis.BasisAlgorithm it follows.
#include "solver/hierarchy.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <cmath>
#include <limits>

namespace hqp {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bool within(const CVecRef& cx, const CVecRef& lo, const CVecRef& up, const CVecRef& los,
            const CVecRef& ups) {
  for (Index i = 0; i < cx.size(); ++i) {
    if (cx(i) < lo(i) - kFeasTol * los(i) || cx(i) > up(i) + kFeasTol * ups(i)) return false;
  }
  return true;
}

// Strictly inside [lo, up] by kFeasTol (times the bounds' scales): the anchor's test. A
// point within the feasibility band but not inside it (a row at its bound to rounding) is
// left to the active set, whose point does not depend on where the least squares started.
bool inside(const CVecRef& cx, const CVecRef& lo, const CVecRef& up, const CVecRef& los,
            const CVecRef& ups) {
  for (Index i = 0; i < cx.size(); ++i) {
    if (!(cx(i) >= lo(i) + kFeasTol * los(i) && cx(i) <= up(i) - kFeasTol * ups(i))) return false;
  }
  return true;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double mth_singular(const CVecRef& s, Index m, Index r, double thr) {
  if (m == 0) return kInf;
  if (m > r || m > s.size()) return 0.0;
  const double v = s(m - 1);
  return v > thr ? v : 0.0;
}

}  // namespace

const char* solver_simd() {
#if defined(__AVX2__) && defined(__FMA__)
  return "avx2+fma";
#else
  return "sse2";
#endif
}

const char* solver_simd_option() {
#ifdef HQP_SIMD_OPTION
  return HQP_SIMD_OPTION;
#else
  return "AUTO";
#endif
}

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
  a_support.compute(A);
  c_support.compute(C);
}

void Slot::reserve(Index n, Index me, Index mi, Index P, Index total_in) {
  const Index nq = n + mi;  // the QP's variables: reduced coordinates and the level's slacks
  Ak.reserve(me, n);
  Ck.reserve(mi, n);
  Gk.reserve(P, n);
  Z.reserve(n, n);
  E.reserve(me + mi + P, n);
  Msig.reserve(me + mi, n);
  H.reserve(nq, nq);
  Cq.reserve(mi + P, nq);
  y.reserve(n);
  ref.reserve(n);
  g.reserve(nq);
  v.reserve(nq);
  v0.reserve(nq);
  qlo.reserve(mi + P);
  qup.reserve(mi + P);
  gx.reserve(P);
  glr.reserve(P);
  gur.reserve(P);
  gxl.reserve(P);
  w.reserve(P);
  absorbed.reserve(P);
  svals.reserve(std::min(me, n));
  fact.reserve(me, n, n);
  null_qr.reserve(me + mi + P, n, n);
  as.reserve(me, mi, P, n, n, kMaxIter);
  qp.reserve(nq, mi + P);
  sv.reserve(me + mi, n);
  weak.reserve(me, n);
  bk.resize(me);
  xl.resize(n);
  tmp.resize(n);
  zref.resize(n);
  xc.resize(n);
  dc.reserve(n);
  cx.resize(mi);
  cx0.resize(mi);
  lo_r.resize(mi);
  up_r.resize(mi);
  s.resize(mi);
  violated.resize(mi);
  // the warm-start memory of another shape is no guess (as a size mismatch before)
  if (memo_s.size() != mi || memo_w.size() != total_in) {
    has_guess = false;
    memo_s.resize(mi);
    memo_w.resize(total_in);
  }
  if (point.size() != n) {
    has_point = false;
    point.resize(n);
  }
}

bool Hierarchy::shapes_changed(Index n) {
  const std::size_t count = 1 + 2 * levels_.size();
  bool same = shapes_.size() == count && shapes_[0] == n;
  for (std::size_t k = 0; same && k < levels_.size(); ++k) {
    same = shapes_[1 + 2 * k] == levels_[k].A.rows() && shapes_[2 + 2 * k] == levels_[k].C.rows();
  }
  if (same) return false;
  shapes_.resize(count);
  shapes_[0] = n;
  for (std::size_t k = 0; k < levels_.size(); ++k) {
    shapes_[1 + 2 * k] = levels_[k].A.rows();
    shapes_[2 + 2 * k] = levels_[k].C.rows();
  }
  return true;
}

void Hierarchy::resize_levels(std::size_t count) {
  if (levels_.size() != count) levels_.resize(count);
  if (slots_.size() != count) slots_.resize(count);
}

void Hierarchy::reset() {
  has_anchor_ = false;
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
  // a level whose QP fails (a thin feasible set) sends the solve to a second pass that
  // absorbs the rows active over the optimal sets above (BasisAlgorithm.solve)
  const long long budget = settings_.work_budget;
  budget_left_ = budget > 0 ? budget : std::numeric_limits<long long>::max();
  std::string err = solve_pass(n, user_levels, false);
  if (!err.empty()) {
    const int first = qp_count_;
    err = solve_pass(n, user_levels, true);
    qp_count_ += first;
  }
  work_used_ = budget > 0 ? budget - budget_left_ : 0;
  if (err.empty() && settings_.warm_start) {
    anchor_ = x_;
    has_anchor_ = true;
  } else {
    has_anchor_ = false;
  }
  return err;
}

std::string Hierarchy::solve_pass(Index n, Index user_levels, bool absorb) {
  const double rank_tol = settings_.rank_tol;
  const Index NL = Index(levels_.size());
  if (Index(slots_.size()) != NL) slots_.resize(NL);
  if (Index(results_.size()) != user_levels) results_.resize(user_levels);
  if (n != n_) {
    reset();
    n_ = n;
  }
  qp_count_ = 0;
  anchored_ = 0;
  final_seconds_ = 0.0;
  x_.resize(n);
  x_.setZero();
  Index total_in = 0;
  for (const LevelData& lv : levels_) total_in += lv.C.rows();
  if (shapes_changed(n)) {
    // the structure changed: every workspace reserved for the largest shape of its level
    Index P = 0;
    for (Index k = 0; k < NL; ++k) {
      const LevelData& lv = levels_[k];
      slots_[k].reserve(n, lv.A.rows(), lv.C.rows(), P, total_in);
      if (k < user_levels) {
        results_[k].residual_eq.resize(lv.A.rows());
        results_[k].violation_in.resize(lv.C.rows());
        results_[k].state.resize(lv.C.rows());
      }
      P += lv.C.rows();
    }
  }
  if (G_.rows() != total_in || G_.cols() != n) G_.resize(total_in, n);
  gl_.resize(total_in);
  gu_.resize(total_in);
  gls_.resize(total_in);
  gus_.resize(total_in);
  gid_.resize(total_in);
  gtmp_.resize(total_in);
  Index p = 0;
  Index off = 0;
  const WorkM* Z = nullptr;  // nullptr: identity
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
    if (k < user_levels) {
      results_[k].weak = 0;
      results_[k].cut = false;
    }
    if (r == 0 || me + mi == 0) {
      if (k < user_levels) results_[k].seconds = seconds_since(t0);
      off += mi;
      continue;
    }
    const CMapM Zm = Z ? Z->mat() : CMapM(nullptr, 0, 0);  // the basis (n, r) of this level
    const bool carried = p > 0;
    auto G = G_.topRows(p);
    auto gl = gl_.head(p);
    auto gu = gu_.head(p);
    auto gls = gls_.head(p);
    auto gus = gus_.head(p);
    MapM Ak = slot.Ak.mat(me, r);
    if (Z)
      lv.a_support.project(lv.A, Zm, Ak);
    else
      Ak = lv.A;
    slot.projected = true;
    // a level of equality rows alone that the basis no longer reaches has a constant cost
    // over the feasible set: its point is x, by least squares (BasisAlgorithm._level, inert)
    const bool inert =
        mi == 0 && Ak.size() > 0 && Ak.cwiseAbs().maxCoeff() <= rank_tol * lv.a_scale;
    if (inert) Ak.setZero();
    slot.bk = lv.b;
    slot.bk.noalias() -= lv.A * x_;
    if (lv.weak > 0.0 && lv.kind == LevelKind::kUser && me && !inert) {
      // the weak directions' targets filtered before any step uses them (Level)
      const int weak = slot.weak.apply(Ak, slot.bk, Z ? &Zm : nullptr, x_, lv.b, lv.weak,
                                       rank_tol, lv.a_scale);
      if (k < user_levels) results_[k].weak = weak;
    }
    // 1. least squares on the equality rows
    const bool ws = settings_.warm_start && warm_slot(slot);
    bool have_warm = false;
    MapI w = slot.w.vec(p);
    if (ws && (mi || carried)) {
      have_warm = slot.has_guess && slot.memo_s.size() == mi && slot.memo_w.size() == total_in &&
                  slot.has_point && slot.point.size() == n;
      if (have_warm) {
        slot.s = slot.memo_s;
        for (Index j = 0; j < p; ++j) w(j) = slot.memo_w(gid_(j));
      }
    }
    bool deferred;
    if (ws) {
      deferred = have_warm && (slot.s.any() || w.any()) && !inert;
    } else {
      deferred = (mi > 0 || carried) && slot.needed_qp && slot.nq_mi == mi && slot.nq_r == r &&
                 slot.nq_p == p && !inert;
    }
    bool y_none = true;
    Null null = Null::kNone;
    MapV y = slot.y.vec(r);
    // the previous solve's solution, brought into this optimal set, as the start of the
    // least squares (BasisAlgorithm._anchored): strictly inside every bound, no active set
    const bool anchor = ws && has_anchor_ && lv.kind == LevelKind::kUser && !inert &&
                        (mi > 0 || carried);
    if (deferred && !anchor) {
      // the previous solve needed this level's inequalities: straight to its active set
    } else if (lv.kind == LevelKind::kNorm) {
      if (Z)
        y.noalias() = Zm.transpose() * slot.bk;
      else
        y = slot.bk;
      y_none = false;
      null = Null::kEmpty;
    } else if (me) {
      slot.fact.compute(Ak, rank_tol, lv.a_scale);
      slot.has_fact = true;
      slot.fact.lstsq(slot.bk, y);
      y_none = false;
      null = Null::kFact;
    }
    slot.xl = x_;
    if (!y_none) {
      if (Z)
        slot.xl.noalias() += Zm * y;
      else
        slot.xl += y;
    }
    // 2. does the least-squares point satisfy the inequalities?
    bool feasible = !deferred;
    bool anchored = false;
    if (anchor) {
      // y_c = y + (I - P) Z^T (anchor - x): the least-squares point nearest the anchor
      MapV d = slot.dc.vec(r);
      slot.tmp = anchor_ - x_;
      if (Z)
        d.noalias() = Zm.transpose() * slot.tmp;
      else
        d = slot.tmp;
      if (!y_none && me) {
        if (slot.fact.rank() >= r) {
          d = y;  // no null space: the least-squares point is unique
        } else {
          slot.fact.apply_qt(d);
          d.head(slot.fact.rank()).setZero();
          slot.fact.apply_q(d);
          d += y;
        }
      }
      slot.xc = x_;
      if (Z)
        slot.xc.noalias() += Zm * d;
      else
        slot.xc += d;
      bool ok = true;
      if (mi) {
        slot.cx.noalias() = lv.C * slot.xc;
        ok = inside(slot.cx, lv.lo, lv.up, lv.los, lv.ups);
      }
      if (ok && carried) {
        MapV gxl = slot.gxl.vec(p);
        gxl.noalias() = G * slot.xc;
        ok = inside(gxl, gl, gu, gls, gus);
      }
      if (ok) {
        anchored = true;
        ++anchored_;
        slot.xl = slot.xc;
        y = d;
        y_none = false;
        feasible = true;
        if (deferred) {
          deferred = false;
          if (me) null = Null::kFact;
        }
      } else if (deferred) {
        // as without the anchor: straight to the active set, the null space decided below
        null = Null::kNone;
        slot.xl = x_;
      }
    }
    if (anchored) {
      // (checked above)
    } else if (mi && feasible) {
      slot.cx.noalias() = lv.C * slot.xl;
      feasible = within(slot.cx, lv.lo, lv.up, lv.los, lv.ups);
    }
    if (feasible && carried && !anchored) {
      MapV gxl = slot.gxl.vec(p);
      gxl.noalias() = G * slot.xl;
      feasible = within(gxl, gl, gu, gls, gus);
    }
    bool has_violated = false;
    bool qp_point = false;
    Index n_absorbed = 0;
    MapI absorbed = slot.absorbed.vec(p);
    slot.violated.setZero();
    if (!feasible) {
      MapM Ck = slot.Ck.mat(mi, r);
      if (Z)
        lv.c_support.project(lv.C, Zm, Ck);
      else
        Ck = lv.C;
      MapV gx = slot.gx.vec(p);
      gx.noalias() = G * x_;
      slot.cx0.noalias() = lv.C * x_;
      slot.lo_r = lv.lo - slot.cx0;
      slot.up_r = lv.up - slot.cx0;
      MapV glr = slot.glr.vec(p), gur = slot.gur.vec(p);
      glr = gl - gx;
      gur = gu - gx;
      const double scale = std::max(lv.a_scale, lv.c_scale);
      const LevelRows rows{Ak, slot.bk, Ck, slot.lo_r, slot.up_r, lv.los, lv.ups};
      const CarriedRows held{G, glr, gur, gls, gus, Z};
      bool y_ok = false;
      // 3a. the previous solve's active set (or the least-squares point's), verified
      if (ws) {
        MapV ref = slot.ref.vec(r);
        if (!have_warm) {
          slot.tmp = slot.xl - x_;
          if (Z)
            ref.noalias() = Zm.transpose() * slot.tmp;
          else
            ref = slot.tmp;
          MapV qlo = slot.qlo.vec(mi), qup = slot.qup.vec(p);
          if (mi) qlo.noalias() = Ck * ref;
          if (carried) {
            if (Z) {
              slot.zref.noalias() = Zm * ref;
              qup.noalias() = G * slot.zref;
            } else {
              qup.noalias() = G * ref;
            }
          }
          guess_from_point(mi ? qlo.data() : nullptr, slot.lo_r, slot.up_r, lv.los, lv.ups,
                           carried ? qup.data() : nullptr, glr, gur, gls, gus, -kFeasTol,
                           slot.s, w);
        } else {
          slot.tmp = slot.point - x_;
          if (Z)
            ref.noalias() = Zm.transpose() * slot.tmp;
          else
            ref = slot.tmp;
        }
        y_ok = slot.as.solve(rows, held, slot.s, w, rank_tol, scale, kMaxIter, ref.data(), y);
      }
      bool verified = y_ok;  // y solved on an active set that verified (slot.as holds it)
      bool ok = true;
      if (!y_ok) {
        // 3b. QP in the reduced coordinates (and the level's slacks): G Z formed here only
        ++qp_count_;
        MapM Gk = slot.Gk.mat(p, r);
        if (Z)
          Gk.noalias() = G * Zm;
        else
          Gk = G;
        qp_point = true;
        const Index nq = r + mi;
        MapM H = slot.H.mat(nq, nq);
        H.setZero();
        H.topLeftCorner(r, r).noalias() = Ak.transpose() * Ak;
        MapV g = slot.g.vec(nq);
        g.setZero();
        g.head(r).noalias() = Ak.transpose() * slot.bk;
        g.head(r) *= -1.0;
        MapM Cq = slot.Cq.mat(mi + p, nq);
        Cq.setZero();
        MapV qlo = slot.qlo.vec(mi + p), qup = slot.qup.vec(mi + p);
        if (mi) {
          H.bottomRightCorner(mi, mi).setIdentity();
          Cq.topLeftCorner(mi, r) = Ck;
          Cq.block(0, r, mi, mi).setIdentity();
          Cq.block(0, r, mi, mi) *= -1.0;
          qlo.head(mi) = slot.lo_r;
          qup.head(mi) = slot.up_r;
        }
        if (carried) {
          Cq.bottomLeftCorner(p, r) = Gk;
          qlo.tail(p) = glr;
          qup.tail(p) = gur;
        }
        MapV v = slot.v.vec(nq);
        // the first pass tries DAQP's cheap attempts only: where they fail, the absorbing pass
        // (with every attempt) is the remedy for thin feasible sets (issue 17)
        // a feasible point of the QP, where PrimalQP starts if DAQP's first attempt fails in
        // the absorbing pass (docs/design/control.md):
        // the levels above's solution (y = 0) with the level's slacks at their clamp
        MapV v0 = slot.v0.vec(nq);
        v0.setZero();
        for (Index i = 0; i < mi; ++i)
          v0(r + i) = -std::min(std::max(0.0, slot.lo_r(i)), slot.up_r(i));
        slot.qp.set_budget(settings_.work_budget > 0 ? &budget_left_ : nullptr);
        ok = slot.qp.solve(H, g, Cq, qlo, qup, v, !absorb, v0.data());
        if (k < user_levels && slot.qp.cut()) results_[k].cut = true;
        y = v.head(r);
        if (ws && y.allFinite()) {
          // polish: the QP point's active set, solved exactly if it verifies
          MapV plo = slot.qlo.vec(mi), pup = slot.qup.vec(p);
          if (mi) plo.noalias() = Ck * y;
          if (carried) pup.noalias() = Gk * y;
          guess_from_point(mi ? plo.data() : nullptr, slot.lo_r, slot.up_r, lv.los, lv.ups,
                           carried ? pup.data() : nullptr, glr, gur, gls, gus, kActiveTol,
                           slot.s, w);
          MapV ref = slot.ref.vec(r);
          ref = y;
          MapV vp = slot.v.vec(r);
          if (slot.as.solve(rows, held, slot.s, w, rank_tol, scale, kPolishIter, ref.data(),
                            vp)) {
            y = vp;
            ok = true;
            verified = true;
          } else {
            slot.warm_skip = kWarmSkip;
            slot.has_guess = false;
          }
        }
      }
      (void)ok;
      if (ws) {
        slot.memo_s = slot.s;
        slot.memo_w.setZero();
        for (Index j = 0; j < p; ++j) slot.memo_w(gid_(j)) = w(j);
        slot.has_guess = true;  // (as the reference: kept even after a failed polish)
        slot.point = x_;
        if (Z)
          slot.point.noalias() += Zm * y;
        else
          slot.point += y;
        slot.has_point = true;
      }
      if (!y.allFinite()) {
        return "level " + std::to_string(k) +
               ": the native QP (DAQP) returned a non-finite solution";
      }
      slot.xl = x_;
      if (Z)
        slot.xl.noalias() += Zm * y;
      else
        slot.xl += y;
      if (mi) {
        slot.cx.noalias() = lv.C * slot.xl;
        for (Index i = 0; i < mi; ++i) {
          const bool v = slot.cx(i) > lv.up(i) + kFixTol * lv.ups(i) ||
                         slot.cx(i) < lv.lo(i) - kFixTol * lv.los(i);
          slot.violated(i) = v;
          has_violated = has_violated || v;
        }
      }
      // carried rows held with a positive multiplier bound the level's whole optimal set:
      // equalities of the basis below (hqp.solver.basis.BasisAlgorithm._absorbed)
      if (absorb && verified && carried)
        n_absorbed = std::max<Index>(0, slot.as.absorbed(y, absorbed));
    }
    if (qp_point) {
      slot.needed_qp = true;
      slot.nq_mi = mi;
      slot.nq_r = r;
      slot.nq_p = p;
    } else {
      slot.needed_qp = false;
    }
    // 4. shrink the basis: equality rows, violated rows and absorbed carried rows become
    // equalities
    if (has_violated || n_absorbed) {
      const Index nv = slot.violated.sum();
      MapM E = slot.E.mat(me + nv + n_absorbed, r);
      if (me) E.topRows(me) = Ak;
      double cmax = 0.0;
      for (Index i = 0, j = me; i < mi; ++i) {
        if (!slot.violated(i)) continue;
        if (Z)
          E.row(j).noalias() = lv.C.row(i) * Zm;
        else
          E.row(j) = lv.C.row(i);
        cmax = std::max(cmax, lv.C.row(i).cwiseAbs().maxCoeff());
        ++j;
      }
      for (Index i = 0, j = me + nv; i < p && n_absorbed; ++i) {
        if (!absorbed(i)) continue;
        if (Z)
          E.row(j).noalias() = G.row(i) * Zm;
        else
          E.row(j) = G.row(i);
        cmax = std::max(cmax, G.row(i).cwiseAbs().maxCoeff());
        ++j;
      }
      slot.null_qr.compute(E, rank_tol, std::max(lv.a_scale, cmax));
      null = Null::kViolated;
    } else if (deferred) {
      if (lv.kind == LevelKind::kNorm) {
        null = Null::kEmpty;
      } else if (me) {
        if (!slot.has_fact) slot.fact.compute(Ak, rank_tol, lv.a_scale);
        slot.has_fact = true;
        null = Null::kFact;
      } else {
        null = Null::kNone;
      }
    }
    x_ = slot.xl;
    if (null != Null::kNone) {
      if (null == Null::kEmpty) {
        slot.Z.mat(n, 0);
      } else {
        PivotedQR& f = null == Null::kFact ? slot.fact : slot.null_qr;
        if (f.rank() >= r) {
          slot.Z.mat(n, 0);  // nothing left free
        } else if (Z && f.rank() == 0) {
          slot.Z.mat(n, r) = Zm;  // the same set
        } else if (Z) {
          // Z N = (Z Q)[:, rank:]: the reflectors applied to Z from the right, cheaper than
          // forming N and multiplying (n r rank against n r (r - rank) products)
          const Index c = r - f.rank();
          MapM W = slot.Z.mat(n, r);
          W = Zm;
          f.apply_q_right(W);
          if (c < r && c > 0)
            std::memmove(slot.Z.data(), slot.Z.data() + n * (r - c), sizeof(double) * n * c);
          slot.Z.mat(n, c);
        } else {
          const CMapM N = f.null();
          MapM Zn = slot.Z.mat(n, N.cols());
          Zn = N;
        }
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
  const MapM Ak = slot.Ak.mat();
  const Index r = Ak.cols();
  if (m > r) return 0.0;
  double scale = lv.a_scale;
  const double* s_data;
  Index s_size;
  if (n_act) {
    MapM Msig = slot.Msig.mat(m, r);
    if (me) Msig.topRows(me) = Ak;
    double cmax = 0.0;
    for (Index i = 0, j = me; i < out.state.size(); ++i) {
      if (!out.state(i)) continue;
      if (slot.Zb)
        Msig.row(j).noalias() = lv.C.row(i) * slot.Zb->mat();
      else
        Msig.row(j) = lv.C.row(i);
      cmax = std::max(cmax, lv.C.row(i).cwiseAbs().maxCoeff());
      ++j;
    }
    scale = std::max(scale, cmax);
    const CMapV sv = slot.sv.compute(Msig, settings_.rank_tol, scale);
    s_data = sv.data();
    s_size = sv.size();
  } else if (slot.has_fact) {
    MapV sv = slot.svals.vec(std::min(slot.fact.rows(), slot.fact.cols()));
    slot.fact.singular_values(sv, settings_.rank_tol, scale);
    s_data = sv.data();
    s_size = sv.size();
  } else {
    const CMapV sv = slot.sv.compute(Ak, settings_.rank_tol, scale);
    s_data = sv.data();
    s_size = sv.size();
  }
  const CMapV s(s_data, s_size);
  const double s0 = s.size() ? s(0) : 0.0;
  return mth_singular(s, m, r, settings_.rank_tol * std::max(s0, scale));
}

}  // namespace hqp
