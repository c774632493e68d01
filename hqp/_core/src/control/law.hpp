// The papers' prioritised null-space torque law in the native core: the C++ twin of
// hqp.control.nullspace.law.prioritized_torques (method="whitened", internal forces "none"
// or "min-norm"; seed 003 eq. 11-23 with the support-consistent form of Sentis, Park and
// Khatib 2010, derivation in docs/design/nullspace.md), and the law's control step (NativeLaw):
// the rows of a NativeStep's kernels (its model pass, no solve), the papers' joint-limit
// activation zones (hqp.tasks.joint_limit_zone), the law, x = [qdd | f] and the report's
// numbers, in one call.
//
// Structure and workspace apart: the shapes (nv, the actuated joints, the levels and their
// sources) are fixed when the step is built; the workspace (factorisations, bases, stacked
// rows) is sized by the first step and reused. A step allocates nothing on the heap while
// the shapes of its levels hold (the active contacts, the joints inside their zones, the
// ranks the law decides); a new shape resizes the workspace once.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <stdexcept>
#include <string>
#include <vector>

#include "control/step.hpp"
#include "solver/linalg.hpp"

namespace hqp {

/// PHI_TOL: relative threshold for the rank of Phi and of Lambda_s^-1.
constexpr double kPhiTol = 1e-10;

/// A malformed law input (raised as hqp.errors.InvalidInput).
class LawError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Eigen 3.4's SelfAdjointEigenSolver::compute (lower triangle read; the same scaling,
/// tridiagonalisation, Householder Q and QR iterations) on this object's fixed-capacity
/// storage: no heap allocation for any shape within the capacity (Eigen's own solver
/// allocates a workspace at each call with eigenvectors).
class SymmetricEigen {
 public:
  void reserve(Index n);
  /// Eigenvalues ascending (and eigenvectors as columns when `vectors`); false where the QR
  /// iteration did not converge.
  bool compute(const CMatRef& A, bool vectors);
  CMapV values() const { return diag_.vec(); }
  CMapM vectors() const { return vec_.mat(); }

 private:
  WorkM mat_, vec_, diag_, sub_, hc_, ws_;
};

/// What the law did on one level (hqp.control.nullspace.law.LawLevel): its rows are
/// [start, start + rows) of the stacked rows given to NullSpaceLaw::solve.
struct LawLevelInfo {
  Index start = 0, rows = 0;
  Index rank = 0;
  Index free = 0;  ///< columns of the whitened basis Z_k left by the levels above
  double threshold = 0.0, target_norm = 0.0;
};

/// The law on plain matrices, M qdd + h = S^T tau + J_s^T f with S = [0 I] (the last na of
/// nv velocities actuated; S = I when nv_base = 0).
///
/// Three calls: dynamics() (Cholesky of M, the support-consistent Phi and its
/// eigen-decomposition), solve() (eq. 14-23 level after level in whitened coordinates; may be
/// called again with other levels, the activation zones' passes) and finish() (internal
/// forces, qdd, f, residuals).
class NullSpaceLaw {
 public:
  NullSpaceLaw(Index nv, Index nv_base);

  /// Support-consistent dynamics from M (nv, nv), h (nv,), the support rows J_s (ns, nv) and
  /// their targets b_s (ns,). Returns an error ("" on success): M not positive definite.
  std::string dynamics(const CMatRef& M, const CVecRef& h, const CMatRef& Js,
                       const CVecRef& bs);
  /// The levels, highest first: level k is the rows [starts[k], starts[k+1]) of J (rows, nv)
  /// and a (rows,). Fills the per-level report and the torques of the plain law.
  void solve(const CMatRef& J, const CVecRef& a, const Index* starts, Index n_levels,
             double eig_tol);
  /// Internal forces (min_norm: the torque in null(Phi) giving the least-norm support
  /// forces), then qdd, f and each level's residual J qdd - a.
  void finish(const CMatRef& J, const CVecRef& a, bool min_norm);

  Index nv() const { return nv_; }
  Index na() const { return na_; }
  Index ns() const { return ns_; }
  Index rank() const { return r_; }  ///< rank of Phi
  Index support_rank() const { return ns_rank_; }  ///< rank of Lambda_s^-1 (PHI_TOL)
  bool plain() const { return plain_; }
  const VectorXd& tau() const { return tau_; }
  const VectorXd& tau_internal() const { return tau_int_; }
  const VectorXd& qdd() const { return qdd_; }
  const VectorXd& f() const { return f_; }
  const VectorXd& qdd0() const { return qdd0_; }
  const MatrixXd& phi() const { return Phi_; }
  const MatrixXd& phi_pinv() const { return Phi_pinv_; }
  /// B = M^-1 N_s^T S^T (nv, na): qdd = B tau + qdd0.
  const MatrixXd& torque_to_qdd() const { return B_; }
  /// W (nv, r): Lambda_k|prec(k)^-1 = (J_k W Z_k)(J_k W Z_k)^T.
  Eigen::Block<const MatrixXd, Eigen::Dynamic, Eigen::Dynamic, true> whiten() const {
    return Wh_.leftCols(r_);
  }
  Index level_count() const { return Index(info_.size()); }
  const LawLevelInfo& level(Index k) const { return info_[std::size_t(k)]; }
  /// Z_k (r, free_k), k = 0 .. level_count() (the last: after every level).
  Eigen::Block<const MatrixXd> basis(Index k) const {
    return Z_[std::size_t(k)].topLeftCorner(r_, basis_cols_[std::size_t(k)]);
  }
  /// Per row of the stacked levels: eigenvalues of Lambda^-1 (eq. 22, descending within a
  /// level, zero-padded), F (eq. 21, 23), the residual J qdd - a (after finish()).
  const VectorXd& eigenvalues() const { return eig_; }
  const VectorXd& forces() const { return F_; }
  const VectorXd& residuals() const { return res_; }

 private:
  /// Returns the number of eigenvalues kept.
  Index sym_pinv(const MatrixXd& A, double rel_tol, MatrixXd& pinv);

  Index nv_, nv_base_, na_;
  Index ns_ = 0, r_ = 0, nint_ = 0, ns_rank_ = 0;
  bool plain_ = false;
  // dynamics
  Eigen::LLT<MatrixXd> llt_;
  MatrixXd R_, Rinv_, Minv_, MinvJsT_, Ls_inv_, Lambda_s_, Jbar_s_, B_, Phi_,
      Phi_pinv_, Tm_, Wh_, Zint_, Js_, Df_, DfU_;
  VectorXd h_, bs_, qdd0_, w_;
  SymmetricEigen eig_s_, eig_phi_, gram_;
  MatrixXd G_;
  // levels
  std::vector<LawLevelInfo> info_;
  std::vector<MatrixXd> Z_, T_;
  std::vector<Index> basis_cols_;
  std::vector<Eigen::JacobiSVD<MatrixXd>> svd_;
  MatrixXd Jh_;
  VectorXd y_, resid_, coef_, eig_, F_, res_, ytmp_, tmp_int_;
  WorkM gwork_, uw_;
  // finish
  Eigen::JacobiSVD<MatrixXd> svd_int_;
  VectorXd tau_, tau_int_, qdd_, f_, fplain_, u_, yint_, gen_;
};

/// The papers' joint-limit activation zones (hqp.tasks.joint_limit_zone.JointLimitZone,
/// seed 003 eq. 25, 27-28): one row qdd_i = qdd_ref_i per actuated joint inside its zone.
struct JointLimitZoneKernel {
  Eigen::VectorXd low_edge, high_edge;  ///< q_lower + zone, q_upper - zone
  Eigen::VectorXd low_safe, high_safe;  ///< safety positions
  double kp = 100.0, kv = 20.0, max_velocity = 0.0;
  // the last step
  Eigen::VectorXi active;  ///< indices of the joints inside a zone (first `count`)
  Eigen::VectorXd error, ref;
  Index count = 0;
  /// The active joints at (q_a, v_a) (each (na,)), their errors and references.
  void update(const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& v);
};

/// Settings of the law's step.
struct LawSettings {
  double eig_tol = 1e-12;   ///< EIG_TOL
  bool min_norm = true;     ///< internal_forces "min-norm" (else "none")
};

/// The law's control step on a NativeStep's kernels (hqp.control.nullspace.native).
///
/// Sources, in the stack's order: NativeStep entries (their equality rows on qdd only at
/// a physics level are the support, elsewhere the task levels; as
/// hqp.control.nullspace.multicontact.law_problem) and joint-limit zones.
class NativeLaw {
 public:
  NativeLaw(NativeStep& step, const LawSettings& settings);

  /// One per stack level, in order: whether it is a physics level.
  void add_level(bool physics);
  /// A NativeStep entry of stack level `level` (`slot_start`: its contact slot's first
  /// column, -1 for another kernel); returns the source index.
  int add_entry(int level, int handle, Index slot_start = -1);
  /// A joint-limit zone of stack level `level` with weight `weight`; returns the source.
  int add_zone(int level, double weight, const JointLimitZoneKernel& kernel);

  /// One step at (q, v) with the period dt: "" on success, else why the law cannot run
  /// (the Python law then runs the step). No heap allocation once shapes are fixed.
  std::string step(const Eigen::Ref<const Eigen::VectorXd>& q,
                   const Eigen::Ref<const Eigen::VectorXd>& v, double dt);

  const NativeStep& native_step() const { return step_; }
  const NullSpaceLaw& law() const { return law_; }
  const LawSettings& settings() const { return settings_; }
  LawSettings& settings() { return settings_; }
  int source_count() const { return int(sources_.size()); }
  int level_count() const { return int(phys_.size()); }
  const VectorXd& x() const { return x_; }
  const VectorXd& tau() const { return law_.tau(); }

  /// Per source, at the last step: its law level (-1: none of its rows is a task row),
  /// rows [start, start + count) of the stacked law rows, whether its rows span a task of
  /// the built stack (it has rows), the unweighted residual norm at x, whether it had
  /// equality rows on the contact forces at a task level (not used by the law), and in
  /// diagnose(): eig_min (NaN: none) and whether it is singular.
  struct SourceResult {
    int law_level = -1;
    Index start = 0, count = 0;
    bool present = false;
    bool force_rows = false;
    double residual = 0.0;
    double eig_min = 0.0;
    bool singular = false;
  };
  const SourceResult& source(int s) const { return results_[std::size_t(s)]; }
  /// Per stack level at the last step: rows present, the level cost at x (weighted).
  bool level_present(int k) const { return level_rows_[std::size_t(k)] > 0; }
  double level_cost(int k) const { return level_cost_[std::size_t(k)]; }
  /// Law level k: its stack level.
  int law_level_index(int k) const { return law_stack_level_[std::size_t(k)]; }
  /// The stacked law rows (weighted, as the built levels hold them) and support rows.
  Eigen::Block<const MatrixXd> rows() const { return J_.topRows(m_); }
  Eigen::VectorBlock<const VectorXd> targets() const { return a_.head(m_); }
  Eigen::Block<const MatrixXd> support() const { return Js_.topRows(ns_); }
  Eigen::VectorBlock<const VectorXd> support_targets() const { return bs_.head(ns_); }
  /// The zone kernel of a source (its active joints, errors and references).
  const JointLimitZoneKernel& zone(int s) const;
  /// Full diagnostics: each source's eig_min, the smallest eigenvalue of its own
  /// Lambda_task|prec(level)^-1 (unweighted rows), and whether it is below
  /// singular_tolerance times its unprojected largest eigenvalue (as
  /// hqp.control.diagnostics.Diagnostics.law_statuses, mode "full").
  void diagnose(double singular_tolerance);

 private:
  struct Source {
    int level;
    int handle = -1;  ///< NativeStep entry, or -1 for a zone
    int zone = -1;
    double sqrt_w = 1.0;
    NativeStep::EntryInfo info{};
    Index slot_start = -1;  ///< a contact's slot (its rows on qdd: its Jacobian)
  };
  void lay_out();
  void assemble();
  void decision_vector();
  void report();

  NativeStep& step_;
  LawSettings settings_;
  Index nv_, nv_base_, na_, n_;
  NullSpaceLaw law_;
  std::vector<bool> phys_;
  std::vector<Source> sources_;
  std::vector<JointLimitZoneKernel> zones_;
  std::vector<int> order_;  // sources by (level, order)
  bool laid_out_ = false;
  // assembled rows
  MatrixXd J_, Js_, Jf_, Jfa_;
  VectorXd a_, bs_, x_, gen_, wf_;
  Index m_ = 0, ns_ = 0, nf_ = 0, law_levels_ = 0;
  std::vector<Index> starts_;
  std::vector<int> law_stack_level_;
  std::vector<Index> level_rows_;
  std::vector<double> level_cost_;
  std::vector<SourceResult> results_;
  struct ActiveSlot {
    Index start, size;  ///< the slot in x
    Index row;          ///< its first support row (-1: not a support row)
    double sqrt_w;
  };
  std::vector<ActiveSlot> active_slots_;
  bool support_is_contacts_ = true;  ///< the support rows are the active slots' rows, in order
  Eigen::JacobiSVD<MatrixXd> svd_f_;
  WorkM P_, Ph_, Pz_;
  VectorXd s_;
  SymmetricEigen gram_;
};

}  // namespace hqp
