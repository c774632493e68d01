// The strict lexicographic solver of the native core: the basis algorithm with its
// active-set warm start (the C++ twin of hqp.solver.basis.BasisAlgorithm, run by HierarchicalSolver with
// algorithm="basis"; see that module's docstring for the method and the constants).
//
// Structure and workspace apart (pinocchio's Model/Data): when the shapes of the levels
// change (n, each level's equality and inequality row counts), solve() reserves every
// workspace for the largest shape each level can take (its rows, n, the inequality rows of
// the levels above); while the level shapes hold, solve() allocates nothing, whatever the
// active sets, ranks and carried rows of each solve.
#pragma once

#include <string>
#include <vector>

#include "solver/active_set.hpp"
#include "solver/linalg.hpp"
#include "solver/qp.hpp"

namespace hqp {

constexpr double kFixTol = 1e-6;
constexpr double kCarryMargin = 1e-9;
constexpr double kActiveTol = 1e-7;
constexpr int kPolishIter = 2;
constexpr int kWarmSkip = 50;
constexpr double kRowTol = 1e-7;
constexpr double kSatisfiedCost = 1e-10;

enum class LevelKind : int { kUser = 0, kMetric = 1, kNorm = 2 };

struct Settings {
  double rank_tol = 1e-9;
  bool warm_start = true;
  bool compute_sigma = true;
  /// Work budget of one solve (both passes), in the level QPs' work units (LevelQP: DAQP
  /// iterations, PrimalQP iterations weighted); 0: unbounded (the contract solver's default).
  /// Where it runs out, the levels solved stay exact and each level whose QP it cuts keeps
  /// the best feasible point reached (LevelResult::cut).
  long long work_budget = 0;
};

/// One level's rows, held in the solver's workspace (column-major copies of the inputs).
struct LevelData {
  MatrixXd A, C;
  VectorXd b, lo, up, los, ups;
  IVec bounded;
  double a_scale = 0.0, c_scale = 0.0;
  double weak = 0.0;  ///< the level's weak_threshold (0: no filtering)
  LevelKind kind = LevelKind::kUser;
  RowSupport a_support, c_support;  ///< where the rows of A and C are nonzero (finish())
  /// Scales and flags from A, b, C, lo, up (the fields of hqp.solver.level.CheckedLevel).
  void finish();
  /// The final minimum-norm level over n variables (identity rows, zero target).
  void set_norm(Index n);
};

/// What a solve achieved on one level (hqp.solver.LevelReport).
struct LevelResult {
  double cost = 0.0;
  bool satisfied = true;
  double sigma_min = 0.0;
  VectorXd residual_eq;   ///< A x - b (m_eq,)
  VectorXd violation_in;  ///< signed distance of C x outside [lo, up] (m_in,)
  IVec state;             ///< per inequality row: 0 inside, 1 active, 2 active and violated
  int weak = 0;           ///< weak directions whose target was filtered
  bool cut = false;       ///< the level's QP stopped on the work budget (Settings)
  double seconds = 0.0;
};

/// Per-level workspace and warm-start memory.
struct Slot {
  // warm-start memory
  bool has_guess = false;
  IVec memo_s, memo_w;
  bool has_point = false;
  VectorXd point;
  int warm_skip = 0;
  bool needed_qp = false;
  Index nq_mi = -1, nq_r = -1, nq_p = -1;
  // workspace: sizes fixed by the level shapes (me, mi, n) ...
  VectorXd bk, xl, cx, cx0, lo_r, up_r, tmp, zref, xc;
  IVec s, violated;
  // ... and fixed-capacity storage for the shapes that vary from solve to solve (the basis
  // size r, the carried rows p, the QP's r + mi)
  WorkM Ak, Ck, Gk, Z, E, H, Cq, Msig;
  WorkM dc;  // the anchor's displacement in the reduced coordinates (r,)
  WorkM y, gx, glr, gur, ref, g, qlo, qup, v, v0, gxl, svals;
  WorkI w, absorbed;
  PivotedQR fact, null_qr;
  bool has_fact = false;
  bool projected = false;  // Ak holds A Zb (for the report's sigma)
  const WorkM* Zb = nullptr;  // basis before this level (nullptr: identity)
  ActiveSetSolver as;
  LevelQP qp;
  SingularValues sv;
  WeakFilter weak;
  /// Capacity for a level of me equality and mi inequality rows over n variables below
  /// levels of P inequality rows in all; the fixed-size members sized.
  void reserve(Index n, Index me, Index mi, Index P, Index total_in);
};

/// The instruction set the solver's units were compiled for ("avx2+fma" or "sse2").
const char* solver_simd();
/// The build's HQP_SIMD option ("AUTO", "ON" or "OFF").
const char* solver_simd_option();

class Hierarchy {
 public:
  explicit Hierarchy(const Settings& settings) : settings_(settings) {}

  /// The levels of the next solve: user levels first, then the internal final levels
  /// (metric, minimum norm). Sized with resize_levels; each filled, then finish()ed.
  std::vector<LevelData>& levels() { return levels_; }
  const std::vector<LevelData>& levels() const { return levels_; }
  void resize_levels(std::size_t count);
  /// Solve the levels; returns an empty string on success, else the failure's message.
  std::string solve(Index n, Index user_levels);
  void reset();
  /// Set the work budget of the next solves (Settings::work_budget; 0: unbounded).
  void set_work_budget(long long budget) { settings_.work_budget = budget < 0 ? 0 : budget; }
  /// Work units the last solve used.
  long long work_used() const { return work_used_; }

  const VectorXd& x() const { return x_; }
  const std::vector<LevelResult>& results() const { return results_; }
  int qp_count() const { return qp_count_; }
  /// Levels of the last solve whose point was the anchor's (BasisAlgorithm.anchored).
  int anchored() const { return anchored_; }
  double final_seconds() const { return final_seconds_; }
  const Settings& settings() const { return settings_; }

 private:
  /// One pass of solve(): carried rows held with positive multipliers absorbed if `absorb`.
  std::string solve_pass(Index n, Index user_levels, bool absorb);
  bool warm_slot(Slot& slot);
  /// Whether the level shapes differ from the last solve's (then recorded).
  bool shapes_changed(Index n);
  void report(Index k);
  double sigma_level(Index k);

  Settings settings_;
  std::vector<LevelData> levels_;
  std::vector<Slot> slots_;
  std::vector<LevelResult> results_;
  VectorXd x_;
  VectorXd anchor_;  // the last solve's x (the least squares' start, warm)
  bool has_anchor_ = false;
  MatrixXd G_;
  VectorXd gl_, gu_, gls_, gus_, gtmp_;
  IVec gid_;
  std::vector<Index> shapes_;  // n, then (me, mi) per level, of the last solve
  int qp_count_ = 0;
  int anchored_ = 0;
  long long budget_left_ = 0;
  long long work_used_ = 0;
  double final_seconds_ = 0.0;
  Index n_ = -1;
};

}  // namespace hqp
