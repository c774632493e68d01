// The native control step; see step.hpp.
#include "control/step.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace hqp {

NativeStep::NativeStep(std::unique_ptr<RobotCore> robot, Index nv_base, LayoutC layout,
                       int n_levels, const Settings& settings)
    : robot_(std::move(robot)), nv_base_(nv_base), layout_(std::move(layout)),
      n_levels_(n_levels), hierarchy_(settings) {
  if (layout_.nv != robot_->nv()) throw std::invalid_argument("layout nv differs from the robot's");
  na_ = robot_->nv() - nv_base_;
  n_ = layout_.n();
  G_.setZero(robot_->nv(), n_);
  J6_.setZero(6, robot_->nv());
  tau_.setZero(na_);
  x_ramp_.setZero(n_);
  weak_.assign(std::size_t(std::max(n_levels_, 0)), 0.0);
}

int NativeStep::add(Kind kind, int level, double weight, int index, Index neq, Index nin) {
  if (level < 0 || level >= n_levels_) throw std::invalid_argument("level out of range");
  if (!(weight > 0.0) || !std::isfinite(weight)) throw std::invalid_argument("weight must be > 0");
  Entry e{kind, level, std::sqrt(weight), index};
  e.neq = neq;
  e.nin = nin;
  e.d_eq.setZero(neq);
  e.d_lo.setZero(nin);
  e.d_up.setZero(nin);
  entries_.push_back(e);
  laid_out_ = false;
  return int(entries_.size()) - 1;
}

int NativeStep::add_dynamics(int level, double weight) {
  return add(Kind::kDynamics, level, weight, -1, nv_base_, 0);
}

int NativeStep::add_torque_limits(int level, double weight, const Eigen::VectorXd& tau_max) {
  if (tau_max.size() != na_) throw std::invalid_argument("tau_max: one bound per actuated joint");
  tau_max_.push_back(tau_max);
  return add(Kind::kTorqueLimits, level, weight, int(tau_max_.size()) - 1, 0, na_);
}

int NativeStep::add_contact(int level, double weight, const ContactKernel& kernel) {
  contacts_.push_back(kernel);
  return add(Kind::kContact, level, weight, int(contacts_.size()) - 1, kernel.rows(), 0);
}

int NativeStep::add_contact_limits(int level, double weight, int contact) {
  if (contact < 0 || contact >= int(entries_.size()) || entries_[contact].kind != Kind::kContact)
    throw std::invalid_argument("contact limits: not a contact handle");
  const int index = entries_[contact].index;
  return add(Kind::kContactLimits, level, weight, index, 0, contacts_[index].limit_rows());
}

int NativeStep::add_joint_limits(int level, double weight, const JointLimitParams& params,
                                 const Eigen::VectorXd& max_acceleration,
                                 const Eigen::VectorXd& braking) {
  for (const Eigen::VectorXd* a : {&params.q_lower, &params.q_upper, &params.v_max,
                                   &max_acceleration, &braking}) {
    if (a->size() != na_) throw std::invalid_argument("joint limits: one value per actuated joint");
  }
  joint_limits_.push_back({params, max_acceleration, braking, Eigen::VectorXd::Zero(na_),
                           Eigen::VectorXd::Zero(na_)});
  return add(Kind::kJointLimits, level, weight, int(joint_limits_.size()) - 1, 0, na_);
}

int NativeStep::add_tracking(int level, double weight, const VectorTracking& kernel) {
  tracking_.push_back(kernel);
  return add(Kind::kTracking, level, weight, int(tracking_.size()) - 1, kernel.rows(), 0);
}

int NativeStep::add_orientation(int level, double weight, const OrientationTracking& kernel) {
  orientation_.push_back(kernel);
  return add(Kind::kOrientation, level, weight, int(orientation_.size()) - 1, 3, 0);
}

int NativeStep::add_constant(int level, double weight, const Eigen::MatrixXd& A,
                             const Eigen::VectorXd& b) {
  if (A.cols() != n_ || A.rows() != b.size())
    throw std::invalid_argument("constant rows: A must be (rows, n) and b (rows,)");
  constants_.emplace_back(A, b);
  return add(Kind::kConstant, level, weight, int(constants_.size()) - 1, A.rows(), 0);
}

int NativeStep::add_gaze(int level, double weight, const GazeKernel& kernel) {
  gaze_.push_back(kernel);
  return add(Kind::kGaze, level, weight, int(gaze_.size()) - 1, kernel.rows(), 0);
}

int NativeStep::add_internal_forces(int level, double weight, const InternalForcesKernel& kernel) {
  internal_.push_back(kernel);
  return add(Kind::kInternalForces, level, weight, int(internal_.size()) - 1, kernel.rows(), 0);
}

int NativeStep::add_distance(int level, double weight, const DistanceKernel& kernel) {
  distance_.push_back(kernel);
  return add(Kind::kDistance, level, weight, int(distance_.size()) - 1, 0, kernel.rows());
}

int NativeStep::add_pose(int level, double weight, const PoseKernel& kernel) {
  pose_.push_back(kernel);
  return add(Kind::kPose, level, weight, int(pose_.size()) - 1, kernel.rows(), 0);
}

int NativeStep::add_effort(int level, double weight, const Eigen::VectorXd& scale) {
  if (scale.size() != na_) throw std::invalid_argument("effort: one scale per actuated joint");
  effort_.push_back(scale);
  return add(Kind::kEffort, level, weight, int(effort_.size()) - 1, na_, 0);
}

int NativeStep::add_cop(int level, double weight, const CoPKernel& kernel) {
  cop_.push_back(kernel);
  return add(Kind::kCoP, level, weight, int(cop_.size()) - 1, kernel.rows(), 0);
}

int NativeStep::add_torque_rate(int level, double weight) {
  const double inf = std::numeric_limits<double>::infinity();
  rate_.emplace_back(Eigen::VectorXd::Constant(na_, -inf), Eigen::VectorXd::Constant(na_, inf));
  return add(Kind::kTorqueRate, level, weight, int(rate_.size()) - 1, 0, na_);
}

void NativeStep::set_torque_rate(int handle, const Eigen::Ref<const Eigen::VectorXd>& tau_lo,
                                 const Eigen::Ref<const Eigen::VectorXd>& tau_hi) {
  const Entry& e = checked(handle, Kind::kTorqueRate, "torque-rate");
  if (tau_lo.size() != na_ || tau_hi.size() != na_)
    throw std::invalid_argument("torque rate: one bound per actuated joint");
  for (Index i = 0; i < na_; ++i) {
    if (std::isnan(tau_lo(i)) || std::isnan(tau_hi(i)) || tau_lo(i) > tau_hi(i))
      throw std::invalid_argument("torque rate: bounds must be ordered and not NaN");
  }
  auto& bounds = rate_[std::size_t(e.index)];  // in place: no allocation per step
  bounds.first = tau_lo;
  bounds.second = tau_hi;
}

const NativeStep::Entry& NativeStep::checked(int handle, Kind kind, const char* what) const {
  if (handle < 0 || handle >= int(entries_.size()) || entries_[std::size_t(handle)].kind != kind)
    throw std::invalid_argument(std::string("not a ") + what + " handle");
  return entries_[std::size_t(handle)];
}

GazeKernel& NativeStep::gaze(int handle) {
  return gaze_[std::size_t(checked(handle, Kind::kGaze, "gaze").index)];
}

InternalForcesKernel& NativeStep::internal_forces(int handle) {
  return internal_[std::size_t(checked(handle, Kind::kInternalForces, "internal-forces").index)];
}

DistanceKernel& NativeStep::distance(int handle) {
  return distance_[std::size_t(checked(handle, Kind::kDistance, "distance").index)];
}

PoseKernel& NativeStep::pose(int handle) {
  return pose_[std::size_t(checked(handle, Kind::kPose, "pose").index)];
}

CoPKernel& NativeStep::cop(int handle) {
  return cop_[std::size_t(checked(handle, Kind::kCoP, "cop").index)];
}

VectorTracking& NativeStep::tracking(int handle) {
  if (handle < 0 || handle >= int(entries_.size()) || entries_[handle].kind != Kind::kTracking)
    throw std::invalid_argument("not a tracking handle");
  return tracking_[std::size_t(entries_[handle].index)];
}

OrientationTracking& NativeStep::orientation(int handle) {
  if (handle < 0 || handle >= int(entries_.size()) || entries_[handle].kind != Kind::kOrientation)
    throw std::invalid_argument("not an orientation handle");
  return orientation_[std::size_t(entries_[handle].index)];
}

ContactKernel& NativeStep::contact(int handle) {
  if (handle < 0 || handle >= int(entries_.size()) || entries_[handle].kind != Kind::kContact)
    throw std::invalid_argument("not a contact handle");
  return contacts_[std::size_t(entries_[handle].index)];
}

void NativeStep::set_braking(int handle, const Eigen::VectorXd& braking) {
  if (handle < 0 || handle >= int(entries_.size()) || entries_[handle].kind != Kind::kJointLimits)
    throw std::invalid_argument("not a joint-limits handle");
  JointLimitEntry& j = joint_limits_[std::size_t(entries_[handle].index)];
  if (braking.size() != na_) throw std::invalid_argument("braking: one value per actuated joint");
  j.B = braking;
}

std::size_t NativeStep::index_of(int handle) const {
  if (handle < 0 || handle >= int(entries_.size())) throw std::invalid_argument("no such handle");
  return std::size_t(handle);
}

void NativeStep::set_ramp(int handle, double keep) {
  Entry& e = entries_[index_of(handle)];
  if (!(keep >= 0.0 && keep <= 1.0)) throw std::invalid_argument("ramp: keep must be in [0, 1]");
  e.keep = keep;
}

void NativeStep::record_ramp(int handle, const Eigen::Ref<const Eigen::VectorXd>& x_prev) {
  Entry& e = entries_[index_of(handle)];
  if (x_prev.size() != n_) throw std::invalid_argument("ramp: x_prev must be (n,)");
  if (!x_prev.allFinite()) throw std::invalid_argument("ramp: x_prev holds NaN or inf");
  x_ramp_ = x_prev;  // in place: sized at construction
  e.record = true;
}

void NativeStep::set_ramp_offsets(int handle, const Eigen::Ref<const Eigen::VectorXd>& d_eq,
                                  const Eigen::Ref<const Eigen::VectorXd>& d_lo,
                                  const Eigen::Ref<const Eigen::VectorXd>& d_up) {
  Entry& e = entries_[index_of(handle)];
  if (d_eq.size() != e.neq || d_lo.size() != e.nin || d_up.size() != e.nin)
    throw std::invalid_argument("ramp offsets: one per equality row and two per inequality row");
  if (!d_eq.allFinite() || !d_lo.allFinite() || !d_up.allFinite())
    throw std::invalid_argument("ramp offsets: NaN or inf");
  e.d_eq = d_eq;
  e.d_lo = d_lo;
  e.d_up = d_up;
  e.record = false;
}

NativeStep::RampOffsets NativeStep::ramp_offsets(int handle) const {
  const Entry& e = entries_[index_of(handle)];
  return {e.d_eq, e.d_lo, e.d_up};
}

void NativeStep::set_weak_threshold(int level, double threshold) {
  if (level < 0 || level >= n_levels_) throw std::out_of_range("weak threshold: no such level");
  if (!(threshold >= 0.0 && threshold < std::numeric_limits<double>::infinity())) {
    throw std::invalid_argument("weak threshold: expected a finite value >= 0");
  }
  weak_[std::size_t(level)] = threshold;
}

double NativeStep::weak_threshold(int level) const {
  if (level < 0 || level >= n_levels_) throw std::out_of_range("weak threshold: no such level");
  return weak_[std::size_t(level)];
}

void NativeStep::layout_levels() {
  // row offsets per level in entry order; empty levels are left out (as Stack.build)
  std::vector<Index> neq(std::size_t(n_levels_), 0), nin(std::size_t(n_levels_), 0);
  for (Entry& e : entries_) {
    e.eq0 = neq[std::size_t(e.level)];
    e.in0 = nin[std::size_t(e.level)];
    neq[std::size_t(e.level)] += e.neq;
    nin[std::size_t(e.level)] += e.nin;
  }
  used_.clear();
  built_of_.assign(std::size_t(n_levels_), -1);
  for (int k = 0; k < n_levels_; ++k) {
    if (neq[std::size_t(k)] + nin[std::size_t(k)] == 0) continue;
    built_of_[std::size_t(k)] = int(used_.size());
    used_.push_back(k);
  }
  hierarchy_.resize_levels(used_.size() + 1);
  auto& data = hierarchy_.levels();
  for (std::size_t b = 0; b < used_.size(); ++b) {
    LevelData& lv = data[b];
    const std::size_t k = std::size_t(used_[b]);
    lv.A.setZero(neq[k], n_);
    lv.b.setZero(neq[k]);
    lv.C.setZero(nin[k], n_);
    lv.lo.setZero(nin[k]);
    lv.up.setZero(nin[k]);
    lv.kind = LevelKind::kUser;
  }
  data.back().set_norm(n_);
  residual_.setZero(Index(entries_.size()));
  // the report's storage, for the largest shapes it can meet
  Index rows_max = 1;
  for (std::size_t k = 0; k < std::size_t(n_levels_); ++k) {
    rows_max = std::max(rows_max, neq[k] + nin[k]);
  }
  task_rows_.clear();
  for (const Entry& e : entries_) {
    task_rows_.push_back(
        {e.level, built_of_[std::size_t(e.level)], e.eq0, e.neq, e.in0, e.nin, e.sqrt_w});
  }
  report_.reserve(Index(entries_.size()), Index(used_.size()), rows_max, n_);
  laid_out_ = true;
}

void NativeStep::set_report(double tolerance, double singular_tolerance, bool full) {
  if (!(tolerance >= 0.0) || !(singular_tolerance >= 0.0)) {
    throw std::invalid_argument("report: tolerances must be >= 0");
  }
  report_.set(tolerance, singular_tolerance, full);
  report_on_ = true;
}

void NativeStep::report() {
  if (!laid_out_) throw std::logic_error("report: no step made yet");
  report_.compute(hierarchy_.levels(), hierarchy_.results(), used_, task_rows_, residual_);
}

const Eigen::VectorXd& NativeStep::diagnose() {
  const bool full = report_.full();
  report_.set(report_.tolerance(), report_.singular_tolerance(), true);
  report();
  report_.set(report_.tolerance(), report_.singular_tolerance(), full);
  return report_.sigma();
}

NativeStep::EntryInfo NativeStep::entry(int handle) const {
  const Entry& e = entries_[index_of(handle)];
  if (!laid_out_) throw std::logic_error("entry rows are placed by the first step");
  return {int(e.kind), e.level, built_of_[std::size_t(e.level)], e.eq0, e.neq, e.in0, e.nin,
          e.sqrt_w};
}

std::string NativeStep::rows(const Eigen::Ref<const Eigen::VectorXd>& q,
                             const Eigen::Ref<const Eigen::VectorXd>& v, double dt) {
  if (!laid_out_) layout_levels();
  RobotCore& robot = *robot_;
  robot.update(q, v);
  contact_dynamics(robot, layout_, G_, J6_);
  auto& data = hierarchy_.levels();
  for (Entry& e : entries_) {
    LevelData& lv = data[std::size_t(built_of_[std::size_t(e.level)])];
    auto A = lv.A.middleRows(e.eq0, e.neq);
    auto b = lv.b.segment(e.eq0, e.neq);
    auto C = lv.C.middleRows(e.in0, e.nin);
    auto lo = lv.lo.segment(e.in0, e.nin);
    auto up = lv.up.segment(e.in0, e.nin);
    switch (e.kind) {
      case Kind::kDynamics:
        A = G_.topRows(nv_base_);
        b = -robot.h().head(nv_base_);
        break;
      case Kind::kTorqueLimits: {
        const Eigen::VectorXd& tau = tau_max_[std::size_t(e.index)];
        C = G_.bottomRows(na_);
        lo = -tau - robot.h().tail(na_);
        up = tau - robot.h().tail(na_);
        break;
      }
      case Kind::kTorqueRate: {
        const auto& bounds = rate_[std::size_t(e.index)];
        C = G_.bottomRows(na_);
        lo = bounds.first - robot.h().tail(na_);
        up = bounds.second - robot.h().tail(na_);
        break;
      }
      case Kind::kContact:
        contacts_[std::size_t(e.index)].write(robot, A, b);
        break;
      case Kind::kContactLimits:
        contacts_[std::size_t(e.index)].write_limits(robot, C, lo, up);
        break;
      case Kind::kJointLimits: {
        JointLimitEntry& j = joint_limits_[std::size_t(e.index)];
        const Index nq_base = robot.nq() - na_;
        joint_limit_bounds(j.params, robot.q().tail(robot.nq() - nq_base), robot.v().tail(na_),
                           j.A, j.B, dt, j.lb, j.ub);
        C.setZero();
        C.middleCols(nv_base_, na_).setIdentity();
        lo = j.lb;
        up = j.ub;
        break;
      }
      case Kind::kTracking:
        tracking_[std::size_t(e.index)].write(robot, A, b);
        break;
      case Kind::kOrientation:
        orientation_[std::size_t(e.index)].write(robot, A, b);
        break;
      case Kind::kConstant:
        A = constants_[std::size_t(e.index)].first;
        b = constants_[std::size_t(e.index)].second;
        break;
      case Kind::kGaze:
        if (const char* why = gaze_[std::size_t(e.index)].write(robot, A, b))
          return std::string("gaze: ") + why;
        break;
      case Kind::kInternalForces:
        if (const char* why = internal_[std::size_t(e.index)].write(robot, A, b))
          return std::string("internal forces: ") + why;
        break;
      case Kind::kDistance:
        distance_[std::size_t(e.index)].write(robot, dt, C, lo, up);
        break;
      case Kind::kPose:
        pose_[std::size_t(e.index)].write(robot, A, b);
        break;
      case Kind::kEffort: {
        const Eigen::VectorXd& w = effort_[std::size_t(e.index)];
        A.noalias() = w.asDiagonal() * G_.bottomRows(na_);
        b = -(w.array() * robot.h().tail(na_).array()).matrix();
        break;
      }
      case Kind::kCoP:
        cop_[std::size_t(e.index)].write(robot, A, b);
        break;
    }
    if (e.record) {  // the ramp's first step: its offsets at x_prev (hqp.stack._ramp_offsets)
      e.record = false;
      e.d_eq.noalias() = A * x_ramp_;
      e.d_eq -= b;
      e.d_lo.noalias() = C * x_ramp_;
      e.d_up = e.d_lo;
      for (Index i = 0; i < e.nin; ++i) {
        e.d_lo(i) = std::isfinite(lo(i)) ? std::min(e.d_lo(i) - lo(i), 0.0) : 0.0;
        e.d_up(i) = std::isfinite(up(i)) ? std::max(e.d_up(i) - up(i), 0.0) : 0.0;
      }
    }
    if (e.keep != 0.0) {  // a ramp: targets moved by keep times the offsets (hqp.stack._ramp)
      b += e.keep * e.d_eq;
      lo += e.keep * e.d_lo;
      up += e.keep * e.d_up;
    }
    if (e.sqrt_w != 1.0) {
      A *= e.sqrt_w;
      b *= e.sqrt_w;
      C *= e.sqrt_w;
      lo *= e.sqrt_w;
      up *= e.sqrt_w;
    }
  }
  return std::string();
}

std::string NativeStep::step(const Eigen::Ref<const Eigen::VectorXd>& q,
                             const Eigen::Ref<const Eigen::VectorXd>& v, double dt) {
  const std::string rows_error = rows(q, v, dt);
  if (!rows_error.empty()) return rows_error;
  RobotCore& robot = *robot_;
  auto& data = hierarchy_.levels();
  for (std::size_t k = 0; k < used_.size(); ++k) {
    data[k].weak = weak_[std::size_t(used_[k])];
    data[k].finish();
  }
  const std::string error = hierarchy_.solve(n_, Index(used_.size()));
  if (!error.empty()) return error;
  tau_.noalias() = G_.bottomRows(na_) * hierarchy_.x();
  tau_ += robot.h().tail(na_);
  const auto& results = hierarchy_.results();
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    const Entry& e = entries_[i];
    const LevelResult& r = results[std::size_t(built_of_[std::size_t(e.level)])];
    const double sq = r.residual_eq.segment(e.eq0, e.neq).squaredNorm() +
                      r.violation_in.segment(e.in0, e.nin).squaredNorm();
    residual_[Index(i)] = std::sqrt(sq) / e.sqrt_w;
  }
  if (report_on_) report();
  return std::string();
}

}  // namespace hqp
