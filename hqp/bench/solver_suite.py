"""The ``solver`` suite: both lexicographic algorithms on every backend, and DAQP's hierarchy.

Random hierarchies (:mod:`hqp.bench.problems`) with ``n`` in {20, 40, 80} and
2 to 5 levels: equalities, two-sided and one-sided inequalities, a conflicting
level and a rank-deficient one. Each configuration is a short sequence of
hierarchies with the same matrices and slowly drifting targets and bounds
(what a control loop sees), solved in turn by one persistent solver. The
``n = 40``, 4-level configurations are the issue's reference problem, in two
families: ``mixed`` (narrow bands: many rows active or violated, a QP at
nearly every level) and ``light`` (wide bands: a few active rows, as in a
controller whose limits are mostly far).

Row fields: ``robot`` (None), ``solver`` (``"<algorithm>/<backend>"`` or
``"daqp-hier"``), ``levels``, ``n``, ``rows`` (equality + inequality rows),
``median_ms``, ``p95_ms``, ``cpu_median_ms`` (thread CPU time, robust to other
processes on the cores), ``reps``, ``speedup_vs_cascade`` and
``cpu_speedup_vs_cascade`` (cascade median / this median on the same backend,
wall clock and CPU; basis rows), ``ratio_to_basis_proxsuite``
(this median / basis-proxsuite median), ``qp_count`` (QPs per solve),
``cost_excess`` (largest relative excess of a level's cost over the
basis-proxsuite solution, ``(cost - ref) / max(1, ref)``), ``exact`` (every
level within the contract's ``1e-6`` relative tolerance), ``family``,
``active_rows`` (inequality rows active at the solution), ``warm_start``
(the solvers' active-set warm start, :mod:`hqp.solver.active_set`, on by
default except with ``proxsuite``; the reference problem is measured a
second time with it flipped) and, for
``daqp-hier``, ``level_cost_excess`` per level.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
from tqdm import tqdm

from hqp.bench import register_suite
from hqp.bench.daqp_hier import daqp_hierarchy_data, solve_daqp_hierarchy
from hqp.bench.method import measure
from hqp.bench.problems import LevelSpec, random_hierarchy
from hqp.solver import ALGORITHMS, HierarchicalSolver, Level, available_backends, supports

N_VALUES = (20, 40, 80)
LEVEL_COUNTS = (2, 3, 4, 5)
VARIANTS = 8
"""Hierarchies per configuration (same matrices, drifting targets and bounds)."""

LIGHT_BAND = 8.0
"""Band scale of the ``light`` family (few active inequality rows)."""


def level_specs(n: int, levels: int, band: float = 1.0) -> list[LevelSpec]:
    """Return the first ``levels`` level shapes of the suite.

    In order: consistent equalities (``n/8``), two-sided limits (``n/2``), a
    conflicting task (``n/4``), a rank-deficient task with one-sided bounds
    (``n/4`` + ``n/4``), a posture task (``n/2``).

    For ``levels = 4`` and ``band = 1`` this is
    :func:`hqp.bench.problems.reference_specs`; ``band`` scales the inequality
    half widths (``band = 8``: only a few rows active, as in a controller whose
    limits are mostly far).
    """
    q = max(1, n // 4)
    kinds = [
        LevelSpec(m_eq=max(1, n // 8)),
        LevelSpec(m_in=max(1, n // 2), two_sided=True, band=band),
        LevelSpec(m_eq=q, conflicting=True),
        LevelSpec(m_eq=q, m_in=q, two_sided=False, rank_deficient=True, band=band),
        LevelSpec(m_eq=max(1, n // 2)),
    ]
    return kinds[:levels]


def drifting(levels: list[Level], count: int, rng: np.random.Generator) -> list[list[Level]]:
    """``count`` copies of ``levels`` whose targets and bounds drift slowly."""
    out = []
    for k in range(count):
        phase = 2.0 * np.pi * k / count
        variant = []
        for lv in levels:
            def shift(v: object) -> object:
                if v is None:
                    return None
                arr = np.asarray(v, dtype=float)
                return arr + 0.02 * np.sin(phase + np.arange(arr.size))
            variant.append(Level(A=lv.A, b=shift(lv.b), C=lv.C, lower=shift(lv.lower),
                                 upper=shift(lv.upper), name=lv.name))
        out.append(variant)
    return out


def _costs(levels: list[Level], x: np.ndarray) -> np.ndarray:
    out = []
    for lv in levels:
        c = 0.0
        if lv.A is not None:
            r = lv.A @ x - lv.b
            c += float(r @ r)
        if lv.C is not None:
            cx = lv.C @ x
            lo = -np.inf if lv.lower is None else lv.lower
            up = np.inf if lv.upper is None else lv.upper
            d = np.maximum(cx - up, 0.0) + np.minimum(cx - lo, 0.0)
            c += float(d @ d)
        out.append(c)
    return np.array(out)


def _cycler(fn: Callable[[int], object], count: int) -> Callable[[], object]:
    state = {"i": 0}

    def call() -> object:
        i = state["i"]
        state["i"] = (i + 1) % count
        return fn(i)

    return call


NATIVE_PEER = "daqp"
"""The Python backend that ``basis/native`` is compared with (the same QP library, DAQP)."""


@register_suite("solver")
def solver_suite(quick: bool = False, progress: Callable[[str], None] | None = None) -> list[dict]:
    """Run the solver suite; ``quick`` measures a small subset briefly (CI)."""
    n_values = (20,) if quick else N_VALUES
    level_counts = (2, 4) if quick else LEVEL_COUNTS
    budget = 0.03 if quick else 0.35
    min_reps = 3 if quick else 15
    backends = available_backends()
    solvers = [f"{a}/{b}" for b in backends for a in ALGORITHMS if supports(b, a)] + ["daqp-hier"]
    configs = [(n, L, "mixed", None) for n in n_values for L in level_counts]
    configs.append((20 if quick else 40, 4, "light", None))
    if not quick:
        # the reference problem again with the active-set warm start flipped from
        # each backend's default (both algorithms alike)
        configs.append((40, 4, "mixed", "flipped"))
    rows: list[dict] = []
    bar = tqdm(total=len(configs) * len(solvers), desc="solver suite", unit="run",
               disable=None, leave=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # qpsolvers' OSQP status warnings
        for n, L, family, warm in configs:
            rng = np.random.default_rng(1000 * n + L)
            base = random_hierarchy(rng, n, level_specs(n, L, LIGHT_BAND if family == "light"
                                                         else 1.0))
            variants = drifting(base, VARIANTS, rng)
            m = sum((0 if lv.A is None else len(lv.A)) + (0 if lv.C is None else len(lv.C))
                    for lv in base)
            ref = HierarchicalSolver("proxsuite", "basis")
            ref_sol = ref.solve(variants[0])
            ref_costs = _costs(variants[0], ref_sol.x)
            n_active = int(sum(lv.active.size for lv in ref_sol.levels))
            group = []
            for name in solvers:
                bar.set_postfix_str(f"n={n} L={L} {family} {name}"
                                    + ("" if warm is None else " (warm start flipped)"))
                if name == "daqp-hier":
                    data = [daqp_hierarchy_data(v) for v in variants]
                    x0, _flag = solve_daqp_hierarchy(data[0])
                    timing = measure(_cycler(lambda i: solve_daqp_hierarchy(data[i]),
                                             VARIANTS), budget_s=budget, min_reps=min_reps,
                                     batch=5)
                    qp_count = None
                else:
                    algorithm, backend = name.split("/")
                    ws = None if warm is None else not HierarchicalSolver(backend).warm_start
                    solver = HierarchicalSolver(backend, algorithm, compute_sigma=False,
                                                warm_start=ws)
                    sol0 = solver.solve(variants[0])
                    x0 = sol0.x
                    qp_count = sol0.qp_count
                    slow = sol0.timings["total"] > 0.05
                    timing = measure(_cycler(lambda i: solver.solve(variants[i]), VARIANTS),
                                     budget_s=budget, min_reps=3 if slow else min_reps,
                                     batch=3 if slow else 5)
                excess = (_costs(variants[0], x0) - ref_costs) / np.maximum(1.0, ref_costs)
                row = {
                    "robot": None,
                    "solver": name,
                    "levels": L,
                    "n": n,
                    "rows": int(m),
                    "median_ms": round(timing.median_ms, 4),
                    "p95_ms": round(timing.p95_ms, 4),
                    "cpu_median_ms": round(timing.cpu_median_ms, 4),
                    "reps": timing.reps,
                    "qp_count": qp_count,
                    "cost_excess": float(np.max(excess)),
                    "exact": bool(np.all(np.abs(excess) <= 1e-6)),
                    "family": family,
                    "active_rows": n_active,
                    "reference_problem": n == 40 and L == 4,
                    "warm_start": None if name == "daqp-hier" else solver.warm_start,
                }
                if name == "daqp-hier":
                    row["level_cost_excess"] = [float(e) for e in excess]
                group.append(row)
                bar.update(1)
                if progress is not None:
                    progress(f"n={n} L={L} {family} {name}: {timing.median_ms:.3f} ms")
            by_name = {r["solver"]: r for r in group}
            base_ms = by_name.get("basis/proxsuite", {}).get("median_ms")
            for r in group:
                if r["solver"].startswith("basis/"):
                    # native: against the Python algorithms on the same QP library (DAQP)
                    bk = r["solver"].split("/", 1)[1]
                    cascade = by_name.get("cascade/" + (NATIVE_PEER if bk == "native" else bk))
                    if bk == "native" and f"basis/{NATIVE_PEER}" in by_name:
                        py = by_name[f"basis/{NATIVE_PEER}"]
                        r["speedup_vs_python_basis"] = round(py["median_ms"] / r["median_ms"], 3)
                        r["cpu_speedup_vs_python_basis"] = round(
                            py["cpu_median_ms"] / max(r["cpu_median_ms"], 1e-9), 3)
                    if cascade:
                        r["speedup_vs_cascade"] = round(cascade["median_ms"] / r["median_ms"], 3)
                        r["cpu_speedup_vs_cascade"] = round(
                            cascade["cpu_median_ms"] / max(r["cpu_median_ms"], 1e-9), 3)
                if base_ms:
                    r["ratio_to_basis_proxsuite"] = round(r["median_ms"] / base_ms, 3)
            rows += group
    bar.close()
    return rows
