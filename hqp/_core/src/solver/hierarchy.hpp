// The strict lexicographic solver of the native core: the basis algorithm with its
// active-set warm start (the C++ twin of hqp.solver.basis.BasisAlgorithm, run by HierarchicalSolver with
// algorithm="basis"; see that module's docstring for the method and the constants).
//
// Structure and workspace apart (pinocchio's Model/Data): a Hierarchy is sized by the
// shapes of the levels it last solved; while those hold, solve() allocates nothing.
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
};

/// One level's rows, held in the solver's workspace (column-major copies of the inputs).
struct LevelData {
  MatrixXd A, C;
  VectorXd b, lo, up, los, ups;
  IVec bounded;
  double a_scale = 0.0, c_scale = 0.0;
  LevelKind kind = LevelKind::kUser;
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
  // workspace
  MatrixXd Ak, Ck, Gk, Z, E, H, Cq;
  VectorXd bk, y, xl, cx, cx0, gx, lo_r, up_r, glr, gur, ref, g, qlo, qup, v, gxl, tmp, zref;
  IVec s, w, violated;
  PivotedQR fact, null_qr;
  bool has_fact = false;
  bool projected = false;  // Ak holds A Zb (for the report's sigma)
  const MatrixXd* Zb = nullptr;  // basis before this level (nullptr: identity)
  ActiveSetSolver as;
  LevelQP qp;
  SingularValues sv;
  MatrixXd Msig;
  VectorXd svals;
};

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

  const VectorXd& x() const { return x_; }
  const std::vector<LevelResult>& results() const { return results_; }
  int qp_count() const { return qp_count_; }
  double final_seconds() const { return final_seconds_; }
  const Settings& settings() const { return settings_; }

 private:
  bool warm_slot(Slot& slot);
  void report(Index k);
  double sigma_level(Index k);

  Settings settings_;
  std::vector<LevelData> levels_;
  std::vector<Slot> slots_;
  std::vector<LevelResult> results_;
  VectorXd x_;
  MatrixXd G_;
  VectorXd gl_, gu_, gls_, gus_, gtmp_;
  IVec gid_;
  int qp_count_ = 0;
  double final_seconds_ = 0.0;
  Index n_ = -1;
};

}  // namespace hqp
