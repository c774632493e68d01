// The null-space torque law in the native core; see law.hpp.
#include "control/law.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hqp {

namespace {

constexpr double kTiny = std::numeric_limits<double>::min();  // np.finfo(float).tiny
constexpr double kMachineEps = std::numeric_limits<double>::epsilon();
constexpr unsigned kThin = Eigen::ComputeThinU | Eigen::ComputeThinV;

/// Sized (rows, cols): a resize only where the shape changes.
void shape(MatrixXd& A, Index rows, Index cols) {
  if (A.rows() != rows || A.cols() != cols) A.resize(rows, cols);
}
void shape(VectorXd& v, Index n) {
  if (v.size() != n) v.resize(n);
}

/// Minimum-norm least squares from a thin SVD (numpy.linalg.lstsq's default cut:
/// singular values at most eps * max(rows, cols) * s_max are zero), into y; `tmp` (>= rank).
void svd_lstsq(const Eigen::JacobiSVD<MatrixXd>& svd, const CVecRef& rhs, VecRef y,
               VecRef tmp) {
  const VectorXd& s = svd.singularValues();
  const double cut = kMachineEps * double(std::max(svd.rows(), svd.cols())) * (s.size() ? s(0) : 0.0);
  Index rank = 0;
  while (rank < s.size() && s(rank) > cut) ++rank;
  y.setZero();
  if (rank == 0) return;
  VecRef t = tmp.head(rank);
  t.noalias() = svd.matrixU().leftCols(rank).transpose() * rhs;
  t.array() /= s.head(rank).array();
  y.noalias() = svd.matrixV().leftCols(rank) * t;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// SymmetricEigen

void SymmetricEigen::reserve(Index n) {
  mat_.reserve(n, n);
  vec_.reserve(n, n);
  diag_.reserve(n);
  sub_.reserve(n);
  hc_.reserve(n);
  ws_.reserve(n);
}

bool SymmetricEigen::compute(const CMatRef& A, bool vectors) {
  const Index n = A.rows();
  MapV diag = diag_.vec(n);
  MapM Q = vec_.mat(n, vectors ? n : 0);
  if (n == 0) return true;
  if (n == 1) {
    diag(0) = A(0, 0);
    if (vectors) Q(0, 0) = 1.0;
    return true;
  }
  MapM mat = mat_.mat(n, n);
  mat = A.triangularView<Eigen::Lower>();
  double scale = mat.cwiseAbs().maxCoeff();
  if (scale == 0.0) scale = 1.0;
  mat.triangularView<Eigen::Lower>() /= scale;
  MapV sub = sub_.vec(n - 1);
  MapV hc = hc_.vec(n - 1);
  Eigen::internal::tridiagonalization_inplace(mat, hc);
  diag = mat.diagonal();
  sub = mat.diagonal<-1>();
  if (vectors) {
    MapV ws = ws_.vec(n);
    Eigen::HouseholderSequence<MapM, MapV>(mat, hc).setLength(n - 1).setShift(1).evalTo(Q, ws);
  }
  constexpr int kMaxIterations = Eigen::SelfAdjointEigenSolver<MatrixXd>::m_maxIterations;
  const Eigen::ComputationInfo info =
      Eigen::internal::computeFromTridiagonal_impl(diag, sub, kMaxIterations, vectors, Q);
  diag *= scale;
  return info == Eigen::Success;
}

// ---------------------------------------------------------------------------------------
// NullSpaceLaw: prioritized_torques(method="whitened")

NullSpaceLaw::NullSpaceLaw(Index nv, Index nv_base)
    : nv_(nv), nv_base_(nv_base), na_(nv - nv_base) {
  if (nv <= 0 || nv_base < 0 || nv_base >= nv)
    throw LawError("null-space law: expected nv > 0 and 0 <= nv_base < nv");
  tau_.setZero(na_);
  tau_int_.setZero(na_);
  qdd_.setZero(nv_);
  qdd0_.setZero(nv_);
  gen_.setZero(nv_);
  h_.setZero(nv_);
  eig_phi_.reserve(na_);
  gram_.reserve(nv_);
}

Index NullSpaceLaw::sym_pinv(const MatrixXd& A, double rel_tol, MatrixXd& pinv) {
  // _sym_pinv: eigenvalues above rel_tol times the largest are inverted
  const Index m = A.rows();
  shape(pinv, m, m);
  if (m == 0) return 0;
  eig_s_.reserve(m);
  MapM G = gwork_.mat(m, m);
  G = A;
  G += A.transpose();
  G *= 0.5;
  eig_s_.compute(G, true);
  CMapV w = eig_s_.values();
  CMapM U = eig_s_.vectors();
  double threshold = rel_tol * std::max(w(m - 1), 0.0);
  if (threshold <= 0.0) threshold = kTiny;
  Index keep = 0;
  while (keep < m && w(m - 1 - keep) > threshold) ++keep;
  MapM Uw = uw_.mat(m, keep);
  Uw.noalias() = U.rightCols(keep) * w.tail(keep).cwiseInverse().asDiagonal();
  pinv.noalias() = Uw * U.rightCols(keep).transpose();
  return keep;
}

std::string NullSpaceLaw::dynamics(const CMatRef& M, const CVecRef& h, const CMatRef& Js,
                                   const CVecRef& bs) {
  if (M.rows() != nv_ || M.cols() != nv_ || h.size() != nv_ || Js.cols() != nv_ ||
      bs.size() != Js.rows())
    throw LawError("null-space law: M (nv, nv), h (nv,), J_s (ns, nv), b_s (ns,) expected");
  ns_ = Js.rows();
  plain_ = ns_ == 0 && nv_base_ == 0;
  h_ = h;
  shape(Js_, ns_, nv_);
  Js_ = Js;
  shape(bs_, ns_);
  bs_ = bs;
  // M = R^T R
  llt_.compute(M);
  if (llt_.info() != Eigen::Success) return "M is not positive definite";
  shape(R_, nv_, nv_);
  R_ = llt_.matrixU();
  shape(Rinv_, nv_, nv_);
  Rinv_.setIdentity();
  R_.triangularView<Eigen::Upper>().solveInPlace(Rinv_);
  shape(Minv_, nv_, nv_);
  Minv_.noalias() = Rinv_ * Rinv_.transpose();
  if (ns_) {
    shape(MinvJsT_, nv_, ns_);
    MinvJsT_.noalias() = Minv_ * Js.transpose();
    shape(Ls_inv_, ns_, ns_);
    Ls_inv_.noalias() = Js * MinvJsT_;
    ns_rank_ = sym_pinv(Ls_inv_, kPhiTol, Lambda_s_);
    shape(Jbar_s_, nv_, ns_);
    Jbar_s_.noalias() = MinvJsT_ * Lambda_s_;
    // N_s M^-1 = M^-1 - Jbar_s J_s M^-1 (= M^-1 N_s^T): B = N_s M^-1 S^T, without N_s
    shape(B_, nv_, na_);
    B_ = Minv_.rightCols(na_);
    B_.noalias() -= Jbar_s_ * MinvJsT_.bottomRows(na_).transpose();
    // qdd0 = -N_s M^-1 h + Jbar_s b_s
    shape(u_, ns_);
    u_ = bs;
    u_.noalias() += MinvJsT_.transpose() * h;
    qdd0_.noalias() = -Minv_ * h;
    qdd0_.noalias() += Jbar_s_ * u_;
  } else {
    ns_rank_ = 0;
    shape(Lambda_s_, 0, 0);
    shape(B_, nv_, na_);
    B_ = Minv_.rightCols(na_);
    qdd0_.noalias() = -Minv_ * h;
  }
  shape(Phi_, na_, na_);
  Phi_ = B_.bottomRows(na_);
  Phi_ += B_.bottomRows(na_).transpose();
  Phi_ *= 0.5;
  shape(Phi_pinv_, na_, na_);
  if (plain_) {  // fixed base: Phi = M^-1 = R^-1 R^-T, whitening by the Cholesky factor
    Phi_pinv_ = M;
    r_ = nv_;
    nint_ = 0;
    shape(Wh_, nv_, nv_);
    Wh_ = Rinv_;
    shape(Tm_, nv_, nv_);
    Tm_ = R_.transpose();
    shape(Zint_, na_, 0);
    return std::string();
  }
  // Phi = U diag(w) U^T (ascending): the kept eigenvalues are the last r
  if (!eig_phi_.compute(Phi_, true)) return "no convergence of the eigenvalues of Phi";
  CMapV w = eig_phi_.values();
  CMapM U = eig_phi_.vectors();
  const double threshold = kPhiTol * std::max(w(na_ - 1), 0.0);
  r_ = 0;
  while (r_ < na_ && w(na_ - 1 - r_) > threshold) ++r_;
  nint_ = na_ - r_;
  shape(Tm_, na_, r_);
  Tm_.noalias() = U.rightCols(r_) * w.tail(r_).cwiseSqrt().cwiseInverse().asDiagonal();
  Phi_pinv_.noalias() = Tm_ * Tm_.transpose();  // U_r diag(1 / w_r) U_r^T
  shape(Wh_, nv_, r_);
  Wh_.noalias() = B_ * Tm_;
  shape(Zint_, na_, nint_);
  Zint_ = U.leftCols(nint_);
  return std::string();
}

void NullSpaceLaw::solve(const CMatRef& J, const CVecRef& a, const Index* starts,
                         Index n_levels, double eig_tol) {
  if (J.cols() != nv_ || a.size() != J.rows())
    throw LawError("null-space law: level rows J (m, nv) and a (m,) expected");
  const Index r = r_;
  const Index rows = J.rows();
  shape(eig_, rows);
  shape(F_, rows);
  shape(res_, rows);
  shape(resid_, rows);
  shape(coef_, r);
  shape(y_, r);
  shape(ytmp_, r);
  y_.setZero();
  if (Index(Z_.size()) < n_levels + 1) {
    Z_.resize(std::size_t(n_levels + 1));
    T_.resize(std::size_t(n_levels));
    svd_.resize(std::size_t(n_levels));
  }
  info_.resize(std::size_t(n_levels));  // (capacity kept: no allocation once grown)
  basis_cols_.resize(std::size_t(n_levels + 1));
  for (MatrixXd& Z : Z_) shape(Z, r, r);
  Z_[0].setIdentity();
  basis_cols_[0] = r;
  shape(Jh_, std::max<Index>(rows, 1), r);
  for (Index k = 0; k < n_levels; ++k) {
    LawLevelInfo& info = info_[std::size_t(k)];
    const Index start = starts[k], m = starts[k + 1] - starts[k];
    const Index d = basis_cols_[std::size_t(k)];
    info = LawLevelInfo{start, m, 0, d, 0.0, 0.0};
    const CMatRef Zk = Z_[std::size_t(k)].topLeftCorner(r, d);
    MatRef Znext = Z_[std::size_t(k + 1)].topLeftCorner(r, d);
    if (m == 0) {
      Znext = Zk;
      basis_cols_[std::size_t(k + 1)] = d;
      continue;
    }
    const CMatRef Jk = J.middleRows(start, m);
    const CVecRef ak = a.segment(start, m);
    info.target_norm = ak.norm();
    MatRef Jh = Jh_.topRows(m);
    Jh.noalias() = Jk * Wh_.leftCols(r);
    // ref: the largest eigenvalue of J* Phi J*^T = Jh Jh^T (eq. 22's scale)
    const Index g = std::min(m, r);
    MapM G = gwork_.mat(g, g);
    if (m <= r) {
      G.noalias() = Jh * Jh.transpose();
    } else {
      G.noalias() = Jh.transpose() * Jh;
    }
    double ref = 0.0;
    if (g > 0) {
      gram_.compute(G, false);
      ref = gram_.values()(g - 1);
    }
    info.threshold = std::max(eig_tol * ref, kTiny);
    VecRef resid = resid_.head(m);
    resid = ak;
    resid.noalias() -= Jk * qdd0_;
    resid.noalias() -= Jh * y_;  // a_k - J_k qdd_<k
    VecRef eig = eig_.segment(start, m);
    VecRef F = F_.segment(start, m);
    eig.setZero();
    F.setZero();
    if (d == 0) {
      basis_cols_[std::size_t(k + 1)] = 0;
      continue;
    }
    MatrixXd& T = T_[std::size_t(k)];
    shape(T, m, d);
    T.noalias() = Jh * Zk;
    Eigen::JacobiSVD<MatrixXd>& svd = svd_[std::size_t(k)];
    svd.compute(T, Eigen::ComputeThinU | Eigen::ComputeFullV);
    const VectorXd& s = svd.singularValues();
    const Index p = s.size();
    eig.head(p) = s.array().square().matrix();  // eq. 22: eigenvalues of Lambda^-1
    Index rank = 0;
    while (rank < p && eig(rank) > info.threshold) ++rank;
    info.rank = rank;
    if (rank) {
      VecRef coef = coef_.head(rank);
      coef.noalias() = svd.matrixU().leftCols(rank).transpose() * resid;
      coef.array() /= s.head(rank).array();
      ytmp_.head(rank) = coef.array() / s.head(rank).array();
      F.noalias() = svd.matrixU().leftCols(rank) * ytmp_.head(rank);  // eq. 23
      VecRef Vc = ytmp_.head(d);
      Vc.noalias() = svd.matrixV().leftCols(rank) * coef;
      y_.noalias() += Zk * Vc;  // L^T tau_k = J^_k|p^T F_k (eq. 20)
    }
    MatRef Zn = Z_[std::size_t(k + 1)].topLeftCorner(r, d - rank);
    Zn.noalias() = Zk * svd.matrixV().rightCols(d - rank);  // eq. 19
    basis_cols_[std::size_t(k + 1)] = d - rank;
  }
  tau_.noalias() = Tm_ * y_;
}

void NullSpaceLaw::finish(const CMatRef& J, const CVecRef& a, bool min_norm) {
  tau_int_.setZero();
  if (ns_) shape(f_, ns_);
  else shape(f_, 0);
  if (min_norm && ns_ && nint_) {
    // f(tau) = Lambda_s (b_s - J_s M^-1 (S^T tau - h)); d f / d tau = -Lambda_s J_s M^-1 S^T
    shape(DfU_, ns_, na_);
    DfU_.noalias() = -Lambda_s_ * MinvJsT_.bottomRows(na_).transpose();
    shape(Df_, ns_, nint_);
    Df_.noalias() = DfU_ * Zint_;
    gen_ = -h_;
    gen_.tail(na_) += tau_;
    shape(u_, ns_);
    u_ = bs_;
    u_.noalias() -= MinvJsT_.transpose() * gen_;
    shape(fplain_, ns_);
    fplain_.noalias() = Lambda_s_ * u_;
    fplain_ = -fplain_;
    svd_int_.compute(Df_, kThin);
    shape(yint_, nint_);
    shape(tmp_int_, nint_);
    svd_lstsq(svd_int_, fplain_, yint_, tmp_int_);
    tau_int_.noalias() = Zint_ * yint_;
    tau_ += tau_int_;
  }
  qdd_ = qdd0_;
  qdd_.noalias() += B_ * tau_;
  if (ns_) {
    gen_ = -h_;
    gen_.tail(na_) += tau_;
    shape(u_, ns_);
    u_ = bs_;
    u_.noalias() -= MinvJsT_.transpose() * gen_;
    f_.noalias() = Lambda_s_ * u_;
  }
  for (const LawLevelInfo& info : info_) {
    if (!info.rows) continue;
    VecRef res = res_.segment(info.start, info.rows);
    res.noalias() = J.middleRows(info.start, info.rows) * qdd_;
    res -= a.segment(info.start, info.rows);
  }
}

// ---------------------------------------------------------------------------------------
// JointLimitZoneKernel

void JointLimitZoneKernel::update(const Eigen::Ref<const Eigen::VectorXd>& q,
                                  const Eigen::Ref<const Eigen::VectorXd>& v) {
  const Index na = q.size();
  if (active.size() != na) {
    active.resize(na);
    error.resize(na);
    ref.resize(na);
  }
  count = 0;
  for (Index i = 0; i < na; ++i) {
    const bool upper = q(i) > high_edge(i);
    const bool lower = q(i) < low_edge(i);
    if (!(upper || lower)) continue;
    active(count) = int(i);
    error(count) = (upper ? high_safe(i) : low_safe(i)) - q(i);
    ++count;
  }
  double speed2 = 0.0;
  for (Index j = 0; j < count; ++j) {
    const double vd = (kp / kv) * error(j);
    speed2 += vd * vd;
  }
  const double speed = std::sqrt(speed2);
  const double nu = speed <= max_velocity ? 1.0 : max_velocity / speed;
  for (Index j = 0; j < count; ++j) {
    const double vd = (kp / kv) * error(j);
    ref(j) = -kv * (v(active(j)) - nu * vd);
  }
}

// ---------------------------------------------------------------------------------------
// NativeLaw

NativeLaw::NativeLaw(NativeStep& step, const LawSettings& settings)
    : step_(step), settings_(settings), nv_(step.robot().nv()), nv_base_(step.nv_base()),
      na_(step.robot().nv() - step.nv_base()), n_(step.n()),
      law_(step.robot().nv(), step.nv_base()) {
  if (!(settings.eig_tol > 0.0 && settings.eig_tol < 1.0))
    throw LawError("null-space law: eig_tol must be in (0, 1)");
}

void NativeLaw::add_level(bool physics) {
  phys_.push_back(physics);
  laid_out_ = false;
}

int NativeLaw::add_entry(int level, int handle, Index slot_start) {
  if (level < 0 || level >= int(phys_.size())) throw LawError("law: level out of range");
  if (handle < 0 || handle >= step_.entry_count()) throw LawError("law: no such entry");
  Source s{level, handle, -1, 1.0};
  s.slot_start = slot_start;
  sources_.push_back(s);
  laid_out_ = false;
  return int(sources_.size()) - 1;
}

int NativeLaw::add_zone(int level, double weight, const JointLimitZoneKernel& kernel) {
  if (level < 0 || level >= int(phys_.size())) throw LawError("law: level out of range");
  if (!(weight > 0.0) || !std::isfinite(weight)) throw LawError("law: weight must be > 0");
  for (const Eigen::VectorXd* e : {&kernel.low_edge, &kernel.high_edge, &kernel.low_safe,
                                   &kernel.high_safe}) {
    if (e->size() != na_) throw LawError("joint-limit zone: one value per actuated joint");
  }
  if (!(kernel.kp > 0.0 && kernel.kv > 0.0 && kernel.max_velocity > 0.0))
    throw LawError("joint-limit zone: kp, kv and max_velocity must be > 0");
  zones_.push_back(kernel);
  zones_.back().update(Eigen::VectorXd::Zero(na_), Eigen::VectorXd::Zero(na_));  // sized
  Source s{level, -1, int(zones_.size()) - 1, std::sqrt(weight)};
  sources_.push_back(s);
  laid_out_ = false;
  return int(sources_.size()) - 1;
}

const JointLimitZoneKernel& NativeLaw::zone(int s) const {
  if (s < 0 || s >= int(sources_.size()) || sources_[std::size_t(s)].zone < 0)
    throw LawError("law: not a joint-limit zone source");
  return zones_[std::size_t(sources_[std::size_t(s)].zone)];
}

void NativeLaw::lay_out() {
  // called after the NativeStep laid out its levels (its first rows())
  Index eq = 0, slots = 0;
  for (Source& s : sources_) {
    if (s.handle >= 0) {
      s.info = step_.entry(s.handle);
      s.sqrt_w = s.info.sqrt_w;
      if (s.info.level != s.level) throw LawError("law: an entry's level differs from the step's");
      eq += s.info.neq;
      if (s.slot_start >= 0) slots += s.info.neq;
    } else {
      eq += na_;
    }
  }
  order_.clear();
  for (int k = 0; k < int(phys_.size()); ++k) {
    for (int i = 0; i < int(sources_.size()); ++i) {
      if (sources_[std::size_t(i)].level == k) order_.push_back(i);
    }
  }
  const Index cap = std::max<Index>(eq, 1);
  J_.setZero(cap, nv_);
  a_.setZero(cap);
  Js_.setZero(cap, nv_);
  bs_.setZero(cap);
  Jf_.setZero(nv_, std::max<Index>(slots, 1));
  wf_.setZero(std::max<Index>(slots, 1));
  gen_.setZero(nv_);
  x_.setZero(n_);
  starts_.assign(phys_.size() + 2, 0);
  law_stack_level_.assign(phys_.size() + 1, -1);
  level_rows_.assign(phys_.size(), 0);
  level_cost_.assign(phys_.size(), 0.0);
  results_.assign(sources_.size(), SourceResult{});
  active_slots_.clear();
  active_slots_.reserve(sources_.size());
  s_.setZero(std::max<Index>(cap, nv_));
  Index in = 0;
  for (const Source& s : sources_) in = std::max(in, s.info.nin);
  if (in > s_.size()) s_.setZero(in);
  gram_.reserve(std::max<Index>(cap, nv_));
  P_.reserve(cap, nv_);
  Pz_.reserve(cap, nv_);
  Ph_.reserve(std::max<Index>(cap, nv_), std::max<Index>(cap, nv_));
  laid_out_ = true;
}

void NativeLaw::assemble() {
  const RobotCore& robot = step_.robot();
  m_ = 0;
  ns_ = 0;
  nf_ = 0;
  active_slots_.clear();
  support_is_contacts_ = true;
  std::fill(level_rows_.begin(), level_rows_.end(), Index(0));
  Index L = 0;
  starts_[0] = 0;
  std::size_t pos = 0;
  for (int k = 0; k < int(phys_.size()); ++k) {
    const bool physics = phys_[std::size_t(k)];
    const Index level_start = m_;
    for (; pos < order_.size() && sources_[std::size_t(order_[pos])].level == k; ++pos) {
      const int si = order_[pos];
      const Source& s = sources_[std::size_t(si)];
      SourceResult& res = results_[std::size_t(si)];
      res = SourceResult{};
      res.start = physics ? ns_ : m_;
      if (s.zone >= 0) {
        JointLimitZoneKernel& z = zones_[std::size_t(s.zone)];
        z.update(robot.q().tail(na_), robot.v().tail(na_));
        level_rows_[std::size_t(k)] += z.count;
        res.present = z.count > 0;
        if (physics && z.count) support_is_contacts_ = false;
        MatrixXd& J = physics ? Js_ : J_;
        VectorXd& b = physics ? bs_ : a_;
        Index& m = physics ? ns_ : m_;
        for (Index j = 0; j < z.count; ++j) {
          J.row(m).setZero();
          J(m, nv_base_ + z.active(j)) = s.sqrt_w;
          b(m) = s.sqrt_w * z.ref(j);
          ++m;
        }
        res.count = z.count;
        continue;
      }
      const NativeStep::EntryInfo& e = s.info;
      res.present = e.neq + e.nin > 0;
      level_rows_[std::size_t(k)] += e.neq + e.nin;
      if (e.neq == 0) continue;
      const LevelData& lv = step_.level(e.built_level);
      const Index support_start = ns_;
      bool all_qdd = true;
      for (Index i = 0; i < e.neq; ++i) {
        const Index row = e.eq0 + i;
        bool qdd_only = true;
        for (Index c = nv_; c < n_; ++c) {
          if (lv.A(row, c) != 0.0) {
            qdd_only = false;
            break;
          }
        }
        if (!qdd_only) {
          all_qdd = false;
          if (!physics) res.force_rows = true;
          continue;
        }
        if (physics) {
          Js_.row(ns_) = lv.A.row(row).head(nv_);
          bs_(ns_++) = lv.b(row);
        } else {
          J_.row(m_) = lv.A.row(row).head(nv_);
          a_(m_++) = lv.b(row);
        }
        ++res.count;
      }
      const bool active_contact = s.slot_start >= 0 && all_qdd;
      if (physics && ns_ > support_start && !active_contact) support_is_contacts_ = false;
      if (active_contact) {  // J_c^T columns
        Jf_.middleCols(nf_, e.neq) = lv.A.middleRows(e.eq0, e.neq).leftCols(nv_).transpose();
        Jf_.middleCols(nf_, e.neq) /= s.sqrt_w;
        active_slots_.push_back({s.slot_start, e.neq, physics ? support_start : -1, s.sqrt_w});
        if (!physics) support_is_contacts_ = false;
        nf_ += e.neq;
      }
    }
    if (!physics && m_ > level_start) {
      law_stack_level_[std::size_t(L)] = k;
      starts_[std::size_t(++L)] = m_;
      for (std::size_t p = 0; p < pos; ++p) {
        const int si = order_[p];
        if (sources_[std::size_t(si)].level == k && results_[std::size_t(si)].count > 0)
          results_[std::size_t(si)].law_level = int(L - 1);
      }
    }
  }
  law_levels_ = L;
}

std::string NativeLaw::step(const Eigen::Ref<const Eigen::VectorXd>& q,
                            const Eigen::Ref<const Eigen::VectorXd>& v, double dt) {
  std::string error = step_.rows(q, v, dt);
  if (!error.empty()) return error;
  if (!laid_out_) lay_out();
  assemble();
  if (!J_.topRows(m_).allFinite() || !a_.head(m_).allFinite() ||
      !Js_.topRows(ns_).allFinite() || !bs_.head(ns_).allFinite())
    return "non-finite law rows";
  const RobotCore& robot = step_.robot();
  error = law_.dynamics(robot.M(), robot.h(), Js_.topRows(ns_), bs_.head(ns_));
  if (!error.empty()) return error;
  law_.solve(J_.topRows(m_), a_.head(m_), starts_.data(), law_levels_, settings_.eig_tol);
  law_.finish(J_.topRows(m_), a_.head(m_), settings_.min_norm);
  if (!law_.tau().allFinite() || !law_.qdd().allFinite() || !law_.f().allFinite())
    return "law returned non-finite values";
  decision_vector();
  report();
  return std::string();
}

void NativeLaw::decision_vector() {
  // decision_vector: x = [qdd | wrenches], the support forces mapped to the active slots by
  // the least-squares solution of [J_c^T ...] w = J_s^T f
  x_.setZero();
  x_.head(nv_) = law_.qdd();
  if (ns_ == 0 || nf_ == 0) return;
  if (support_is_contacts_ && nf_ == ns_ && law_.support_rank() == ns_) {
    // J_s = diag(sqrt w) J_c of full row rank: w_c = sqrt(w_c) f_c is the unique solution
    // (rank at PHI_TOL on J_s M^-1 J_s^T: far above numpy's lstsq cut)
    for (const ActiveSlot& slot : active_slots_) {
      x_.segment(slot.start, slot.size) = slot.sqrt_w * law_.f().segment(slot.row, slot.size);
    }
    return;
  }
  gen_.noalias() = Js_.topRows(ns_).transpose() * law_.f();
  shape(Jfa_, nv_, nf_);
  Jfa_ = Jf_.leftCols(nf_);
  svd_f_.compute(Jfa_, kThin);
  VecRef w = wf_.head(nf_);
  svd_lstsq(svd_f_, gen_, w, s_.head(nf_));
  Index start = 0;
  for (const ActiveSlot& slot : active_slots_) {
    x_.segment(slot.start, slot.size) = w.segment(start, slot.size);
    start += slot.size;
  }
}

void NativeLaw::report() {
  // per source: the unweighted residual of its rows at x (equalities and inequality
  // violations); per stack level: the cost of its weighted rows (Diagnostics, level_cost)
  std::fill(level_cost_.begin(), level_cost_.end(), 0.0);
  const VectorXd& qdd = law_.qdd();
  for (std::size_t i = 0; i < sources_.size(); ++i) {
    const Source& s = sources_[i];
    SourceResult& res = results_[i];
    double sq = 0.0;
    if (s.zone >= 0) {
      const JointLimitZoneKernel& z = zones_[std::size_t(s.zone)];
      for (Index j = 0; j < z.count; ++j) {
        const double r = s.sqrt_w * (qdd(nv_base_ + z.active(j)) - z.ref(j));
        sq += r * r;
      }
    } else if (s.info.neq + s.info.nin > 0) {
      const LevelData& lv = step_.level(s.info.built_level);
      const NativeStep::EntryInfo& e = s.info;
      if (e.neq) {
        VecRef r = s_.head(e.neq);
        r.noalias() = lv.A.middleRows(e.eq0, e.neq) * x_;
        r -= lv.b.segment(e.eq0, e.neq);
        sq += r.squaredNorm();
      }
      if (e.nin) {
        VecRef c = s_.head(e.nin);
        c.noalias() = lv.C.middleRows(e.in0, e.nin) * x_;
        for (Index j = 0; j < e.nin; ++j) {
          const double cx = c(j), lo = lv.lo(e.in0 + j), up = lv.up(e.in0 + j);
          const double viol = cx < lo ? cx - lo : (cx > up ? cx - up : 0.0);
          sq += viol * viol;
        }
      }
    }
    level_cost_[std::size_t(s.level)] += sq;
    res.residual = std::sqrt(sq) / s.sqrt_w;
    res.eig_min = std::numeric_limits<double>::quiet_NaN();
    res.singular = false;
    if (res.law_level >= 0) {  // the smallest eigenvalue of its level (eq. 22)
      const LawLevelInfo& info = law_.level(res.law_level);
      res.eig_min = law_.eigenvalues()(info.start + info.rows - 1);
    }
  }
}

void NativeLaw::diagnose(double singular_tolerance) {
  // Diagnostics.law_statuses ("full"): eigvalsh of (J W Z_k)(J W Z_k)^T with the task's
  // unweighted rows J; its largest unprojected eigenvalue ||J W||_2^2
  const Index r = law_.rank();
  for (std::size_t i = 0; i < sources_.size(); ++i) {
    SourceResult& res = results_[i];
    if (res.law_level < 0 || res.count == 0) continue;
    const double w = sources_[i].sqrt_w * sources_[i].sqrt_w;
    const Index m = res.count;
    MapM P = P_.mat(m, r);
    P.noalias() = J_.middleRows(res.start, m) * law_.whiten();
    const Index g = std::min(m, r);
    MapM Ph = Ph_.mat(g, g);
    if (m <= r) Ph.noalias() = P * P.transpose();
    else Ph.noalias() = P.transpose() * P;
    double ref = 0.0;
    if (g) {
      gram_.compute(Ph, false);
      ref = gram_.values()(g - 1) / w;
    }
    const CMatRef Z = law_.basis(res.law_level);
    MapM Pz = Pz_.mat(m, Z.cols());
    Pz.noalias() = P * Z;
    MapM Pp = Ph_.mat(m, m);
    Pp.noalias() = Pz * Pz.transpose();
    gram_.compute(Pp, false);
    const double eig_min = std::max(gram_.values()(0) / w, 0.0);
    res.eig_min = eig_min;
    res.singular = eig_min < singular_tolerance * ref;
  }
}

}  // namespace hqp
