// Python bindings of the native control step (hqp._core._ext.NativeStep).
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "bindings_numpy.hpp"
#include "bindings_release.hpp"
#include "bindings_tasks.hpp"
#include "control/step.hpp"
#include "solver/linalg.hpp"

namespace hqp {

namespace nb = nanobind;

/// Call f(e, de/dt) with the error of a kernel that tracks a goal (tracking, orientation:
/// zero rate, gaze, pose) at the last step; false (f not called) for any other handle.
template <typename F>
bool visit_error(NativeStep& s, int handle, F&& f) {
  if (handle < 0 || handle >= s.entry_count()) return false;
  switch (s.entry_kind(handle)) {
    case NativeStep::Kind::kTracking:
      f(s.tracking(handle).error(), s.tracking(handle).rate());
      return true;
    case NativeStep::Kind::kOrientation:
      f(s.orientation(handle).error(), Eigen::Vector3d::Zero().eval());
      return true;
    case NativeStep::Kind::kGaze:
      f(s.gaze(handle).error(), s.gaze(handle).rate());
      return true;
    case NativeStep::Kind::kPose:
      f(s.pose(handle).error(), s.pose(handle).rate());
      return true;
    default:
      return false;
  }
}

inline void bind_step(nb::module_& m) {
  using Frames = std::vector<std::tuple<std::string, std::string, Eigen::Matrix4d>>;
  using Slots = std::vector<std::tuple<int, int, Eigen::Index>>;
  nb::class_<NativeStep>(m, "NativeStep")
      .def(
          "__init__",
          [](NativeStep* self, const std::string& urdf, const std::string& root,
             const Frames& frames, Eigen::Index nv_base, const Slots& slots, int n_levels,
             double rank_tol, bool warm_start, bool compute_sigma) {
            std::vector<ExtraFrame> extra;
            for (const auto& [name, parent, T] : frames) {
              extra.push_back({name, parent,
                               pinocchio::SE3(Eigen::Matrix3d(T.topLeftCorner<3, 3>()),
                                              Eigen::Vector3d(T.topRightCorner<3, 1>()))});
            }
            auto robot = std::make_unique<RobotCore>(urdf, root, extra);
            LayoutC layout = make_layout(robot->nv(), slots);
            new (self) NativeStep(std::move(robot), nv_base, std::move(layout), n_levels,
                                  Settings{rank_tol, warm_start, compute_sigma});
          },
          nb::arg("urdf_path"), nb::arg("root_joint"), nb::arg("extra_frames"),
          nb::arg("nv_base"), nb::arg("slots"), nb::arg("n_levels"), nb::arg("rank_tol"),
          nb::arg("warm_start"), nb::arg("compute_sigma"))
      .def_prop_ro("n", &NativeStep::n)
      .def("add_dynamics", &NativeStep::add_dynamics, nb::arg("level"), nb::arg("weight"))
      .def("add_torque_limits", &NativeStep::add_torque_limits, nb::arg("level"),
           nb::arg("weight"), nb::arg("tau_max"))
      .def("add_contact", &NativeStep::add_contact, nb::arg("level"), nb::arg("weight"),
           nb::arg("kernel"))
      .def("add_contact_limits", &NativeStep::add_contact_limits, nb::arg("level"),
           nb::arg("weight"), nb::arg("contact"))
      .def(
          "add_joint_limits",
          [](NativeStep& s, int level, double weight, const Eigen::VectorXd& q_lower,
             const Eigen::VectorXd& q_upper, const Eigen::VectorXd& v_max, double reserve,
             double velocity_time, double inactive_beyond, bool acceleration_bounds,
             const Eigen::VectorXd& A, const Eigen::VectorXd& B, double approach_time,
             const Eigen::VectorXd& recovery) {
            if (recovery.size() != 0 && recovery.size() != A.size())
              throw std::invalid_argument("add_joint_limits: recovery has the wrong size");
            JointLimitParams p{q_lower, q_upper, v_max, reserve, velocity_time, inactive_beyond,
                               acceleration_bounds, approach_time, recovery};
            return s.add_joint_limits(level, weight, p, A, B);
          },
          nb::arg("level"), nb::arg("weight"), nb::arg("q_lower"), nb::arg("q_upper"),
          nb::arg("v_max"), nb::arg("reserve"), nb::arg("velocity_time"),
          nb::arg("inactive_beyond"), nb::arg("acceleration_bounds"), nb::arg("A"), nb::arg("B"),
          nb::arg("approach_time") = 0.0, nb::arg("recovery") = Eigen::VectorXd())
      .def("add_tracking", &NativeStep::add_tracking, nb::arg("level"), nb::arg("weight"),
           nb::arg("kernel"))
      .def("add_orientation", &NativeStep::add_orientation, nb::arg("level"), nb::arg("weight"),
           nb::arg("kernel"))
      .def("add_constant", &NativeStep::add_constant, nb::arg("level"), nb::arg("weight"),
           nb::arg("A"), nb::arg("b"))
      .def("add_gaze", &NativeStep::add_gaze, nb::arg("level"), nb::arg("weight"),
           nb::arg("kernel"))
      .def("add_internal_forces", &NativeStep::add_internal_forces, nb::arg("level"),
           nb::arg("weight"), nb::arg("kernel"))
      .def("add_distance", &NativeStep::add_distance, nb::arg("level"), nb::arg("weight"),
           nb::arg("kernel"))
      .def("add_pose", &NativeStep::add_pose, nb::arg("level"), nb::arg("weight"),
           nb::arg("kernel"))
      .def("add_effort", &NativeStep::add_effort, nb::arg("level"), nb::arg("weight"),
           nb::arg("scale"))
      .def("add_cop", &NativeStep::add_cop, nb::arg("level"), nb::arg("weight"),
           nb::arg("kernel"))
      .def(
          "set_cop_goal",
          [](NativeStep& s, int handle, const Eigen::Vector2d& g) { s.cop(handle).set_goal(g); },
          nb::arg("handle"), nb::arg("goal"))
      .def(
          "set_pose_goal",
          [](NativeStep& s, int handle, const Eigen::Matrix4d& H, const RobotCore::Vector6d& v,
             const RobotCore::Vector6d& a) { s.pose(handle).set_goal(H, v, a); },
          nb::arg("handle"), nb::arg("placement"), nb::arg("velocity"), nb::arg("acceleration"))
      .def(
          "set_force",
          [](NativeStep& s, int handle, const Eigen::VectorXd& f) { s.pose(handle).set_force(f); },
          nb::arg("handle"), nb::arg("force"))
      .def(
          "set_internal_goal",
          [](NativeStep& s, int handle, const Eigen::VectorXd& g) {
            s.internal_forces(handle).set_goal(g);
          },
          nb::arg("handle"), nb::arg("goal"))
      .def(
          "set_obstacle",
          [](NativeStep& s, int handle, int obstacle, const Eigen::Vector3d& a,
             const Eigen::Vector3d& b, const Eigen::Vector3d& velocity, double radius) {
            s.distance(handle).set_obstacle(obstacle, a, b, velocity, radius);
          },
          nb::arg("handle"), nb::arg("obstacle"), nb::arg("a"), nb::arg("b"), nb::arg("velocity"),
          nb::arg("radius"))
      .def(
          "margins",
          [](NativeStep& s, int handle) { return to_numpy(s.distance(handle).margins()); },
          nb::arg("handle"), "d - d_safe per pair of a distance kernel at the last step.")
      .def(
          "set_goal",
          [](NativeStep& s, int handle, const Eigen::VectorXd& p, const Eigen::VectorXd& v,
             const Eigen::VectorXd& a) {
            if (handle >= 0 && handle < s.entry_count() &&
                s.entry_kind(handle) == NativeStep::Kind::kGaze) {
              if (p.size() != 3 || v.size() != 3 || a.size() != 3)
                throw std::invalid_argument("gaze: goal of the wrong size");
              s.gaze(handle).set_goal(p, v, a);
              return;
            }
            s.tracking(handle).set_goal(p, v, a);
          },
          nb::arg("handle"), nb::arg("position"), nb::arg("velocity"), nb::arg("acceleration"))
      .def(
          "set_orientation_goal",
          [](NativeStep& s, int handle, const Eigen::Matrix3d& R, const Eigen::Vector3d& w,
             const Eigen::Vector3d& a) { s.orientation(handle).set_goal(R, w, a); },
          nb::arg("handle"), nb::arg("rotation"), nb::arg("velocity"), nb::arg("acceleration"))
      .def(
          "contact", [](NativeStep& s, int handle) -> ContactKernel& { return s.contact(handle); },
          nb::rv_policy::reference_internal, nb::arg("handle"),
          "The contact kernel of a handle (activate/deactivate it between steps).")
      .def(
          "kernel_error",
          [](NativeStep& s, int handle) {
            nb::object out;
            const bool goal = visit_error(s, handle, [&](const auto& e, const auto& rate) {
              out = nb::make_tuple(to_numpy(e), to_numpy(rate));
            });
            if (!goal) s.tracking(handle);  // throws: not a kernel with a goal
            return out;
          },
          nb::arg("handle"),
          "(e, de/dt) of a tracking, orientation, gaze or pose kernel at the last step (e = current - goal).")
      .def(
          "error_norms",
          [](NativeStep& s) {
            const int n = s.entry_count();
            const double nan = std::numeric_limits<double>::quiet_NaN();
            Eigen::VectorXd e = Eigen::VectorXd::Constant(n, nan);
            Eigen::VectorXd r = Eigen::VectorXd::Constant(n, nan);
            for (int h = 0; h < n; ++h) {
              visit_error(s, h, [&](const auto& error, const auto& rate) {
                e[h] = error.norm();
                r[h] = rate.norm();
              });
            }
            return nb::make_tuple(to_numpy(e), to_numpy(r));
          },
          "(|e|, |de/dt|) of every kernel of kernel_error at the last step, in handle order "
          "(NaN for the others).")
      .def("set_braking", &NativeStep::set_braking, nb::arg("handle"), nb::arg("braking"))
      .def("set_ramp", &NativeStep::set_ramp, nb::arg("handle"), nb::arg("keep"),
           "A kernel ramping in: its targets moved by keep (= 1 - s) times its ramp offsets.")
      .def("record_ramp", &NativeStep::record_ramp, nb::arg("handle"), nb::arg("x_prev"),
           "Record a kernel's ramp offsets at the next step from its rows and x_prev.")
      .def("set_ramp_offsets", &NativeStep::set_ramp_offsets, nb::arg("handle"),
           nb::arg("d_eq"), nb::arg("d_lo"), nb::arg("d_up"))
      .def(
          "ramp_offsets",
          [](const NativeStep& s, int handle) {
            const NativeStep::RampOffsets o = s.ramp_offsets(handle);
            return nb::make_tuple(to_numpy(o.d_eq), to_numpy(o.d_lo), to_numpy(o.d_up));
          },
          nb::arg("handle"), "(d_eq, d_lo, d_up): a kernel's ramp offsets (unweighted).")
      .def("add_torque_rate", &NativeStep::add_torque_rate, nb::arg("level"), nb::arg("weight"))
      .def("set_torque_rate", &NativeStep::set_torque_rate, nb::arg("handle"), nb::arg("tau_lo"),
           nb::arg("tau_hi"))
      .def("set_weak_threshold", &NativeStep::set_weak_threshold, nb::arg("level"),
           nb::arg("threshold"),
           "The weak-direction threshold of a stack level (hqp.solver.Level.weak_threshold).")
      .def("weak_threshold", &NativeStep::weak_threshold, nb::arg("level"))
      .def(
          "weak_directions",
          [](const NativeStep& s) {
            Eigen::VectorXi out(s.level_count());
            for (int k = 0; k < s.level_count(); ++k) out[k] = s.result(k).weak;
            return out;
          },
          "Weak directions filtered in each built level of the last step.")
      .def(
          "step",
          // Eigen::Ref: a contiguous float64 array is read in place (no copy per step)
          [](NativeStep& s, Eigen::Ref<const Eigen::VectorXd> q,
             Eigen::Ref<const Eigen::VectorXd> v, double dt, bool forbid_malloc) {
            if (q.size() != s.robot().nq() || v.size() != s.robot().nv())
              throw std::invalid_argument("state shapes: expected (" +
                                          std::to_string(s.robot().nq()) + "), (" +
                                          std::to_string(s.robot().nv()) + ")");
            if (!(dt > 0.0)) throw std::invalid_argument("dt must be > 0");
            const std::string error =
                released(forbid_malloc, "step", [&] { return s.step(q, v, dt); });
            if (!error.empty()) throw std::runtime_error(error);
          },
          nb::arg("q"), nb::arg("v"), nb::arg("dt"), nb::arg("forbid_malloc") = false,
          "One control step (GIL released): model pass, rows, strict hierarchy, torques. "
          "forbid_malloc: in the checked module, a heap allocation inside the step is an "
          "error (elsewhere ignored).")
      .def_prop_ro("x", [](const NativeStep& s) { return to_numpy(s.x()); })
      .def_prop_ro("tau", [](const NativeStep& s) { return to_numpy(s.tau()); })
      .def_prop_ro("qp_count", [](const NativeStep& s) { return s.hierarchy().qp_count(); })
      .def_prop_ro("residuals", [](const NativeStep& s) { return to_numpy(s.residuals()); },
                   "Unweighted residual norm of each kernel's rows at the last x (handle order).")
      .def_prop_ro("entry_count", &NativeStep::entry_count)
      .def(
          "entry",
          [](const NativeStep& s, int handle) {
            const NativeStep::EntryInfo e = s.entry(handle);
            return nb::make_tuple(e.kind, e.level, e.built_level, e.eq0, e.neq, e.in0, e.nin,
                                  e.sqrt_w);
          },
          nb::arg("handle"),
          "(kind, stack level, built level, eq start, eq rows, ineq start, ineq rows, sqrt w).")
      .def("set_report", &NativeStep::set_report, nb::arg("tolerance"),
           nb::arg("singular_tolerance"), nb::arg("full"),
           "Compute the feasibility report in every step from now on (the statuses, "
           "projected sigma_min and yields_to of each kernel; full=False: the level's "
           "sigma_min and no yields_to).")
      .def("compute_report", &NativeStep::report,
           "Compute the feasibility report of the last step again (after set_report).")
      .def(
          "report_arrays",
          [](const NativeStep& s) {
            return nb::make_tuple(to_numpy(s.statuses()), to_numpy(s.sigmas()),
                                  to_numpy(s.yields()));
          },
          "(status, sigma_min, yields_to) of each kernel at the last step (handle order): "
          "status 0 satisfied, 1 conflict, 2 singular, -1 not reported; yields_to the stack "
          "level a conflict yields to, -1 none above (infeasible alone), -2 not a conflict.")
      .def(
          "diagnose", [](NativeStep& s) { return to_numpy(s.diagnose()); },
          "The full diagnostics' projected sigma_min of each kernel (handle order; NaN: no "
          "equality rows).")
      .def(
          "level_summary",
          [](const NativeStep& s) {
            Eigen::VectorXd cost(s.level_count()), sigma(s.level_count());
            for (int k = 0; k < s.level_count(); ++k) {
              cost[k] = s.result(k).cost;
              sigma[k] = s.result(k).sigma_min;
            }
            return nb::make_tuple(cost, sigma);
          },
          "(cost, sigma_min) of each built level of the last step.")
      .def(
          "com_state",
          [](const NativeStep& s) {
            return nb::make_tuple(to_numpy(Eigen::Vector3d(s.robot().com())),
                                  to_numpy(Eigen::Vector3d(s.robot().com_velocity())));
          },
          "(centre of mass (3,) [m], its velocity (3,) [m/s]) at the last step's state.")
      .def(
          "report_data",
          [](const NativeStep& s) {
            const int L = s.level_count();
            Eigen::VectorXd cost(L), sigma(L);
            Eigen::VectorXi weak(L);
            for (int k = 0; k < L; ++k) {
              cost[k] = s.result(k).cost;
              sigma[k] = s.result(k).sigma_min;
              weak[k] = s.result(k).weak;
            }
            return nb::make_tuple(to_numpy(cost), to_numpy(sigma), to_numpy(weak),
                                  to_numpy(s.residuals()));
          },
          "(cost, sigma_min, weak directions) of each built level and each kernel's "
          "residual of the last step, in one call (the feasibility report's data).")
      .def(
          "level_seconds",
          [](const NativeStep& s) {
            Eigen::VectorXd out(s.level_count());
            for (int k = 0; k < s.level_count(); ++k) out[k] = s.result(k).seconds;
            return out;
          },
          "Time spent on each built level in the last step's solve [s].")
      .def(
          "result",
          [](const NativeStep& s, int k) {
            if (k < 0 || k >= s.level_count()) throw std::invalid_argument("no such level");
            const LevelResult& r = s.result(k);
            return nb::make_tuple(r.cost, r.sigma_min, Eigen::VectorXi(r.state.cast<int>()));
          },
          nb::arg("k"), "The solver's report of built level k: (cost, sigma_min, row states).")
      .def(
          "levels",
          [](const NativeStep& s) {
            nb::list out;
            for (int k = 0; k < s.level_count(); ++k) {
              const LevelData& lv = s.level(k);
              out.append(nb::make_tuple(s.level_index(k), Eigen::MatrixXd(lv.A),
                                        Eigen::VectorXd(lv.b), Eigen::MatrixXd(lv.C),
                                        Eigen::VectorXd(lv.lo), Eigen::VectorXd(lv.up)));
            }
            return out;
          },
          "The last step's built levels: (stack level index, A, b, C, lower, upper).");
}

}  // namespace hqp
