// The feasibility report of a solved hierarchy (seed 001, the servo's feasibility flags):
// per task, satisfied, in conflict (and the level it yields to) or singular, from the
// solver's levels and results alone. Eigen only (no robot), compiled with the solver.
//
// Definitions (hqp.control.diagnostics):
// - Z_k: an orthonormal basis of the directions left free by built levels 0..k, the null
//   space of their equality rows and their active (or violated) inequality rows: the face of
//   the optimal set on which the solution lies.
// - sigma_min of a task with equality rows at built level k: the m-th singular value of its
//   m unweighted rows (equalities and active inequalities) times Z_{k-1}; 0 when m exceeds
//   the free dimension.
// - A task is in conflict when its unweighted residual norm exceeds the tolerance; it yields
//   to the highest built level j < k whose optimal set keeps its residual out of reach,
//   min_y ||r + M Z_j y|| > tolerance (M: its equality and violated inequality rows, r their
//   residuals); to its own level when only tasks of its level block it; to none when even
//   the whole space cannot meet it. The reachable residual grows with j: bisection, started
//   from the last answer.
#pragma once

#include <vector>

#include "solver/hierarchy.hpp"
#include "solver/linalg.hpp"

namespace hqp {

/// Where one task's rows sit in the built levels.
struct TaskRows {
  int level = 0;        ///< the task's level index (what yields_to reports)
  int built = -1;       ///< its built level (-1: no rows)
  Index eq0 = 0, neq = 0, in0 = 0, nin = 0;
  double sqrt_w = 1.0;  ///< the rows' scaling by the square root of the task's weight
};

class Report {
 public:
  /// Storage for `tasks` over built levels of at most `rows_max` rows and n variables.
  void reserve(Index tasks, Index levels, Index rows_max, Index n);
  void set(double tolerance, double singular_tolerance, bool full) {
    tol_ = tolerance;
    singular_ = singular_tolerance;
    full_ = full;
  }
  /// The report of a solve: `levels`, `results` of the built levels (level_index: built
  /// level -> level index), `tasks`, each task's unweighted residual norm. No allocation
  /// after reserve().
  void compute(const std::vector<LevelData>& levels, const std::vector<LevelResult>& results,
               const std::vector<int>& level_index, const std::vector<TaskRows>& tasks,
               const VectorXd& residuals);

  double tolerance() const { return tol_; }
  double singular_tolerance() const { return singular_; }
  bool full() const { return full_; }
  /// Per task: 0 satisfied, 1 conflict, 2 singular, -1 no rows.
  const IVec& status() const { return status_; }
  const VectorXd& sigma() const { return sigma_; }
  /// Per task: the level a conflict yields to, -1 none (infeasible alone), -2 not a conflict.
  const IVec& yields() const { return yields_; }

 private:
  int yields_to(Index i, int k, const TaskRows& t, const LevelData& lv, const LevelResult& res,
                const std::vector<int>& level_index);
  double reachable(int j, double scale);
  /// The basis after built level j (j = -1: the identity).
  CMapM basis(int j) const;

  double tol_ = 1e-5, singular_ = 1e-4;
  bool full_ = true;
  Index n_ = 0;
  VectorXd sigma_;
  IVec status_, yields_, guess_;
  std::vector<WorkM> store_;  // bases; a level that removes no direction shares the one above
  std::vector<int> base_of_;  // built level -> index into store_ (-1: the identity)
  /// out = M Z_j over the nonzero columns of M (support_ computed for M), Z_j = basis(j).
  void project(const CMatRef& M, int j, MapM out) const;

  WorkM M_, P_, r0_, rp_, ws_;
  RowSupport support_;
  PivotedQR null_qr_;
  ColPivQR reach_qr_;
  SingularValues sv_;
};

}  // namespace hqp
