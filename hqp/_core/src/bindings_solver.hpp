// Python bindings of the native solver, shared by hqp._core._ext and the allocation-checked
// hqp._core._ext_checked (which differ only in how the solver sources were compiled).
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>

#include <algorithm>
#include <cstdint>
#include <optional>
#include <vector>

#include <cmath>
#include <memory>
#include <string>

#include "bindings_numpy.hpp"
#include "bindings_release.hpp"
#include "solver/active_set.hpp"
#include "solver/hierarchy.hpp"
#include "solver/nnls.hpp"

namespace hqp {

namespace nb = nanobind;
using DMat = nb::DRef<const Eigen::MatrixXd>;
using DVec = nb::DRef<const Eigen::VectorXd>;

/// The first malformed level (-1: none): shapes, NaN or inf in A, b, C, NaN in a bound,
/// lower > upper, +inf lower, -inf upper. Python explains it (hqp.solver.level).
inline long check_level(const LevelData& lv, Index n) {
  if (lv.A.cols() != n || lv.C.cols() != n || lv.b.size() != lv.A.rows() ||
      lv.lo.size() != lv.C.rows() || lv.up.size() != lv.C.rows())
    return 1;
  if (!lv.A.allFinite() || !lv.b.allFinite() || !lv.C.allFinite()) return 1;
  for (Index i = 0; i < lv.C.rows(); ++i) {
    const double l = lv.lo(i), u = lv.up(i);
    if (std::isnan(l) || std::isnan(u) || l > u || l == HUGE_VAL || u == -HUGE_VAL) return 1;
  }
  return 0;
}

class PySolver {
 public:
  PySolver(double rank_tol, bool warm_start, bool compute_sigma)
      : hierarchy_(Settings{rank_tol, warm_start, compute_sigma}) {}

  /// levels: list of (A, b, C, lower, upper[, weak_threshold]) float64 arrays of one n; final: None or
  /// (A, b, kind, a_scale) of the final-metric level. Returns the failing level's index
  /// (validation), or a result tuple.
  nb::object solve(nb::list levels, Index n, nb::object final, bool validate,
                   bool forbid_malloc) {
    const std::size_t L = nb::len(levels);
    const std::size_t extra = final.is_none() ? 1 : 2;
    hierarchy_.resize_levels(L + extra);
    auto& data = hierarchy_.levels();
    for (std::size_t k = 0; k < L; ++k) {
      nb::tuple t = nb::cast<nb::tuple>(levels[k]);
      LevelData& lv = data[k];
      lv.A = nb::cast<DMat>(t[0]);
      lv.b = nb::cast<DVec>(t[1]);
      lv.C = nb::cast<DMat>(t[2]);
      lv.lo = nb::cast<DVec>(t[3]);
      lv.up = nb::cast<DVec>(t[4]);
      lv.weak = nb::len(t) > 5 ? nb::cast<double>(t[5]) : 0.0;
      lv.kind = LevelKind::kUser;
      if (validate && check_level(lv, n)) return nb::int_(long(k));
      lv.finish();
    }
    std::size_t k = L;
    if (!final.is_none()) {
      nb::tuple t = nb::cast<nb::tuple>(final);
      LevelData& lv = data[k++];
      lv.A = nb::cast<DMat>(t[0]);
      lv.b = nb::cast<DVec>(t[1]);
      lv.kind = LevelKind(nb::cast<int>(t[2]));
      lv.C.resize(0, n);
      lv.lo.resize(0);
      lv.up.resize(0);
      lv.weak = 0.0;
      lv.finish();
      lv.a_scale = nb::cast<double>(t[3]);
    }
    LevelData& norm = data[k];
    if (norm.A.rows() != n || norm.A.cols() != n || norm.kind != LevelKind::kNorm ||
        !norm.b.isZero(0.0)) {
      norm.set_norm(n);
    }
    norm.a_scale = 1.0;
    const std::string error = run(n, Index(L), forbid_malloc);  // (the GIL released)
    if (!error.empty()) return nb::str(error.c_str());
    const auto& res = hierarchy_.results();
    nb::list reports;
    for (std::size_t j = 0; j < L; ++j) {
      const LevelResult& r = res[j];
      active_.clear();
      violated_.clear();
      for (Index i = 0; i < r.state.size(); ++i) {
        if (r.state(i)) active_.push_back(i);
        if (r.state(i) == 2) violated_.push_back(i);
      }
      reports.append(nb::make_tuple(
          r.cost, r.satisfied, r.sigma_min,
          to_numpy(r.residual_eq.data(), std::size_t(r.residual_eq.size())),
          to_numpy(r.violation_in.data(), std::size_t(r.violation_in.size())),
          to_numpy(active_.data(), active_.size()), to_numpy(violated_.data(), violated_.size()),
          r.seconds, r.weak));
    }
    const Eigen::VectorXd& x = hierarchy_.x();
    return nb::make_tuple(to_numpy(x.data(), std::size_t(x.size())), reports,
                          hierarchy_.qp_count(), hierarchy_.final_seconds());
  }

  void reset() { hierarchy_.reset(); }
  int anchored() const { return hierarchy_.anchored(); }

 private:
  std::string run(Index n, Index L, bool forbid_malloc) {
    return released(forbid_malloc, "solve", [&] { return hierarchy_.solve(n, L); });
  }

  Hierarchy hierarchy_;
  std::vector<int64_t> active_, violated_;
};

inline void bind_solver(nb::module_& m) {
  nb::class_<PySolver>(m, "Solver")
      .def(nb::init<double, bool, bool>(), nb::arg("rank_tol"), nb::arg("warm_start"),
           nb::arg("compute_sigma"))
      .def("solve", &PySolver::solve, nb::arg("levels"), nb::arg("n"), nb::arg("final").none(),
           nb::arg("validate"), nb::arg("forbid_malloc") = false)
      .def("reset", &PySolver::reset)
      .def_prop_ro("anchored", &PySolver::anchored,
                   "Levels of the last solve whose point was the anchor's (the previous "
                   "solution's least-squares point, strictly inside every bound).");
  m.def("solver_simd", &solver_simd,
        "The instruction set the solver's translation units were compiled for: \"avx2+fma\" "
        "(HQP_SIMD=AUTO on a machine with them, or ON) or \"sse2\".");
  m.def("solver_simd_option", &solver_simd_option, "The build's HQP_SIMD option.");
  m.def(
      "row_support_project",
      [](const Eigen::MatrixXd& M, const Eigen::MatrixXd& Z) {
        if (M.cols() != Z.rows()) throw std::invalid_argument("M (m, c) and Z (c, r)");
        RowSupport support;
        support.compute(M);
        Eigen::MatrixXd out(M.rows(), Z.cols());
        MapM view(out.data(), out.rows(), out.cols());
        support.project(M, CMapM(Z.data(), Z.rows(), Z.cols()), view);
        return nb::make_tuple(out, support.blocks());
      },
      nb::arg("M"), nb::arg("Z"),
      "M Z through the solver's RowSupport (tests): (product, number of row blocks).");
  m.def(
      "level_qp",
      [](const Eigen::MatrixXd& H, const Eigen::VectorXd& g, const Eigen::MatrixXd& C,
         const Eigen::VectorXd& lo, const Eigen::VectorXd& up) {
        LevelQP qp;
        Eigen::VectorXd v(H.rows());
        const bool ok = qp.solve(H, g, C, lo, up, v);
        return nb::make_tuple(v, ok);
      },
      nb::arg("H"), nb::arg("g"), nb::arg("C"), nb::arg("lo"), nb::arg("up"),
      "The compiled level QP (DAQP with the hierarchy's retries): min 0.5 v'Hv + g'v, "
      "lo <= C v <= up; returns (v, converged). For tests.");
  m.def(
      "primal_qp",
      [](const Eigen::MatrixXd& H, const Eigen::VectorXd& g, const Eigen::MatrixXd& C,
         const Eigen::VectorXd& lo, const Eigen::VectorXd& up, const Eigen::VectorXd& start,
         int max_iter, bool forbid_malloc) {
        const Index n = H.rows(), m = C.rows();
        if (H.cols() != n || g.size() != n || C.cols() != n || lo.size() != m ||
            up.size() != m || start.size() != n)
          throw std::invalid_argument("primal_qp: inconsistent shapes");
        using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
        const RowMatrix Hr = H, Cr = C;
        PrimalQP qp;
        qp.reserve(n, m);
        Eigen::VectorXd v = start;
        bool ok = false;
        const std::string error = released(forbid_malloc, "primal QP", [&] {
          ok = qp.solve(Hr, g, Cr, lo, up, v, max_iter);
          return std::string();
        });
        if (!error.empty()) throw std::runtime_error(error);
        return nb::make_tuple(v, ok, qp.iterations());
      },
      nb::arg("H"), nb::arg("g"), nb::arg("C"), nb::arg("lo"), nb::arg("up"), nb::arg("start"),
      nb::arg("max_iter"), nb::arg("forbid_malloc") = false,
      "The primal active-set QP (PrimalQP) from a feasible start: returns (v, converged, "
      "working-set changes). `forbid_malloc`: Eigen's allocation check around the solve (the "
      "_ext_checked build). For tests.");
  m.def(
      "nnls",
      [](const Eigen::MatrixXd& A, const Eigen::VectorXd& b, double res_tol, int max_outer,
         std::optional<Eigen::VectorXi> warm) {
        Nnls solver;
        const CMapI w(warm ? warm->data() : nullptr, warm ? warm->size() : 0);
        const bool ok = solver.solve(A, b, res_tol, max_outer, warm ? &w : nullptr);
        return nb::make_tuple(Eigen::VectorXd(solver.x()), solver.residual(), ok,
                              solver.steps());
      },
      nb::arg("A"), nb::arg("b"), nb::arg("res_tol"), nb::arg("max_outer"),
      nb::arg("warm").none() = nb::none(),
      "The native solver's non-negative least squares: min ||A x - b||, x >= 0, early exit "
      "at res_tol (< 0: none); returns (x, residual, residual <= res_tol, column entries). "
      "For tests.");
  m.def(
      "active_set_solve",
      [](const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::MatrixXd& C,
         const Eigen::VectorXd& lo, const Eigen::VectorXd& up, const Eigen::VectorXd& los,
         const Eigen::VectorXd& ups, const Eigen::MatrixXd& G, const Eigen::VectorXd& gl,
         const Eigen::VectorXd& gu, const Eigen::VectorXd& gls, const Eigen::VectorXd& gus,
         Eigen::VectorXi s, Eigen::VectorXi w, double rank_tol, double scale, int max_iter) {
        const Index nv = A.cols();
        if (C.cols() != nv || G.cols() != nv || b.size() != A.rows() || s.size() != C.rows() ||
            lo.size() != C.rows() || up.size() != C.rows() || los.size() != C.rows() ||
            ups.size() != C.rows() || w.size() != G.rows() || gl.size() != G.rows() ||
            gu.size() != G.rows() || gls.size() != G.rows() || gus.size() != G.rows() ||
            max_iter < 0)
          throw std::invalid_argument("active_set_solve: inconsistent shapes");
        ActiveSetSolver solver;
        solver.reserve(A.rows(), C.rows(), G.rows(), nv, nv, max_iter);
        const LevelRows L{A, b, C, lo, up, los, ups};
        const CarriedRows K{G, gl, gu, gls, gus};
        Eigen::VectorXd v(nv);
        const bool ok = solver.solve(L, K, s, w, rank_tol, scale, max_iter, nullptr, v);
        return nb::make_tuple(ok ? nb::cast(v) : nb::none(), s, w);
      },
      nb::arg("A"), nb::arg("b"), nb::arg("C"), nb::arg("lo"), nb::arg("up"), nb::arg("los"),
      nb::arg("ups"), nb::arg("G"), nb::arg("gl"), nb::arg("gu"), nb::arg("gls"),
      nb::arg("gus"), nb::arg("s"), nb::arg("w"), nb::arg("rank_tol"), nb::arg("scale"),
      nb::arg("max_iter"),
      "The native active-set warm start of one level (hqp.solver.active_set.solve_guess "
      "without E and ref): returns (v or None, last s, last w). For tests.");
  m.def(
      "qp_stats",
      []() {
        const QPStats st = qp_stats();
        const std::size_t k = QPStats::kSlots;
        Eigen::Matrix<long long, Eigen::Dynamic, 1> calls(k), ok(k), ns(k), iters(k);
        Eigen::Matrix<long long, Eigen::Dynamic, 1> failures(QPStats::kFlags);
        for (std::size_t i = 0; i < k; ++i) {
          calls[Index(i)] = st.calls[i];
          ok[Index(i)] = st.successes[i];
          ns[Index(i)] = st.nanoseconds[i];
          iters[Index(i)] = st.iterations[i];
        }
        for (int i = 0; i < QPStats::kFlags; ++i) failures[i] = st.failures[i];
        return nb::make_tuple(calls, ok, ns, iters, failures);
      },
      "The level QPs' retry statistics of this process: (calls, successes, nanoseconds, "
      "iterations) per attempt, DAQP's (margin 0, 1e-9, 1e-7) x (primal_tol 1e-10, 1e-8) x "
      "(eps_prox 1e-6, 1e-4, 1e-2, 1, auto) in that nesting order, then ProxQP's, then the "
      "primal active-set method's (from the level's known feasible point); and the failed "
      "DAQP calls by exit flag (index -flag; 0: a non-finite point).");
  m.def("reset_qp_stats", &reset_qp_stats, "Zero the level QPs' retry statistics.");
#ifdef HQP_CHECK_MALLOC
  m.attr("malloc_checked") = true;
#else
  m.attr("malloc_checked") = false;
#endif
}

}  // namespace hqp
