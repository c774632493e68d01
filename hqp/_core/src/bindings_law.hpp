// Python bindings of the null-space law (hqp._core._ext.NullSpaceLaw, NativeLaw): the law on
// plain matrices (the tests' entry point against hqp.control.nullspace.law) and the law's
// control step on a NativeStep (hqp.control.nullspace.native).
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

#include "bindings_numpy.hpp"
#include "bindings_release.hpp"
#include "control/law.hpp"
#include "solver/linalg.hpp"

namespace hqp {

namespace nb = nanobind;

namespace law_detail {

/// The per-level report of a law: (start, rows, rank, free, threshold, target_norm) each.
inline nb::list levels(const NullSpaceLaw& law) {
  nb::list out;
  for (Index k = 0; k < law.level_count(); ++k) {
    const LawLevelInfo& l = law.level(k);
    out.append(nb::make_tuple(l.start, l.rows, l.rank, l.free, l.threshold, l.target_norm));
  }
  return out;
}

}  // namespace law_detail

inline void bind_law(nb::module_& m) {
  nb::register_exception_translator([](const std::exception_ptr& p, void*) {
    try {
      std::rethrow_exception(p);
    } catch (const LawError& e) {
      nb::object cls = nb::module_::import_("hqp.errors").attr("InvalidInput");
      PyErr_SetString(cls.ptr(), e.what());
    }
  });

  nb::class_<NullSpaceLaw>(m, "NullSpaceLaw",
                           "The null-space law on plain matrices (prioritized_torques, "
                           "method='whitened'), S = [0 I].")
      .def(nb::init<Index, Index>(), nb::arg("nv"), nb::arg("nv_base"))
      .def(
          "solve",
          [](NullSpaceLaw& law, const Eigen::MatrixXd& M, const Eigen::VectorXd& h,
             const Eigen::MatrixXd& Js, const Eigen::VectorXd& bs, const Eigen::MatrixXd& J,
             const Eigen::VectorXd& a, const std::vector<Index>& starts, double eig_tol,
             bool min_norm, bool forbid_malloc) {
            if (starts.empty() || starts.front() != 0 || starts.back() != J.rows())
              throw LawError("null-space law: starts must run from 0 to the rows of J");
            for (std::size_t k = 1; k < starts.size(); ++k) {
              if (starts[k] < starts[k - 1]) throw LawError("null-space law: starts decrease");
            }
            if (!(eig_tol > 0.0 && eig_tol < 1.0))
              throw LawError("null-space law: eig_tol must be in (0, 1)");
            if (J.cols() != M.rows() || a.size() != J.rows())
              throw LawError("null-space law: level rows J (m, nv) and a (m,) expected");
            return released(forbid_malloc, "step", [&]() {
              std::string e = law.dynamics(M, h, Js, bs);
              if (!e.empty()) return e;
              law.solve(J, a, starts.data(), Index(starts.size()) - 1, eig_tol);
              law.finish(J, a, min_norm);
              return std::string();
            });
          },
          nb::arg("M"), nb::arg("h"), nb::arg("Js"), nb::arg("bs"), nb::arg("J"), nb::arg("a"),
          nb::arg("starts"), nb::arg("eig_tol"), nb::arg("min_norm"),
          nb::arg("forbid_malloc") = false,
          "Dynamics, levels and internal forces; returns '' or why the law cannot run.")
      .def_prop_ro("tau", [](const NullSpaceLaw& l) { return to_numpy(l.tau()); })
      .def_prop_ro("tau_internal",
                   [](const NullSpaceLaw& l) { return to_numpy(l.tau_internal()); })
      .def_prop_ro("qdd", [](const NullSpaceLaw& l) { return to_numpy(l.qdd()); })
      .def_prop_ro("f", [](const NullSpaceLaw& l) { return to_numpy(l.f()); })
      .def_prop_ro("qdd0", [](const NullSpaceLaw& l) { return to_numpy(l.qdd0()); })
      .def_prop_ro("phi", [](const NullSpaceLaw& l) { return Eigen::MatrixXd(l.phi()); })
      .def_prop_ro("phi_pinv",
                   [](const NullSpaceLaw& l) { return Eigen::MatrixXd(l.phi_pinv()); })
      .def_prop_ro("torque_to_qdd",
                   [](const NullSpaceLaw& l) { return Eigen::MatrixXd(l.torque_to_qdd()); })
      .def_prop_ro("whiten", [](const NullSpaceLaw& l) { return Eigen::MatrixXd(l.whiten()); })
      .def_prop_ro("rank", &NullSpaceLaw::rank)
      .def_prop_ro("eigenvalues",
                   [](const NullSpaceLaw& l) { return to_numpy(l.eigenvalues()); })
      .def_prop_ro("forces", [](const NullSpaceLaw& l) { return to_numpy(l.forces()); })
      .def_prop_ro("residuals",
                   [](const NullSpaceLaw& l) { return to_numpy(l.residuals()); })
      .def("levels", &law_detail::levels,
           "Per level: (start, rows, rank, free, threshold, target_norm).")
      .def(
          "basis",
          [](const NullSpaceLaw& l, Index k) {
            if (k < 0 || k > l.level_count()) throw LawError("null-space law: no such basis");
            return Eigen::MatrixXd(l.basis(k));
          },
          nb::arg("k"), "Z_k (r, free_k), k = 0 .. len(levels()).");

  nb::class_<JointLimitZoneKernel>(m, "JointLimitZoneKernel")
      .def(
          "__init__",
          [](JointLimitZoneKernel* self, const Eigen::VectorXd& low_edge,
             const Eigen::VectorXd& high_edge, const Eigen::VectorXd& low_safe,
             const Eigen::VectorXd& high_safe, double kp, double kv, double max_velocity) {
            new (self) JointLimitZoneKernel();
            self->low_edge = low_edge;
            self->high_edge = high_edge;
            self->low_safe = low_safe;
            self->high_safe = high_safe;
            self->kp = kp;
            self->kv = kv;
            self->max_velocity = max_velocity;
          },
          nb::arg("low_edge"), nb::arg("high_edge"), nb::arg("low_safe"), nb::arg("high_safe"),
          nb::arg("kp"), nb::arg("kv"), nb::arg("max_velocity"),
          "Zones q < low_edge or q > high_edge, driven to low_safe / high_safe (eq. 25, 27-28).");

  nb::class_<NativeLaw>(m, "NativeLaw",
                        "The null-space law's control step on a NativeStep's kernels.")
      .def(
          "__init__",
          [](NativeLaw* self, NativeStep& step, double eig_tol, bool min_norm) {
            new (self) NativeLaw(step, LawSettings{eig_tol, min_norm});
          },
          nb::arg("step"), nb::arg("eig_tol"), nb::arg("min_norm"), nb::keep_alive<1, 2>())
      .def("add_level", &NativeLaw::add_level, nb::arg("physics"))
      .def("add_entry", &NativeLaw::add_entry, nb::arg("level"), nb::arg("handle"),
           nb::arg("slot_start") = -1)
      .def("add_zone", &NativeLaw::add_zone, nb::arg("level"), nb::arg("weight"),
           nb::arg("kernel"))
      .def(
          "set_settings",
          [](NativeLaw& s, double eig_tol, bool min_norm) {
            if (!(eig_tol > 0.0 && eig_tol < 1.0))
              throw LawError("null-space law: eig_tol must be in (0, 1)");
            s.settings() = LawSettings{eig_tol, min_norm};
          },
          nb::arg("eig_tol"), nb::arg("min_norm"))
      .def(
          "step",
          [](NativeLaw& s, Eigen::Ref<const Eigen::VectorXd> q,
             Eigen::Ref<const Eigen::VectorXd> v, double dt, bool forbid_malloc) {
            const RobotCore& robot = s.native_step().robot();
            if (q.size() != robot.nq() || v.size() != robot.nv())
              throw LawError("state shapes: expected (" + std::to_string(robot.nq()) + "), (" +
                             std::to_string(robot.nv()) + ")");
            if (!(dt > 0.0)) throw LawError("dt must be > 0");
            return released(forbid_malloc, "step", [&]() { return s.step(q, v, dt); });
          },
          nb::arg("q"), nb::arg("v"), nb::arg("dt"), nb::arg("forbid_malloc") = false,
          "One step of the law (GIL released): the NativeStep's model pass and rows, the "
          "activation zones, the law, x and the report's numbers. Returns '' or why the law "
          "cannot run this step (the Python law then runs it).")
      .def_prop_ro("x", [](const NativeLaw& s) { return to_numpy(s.x()); })
      .def_prop_ro("tau", [](const NativeLaw& s) { return to_numpy(s.tau()); })
      .def_prop_ro("law", [](const NativeLaw& s) -> const NullSpaceLaw& { return s.law(); },
                   nb::rv_policy::reference_internal)
      .def(
          "report",
          [](const NativeLaw& s) {
            const int n = s.source_count();
            Eigen::VectorXd residual(n), eig(n);
            Eigen::VectorXi flags(n), level(n), start(n), count(n);
            for (int i = 0; i < n; ++i) {
              const NativeLaw::SourceResult& r = s.source(i);
              residual[i] = r.residual;
              eig[i] = r.eig_min;
              flags[i] = int(r.present) | (int(r.force_rows) << 1) | (int(r.singular) << 2);
              level[i] = r.law_level;
              start[i] = int(r.start);
              count[i] = int(r.count);
            }
            const int k = s.level_count();
            Eigen::VectorXd cost(k);
            Eigen::VectorXi present(k);
            for (int j = 0; j < k; ++j) {
              cost[j] = s.level_cost(j);
              present[j] = s.level_present(j);
            }
            return nb::make_tuple(to_numpy(residual), to_numpy(eig), to_numpy(flags), to_numpy(level),
                                  to_numpy(start), to_numpy(count), to_numpy(cost),
                                  to_numpy(present));
          },
          "Per source (residual, eig_min, flags: 1 rows present, 2 force rows at a task "
          "level, 4 singular, law level, start, rows) and per stack level (cost, present).")
      .def(
          "diagnose",
          [](NativeLaw& s, double singular_tolerance, bool forbid_malloc) {
            const std::string error = released(forbid_malloc, "step", [&]() {
              s.diagnose(singular_tolerance);
              return std::string();
            });
            if (!error.empty()) throw std::runtime_error(error);
          },
          nb::arg("singular_tolerance"), nb::arg("forbid_malloc") = false,
          "Per source eig_min and singular flag of the full diagnostics (read by report()).")
      .def(
          "zone",
          [](const NativeLaw& s, int source) {
            const JointLimitZoneKernel& z = s.zone(source);
            return nb::make_tuple(to_numpy(z.active.head(z.count)), to_numpy(z.error.head(z.count)),
                                  to_numpy(z.ref.head(z.count)));
          },
          nb::arg("source"), "(active joints, q_limit - q, qdd_ref) of a zone at the last step.")
      .def(
          "law_levels",
          [](const NativeLaw& s) {
            Eigen::VectorXi out(s.law().level_count());
            for (Index k = 0; k < s.law().level_count(); ++k) out[k] = s.law_level_index(int(k));
            return out;
          },
          "The stack level of each law level of the last step.")
      .def_prop_ro("rows", [](const NativeLaw& s) { return Eigen::MatrixXd(s.rows()); })
      .def_prop_ro("targets", [](const NativeLaw& s) { return to_numpy(s.targets()); })
      .def_prop_ro("support", [](const NativeLaw& s) { return Eigen::MatrixXd(s.support()); })
      .def_prop_ro("support_targets",
                   [](const NativeLaw& s) { return to_numpy(s.support_targets()); });
}

}  // namespace hqp
