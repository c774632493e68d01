// The native control step: one call from the state to the torques. The robot model's one
// pinocchio pass, every task kernel writing its rows straight into the solver's level
// matrices (weights applied as sqrt(w), as hqp.stack.Stack.build), the strict hierarchy
// solved in place, and the actuated torques tau = S (M qdd + h - sum_c J_c^T f_c).
//
// The structure (which kernels at which level) is fixed when the step is built; goals,
// contact activation and the joint-limit braking change between steps through the kernels'
// setters.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "model/robot.hpp"
#include "solver/hierarchy.hpp"
#include "solver/linalg.hpp"
#include "solver/report.hpp"
#include "tasks/collision.hpp"
#include "tasks/cop.hpp"
#include "tasks/gaze.hpp"
#include "tasks/internal_forces.hpp"
#include "tasks/joint_limits.hpp"
#include "tasks/orientation.hpp"
#include "tasks/physics.hpp"
#include "tasks/pose.hpp"
#include "tasks/vector_tracking.hpp"

namespace hqp {

class NativeStep {
 public:
  using Index = Eigen::Index;
  enum class Kind { kDynamics, kTorqueLimits, kContact, kContactLimits, kJointLimits,
                    kTracking, kOrientation, kConstant, kGaze, kInternalForces, kDistance,
                    kPose, kEffort, kCoP, kTorqueRate };

  NativeStep(std::unique_ptr<RobotCore> robot, Index nv_base, LayoutC layout, int n_levels,
             const Settings& settings);

  // the kernels, in their level's row order; each returns its handle
  int add_dynamics(int level, double weight);
  int add_torque_limits(int level, double weight, const Eigen::VectorXd& tau_max);
  int add_contact(int level, double weight, const ContactKernel& kernel);
  int add_contact_limits(int level, double weight, int contact);
  int add_joint_limits(int level, double weight, const JointLimitParams& params,
                       const Eigen::VectorXd& max_acceleration, const Eigen::VectorXd& braking);
  int add_tracking(int level, double weight, const VectorTracking& kernel);
  int add_orientation(int level, double weight, const OrientationTracking& kernel);
  /// Equality rows that do not change with the state (A (rows, n), b (rows,)), e.g. the
  /// contact-force regularisation.
  int add_constant(int level, double weight, const Eigen::MatrixXd& A, const Eigen::VectorXd& b);

  int add_gaze(int level, double weight, const GazeKernel& kernel);
  int add_internal_forces(int level, double weight, const InternalForcesKernel& kernel);
  int add_distance(int level, double weight, const DistanceKernel& kernel);
  int add_pose(int level, double weight, const PoseKernel& kernel);
  /// Minimum effort: rows diag(w) S [M | -J^T] x = -diag(w) S h (the torques, scaled by w).
  int add_effort(int level, double weight, const Eigen::VectorXd& scale);
  int add_cop(int level, double weight, const CoPKernel& kernel);
  /// The servo's torque-rate rows: tau_lo <= S (M qdd + h - J_c^T f) <= tau_hi over the
  /// actuated joints, the bounds set by set_torque_rate (infinite until then).
  int add_torque_rate(int level, double weight);

  VectorTracking& tracking(int handle);
  GazeKernel& gaze(int handle);
  InternalForcesKernel& internal_forces(int handle);
  DistanceKernel& distance(int handle);
  PoseKernel& pose(int handle);
  CoPKernel& cop(int handle);
  OrientationTracking& orientation(int handle);
  ContactKernel& contact(int handle);
  void set_braking(int handle, const Eigen::VectorXd& braking);
  /// The torque bounds of a torque-rate kernel for the next steps (+-inf: unbounded).
  void set_torque_rate(int handle, const Eigen::Ref<const Eigen::VectorXd>& tau_lo,
                       const Eigen::Ref<const Eigen::VectorXd>& tau_hi);

  /// A task ramping in (hqp.stack): its rows' targets move by keep * the offsets recorded
  /// at the ramp's first step, b + keep d_eq and the bounds widened by keep d_lo, keep d_up,
  /// before the weight's scaling (keep = 1 - s, s the ramp fraction; 0: the rows as they are).
  void set_ramp(int handle, double keep);
  /// Record the ramp offsets of a kernel at the next step from its (unweighted) rows and
  /// x_prev: d_eq = A x_prev - b, d_lo = min(0, C x_prev - lo) and d_up = max(0, C x_prev -
  /// up) on finite bounds (0 elsewhere), as hqp.stack records them. One x_prev per step.
  void record_ramp(int handle, const Eigen::Ref<const Eigen::VectorXd>& x_prev);
  /// Set a kernel's ramp offsets (recorded by a Python step).
  void set_ramp_offsets(int handle, const Eigen::Ref<const Eigen::VectorXd>& d_eq,
                        const Eigen::Ref<const Eigen::VectorXd>& d_lo,
                        const Eigen::Ref<const Eigen::VectorXd>& d_up);
  /// The ramp offsets (d_eq, d_lo, d_up) of a kernel.
  struct RampOffsets {
    const Eigen::VectorXd& d_eq;
    const Eigen::VectorXd& d_lo;
    const Eigen::VectorXd& d_up;
  };
  RampOffsets ramp_offsets(int handle) const;

  /// The weak-direction threshold of stack level `level` (hqp.solver.Level.weak_threshold,
  /// in the units of the level's weighted rows; 0, the default: no filtering).
  void set_weak_threshold(int level, double threshold);
  double weak_threshold(int level) const;

  /// One control step at (q, v) with the period dt; "" on success, else the failure. No
  /// heap allocation once the first step has sized everything.
  std::string step(const Eigen::Ref<const Eigen::VectorXd>& q,
                   const Eigen::Ref<const Eigen::VectorXd>& v, double dt);
  /// The first part of step(): the model pass and every kernel's rows in the level matrices
  /// (level(k)), no solve ("" on success). The null-space law's step (control/law.hpp) runs
  /// its own resolution on these rows.
  std::string rows(const Eigen::Ref<const Eigen::VectorXd>& q,
                   const Eigen::Ref<const Eigen::VectorXd>& v, double dt);

  Index n() const { return n_; }
  Index nv_base() const { return nv_base_; }
  const RobotCore& robot() const { return *robot_; }
  const Hierarchy& hierarchy() const { return hierarchy_; }
  /// The built levels (non-empty ones, in order) of the last step.
  int level_count() const { return int(used_.size()); }
  const LevelData& level(int k) const { return hierarchy_.levels()[std::size_t(k)]; }
  int level_index(int k) const { return used_[std::size_t(k)]; }
  const Eigen::VectorXd& x() const { return hierarchy_.x(); }
  const Eigen::VectorXd& tau() const { return tau_; }

  /// What the feasibility report needs of one kernel: where its rows sit in the built levels.
  struct EntryInfo {
    int kind, level, built_level;
    Index eq0, neq, in0, nin;
    double sqrt_w;
  };
  int entry_count() const { return int(entries_.size()); }
  Kind entry_kind(int handle) const { return entries_[std::size_t(handle)].kind; }
  EntryInfo entry(int handle) const;
  /// Unweighted residual norm of each kernel's rows at the last step's x (equality residual
  /// and inequality violation stacked), in handle order; filled by step() without allocating.
  const Eigen::VectorXd& residuals() const { return residual_; }
  /// The feasibility report's settings (solver/report.hpp): a kernel whose unweighted
  /// residual norm exceeds `tolerance` is in conflict; one with equality rows whose projected
  /// sigma_min is below `singular_tolerance` is singular; `full`: projected sigma_min per
  /// kernel and the level each conflict yields to (else the level's sigma_min, no yields_to).
  /// Once set, every step() computes the report before it returns.
  void set_report(double tolerance, double singular_tolerance, bool full);
  /// Compute the report of the last step (statuses(), sigmas(), yields()); no heap
  /// allocation (its storage is reserved when the levels are laid out).
  void report();
  /// The full diagnostics' sigma_min of each kernel (handle order; NaN for a kernel without
  /// equality rows).
  const Eigen::VectorXd& diagnose();
  /// Per kernel (handle order): 0 satisfied, 1 conflict, 2 singular, -1 not reported (no
  /// rows in the built levels).
  const IVec& statuses() const { return report_.status(); }
  const Eigen::VectorXd& sigmas() const { return report_.sigma(); }
  /// Per kernel: the stack level a conflict yields to; -1: infeasible on its own (no level
  /// above blocks it); -2: not a conflict (or a report without yields_to).
  const IVec& yields() const { return report_.yields(); }
  /// The solver's report of built level k (cost, sigma_min, per-row states).
  const LevelResult& result(int k) const { return hierarchy_.results()[std::size_t(k)]; }

 private:
  struct Entry {
    Kind kind;
    int level;
    double sqrt_w;
    int index;  // into the kernel list of its kind
    Index neq = 0, nin = 0, eq0 = 0, in0 = 0;
    double keep = 0.0;    // a ramp: 1 - s (0: none)
    bool record = false;  // record the ramp offsets at the next step
    Eigen::VectorXd d_eq, d_lo, d_up;  // ramp offsets (unweighted row units)
  };
  /// The index of a handle in entries_ (std::invalid_argument: no such handle).
  std::size_t index_of(int handle) const;
  struct JointLimitEntry {
    JointLimitParams params;
    Eigen::VectorXd A, B, lb, ub;
  };
  int add(Kind kind, int level, double weight, int index, Index neq, Index nin);
  const Entry& checked(int handle, Kind kind, const char* what) const;
  void layout_levels();

  std::unique_ptr<RobotCore> robot_;
  Index nv_base_, na_, n_;
  LayoutC layout_;
  int n_levels_;
  Hierarchy hierarchy_;
  std::vector<Entry> entries_;
  std::vector<ContactKernel> contacts_;
  std::vector<VectorTracking> tracking_;
  std::vector<OrientationTracking> orientation_;
  std::vector<GazeKernel> gaze_;
  std::vector<InternalForcesKernel> internal_;
  std::vector<DistanceKernel> distance_;
  std::vector<PoseKernel> pose_;
  std::vector<Eigen::VectorXd> effort_;
  std::vector<CoPKernel> cop_;
  std::vector<JointLimitEntry> joint_limits_;
  std::vector<Eigen::VectorXd> tau_max_;
  std::vector<std::pair<Eigen::VectorXd, Eigen::VectorXd>> rate_;  // torque bounds
  std::vector<std::pair<Eigen::MatrixXd, Eigen::VectorXd>> constants_;
  std::vector<double> weak_;       // weak threshold per stack level
  std::vector<int> used_;          // built level k -> stack level index
  std::vector<int> built_of_;      // stack level index -> built level (-1: empty)
  bool laid_out_ = false;
  Eigen::MatrixXd G_;
  RobotCore::Matrix6Xd J6_;
  Eigen::VectorXd tau_;
  Eigen::VectorXd x_ramp_;  // the x_prev of the ramp offsets recorded at the next step
  Eigen::VectorXd residual_;
  Report report_;
  std::vector<TaskRows> task_rows_;
  bool report_on_ = false;

};

}  // namespace hqp
