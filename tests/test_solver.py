"""The lexicographic solver against closed forms, planted optima and an independent cascade."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import quadprog

import hqp
from hqp.solver import (
    ALGORITHMS,
    HierarchicalSolver,
    Level,
    LevelReport,
    Solution,
    available_backends,
    solve,
)

BACKENDS = available_backends()
COMBOS = [(b, a) for b in BACKENDS for a in ALGORITHMS if b != "native" or a == "basis"]
SOLVERS = [("proxsuite", "basis"), ("proxsuite", "cascade"), ("native", "basis")]
"""The solvers of the closed-form and reference tests: both Python algorithms and the core."""


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # qpsolvers' OSQP status warnings
        yield


# ----------------------------------------------------------------- references


def pinv_recursion(eq_levels, n, metric=None, target=None, rcond=1e-10):
    """Closed-form recursive pseudo-inverse solution (projector form, SVD pseudo-inverse).

    x_k = x_{k-1} + (A_k P_{k-1})^+ (b_k - A_k x_{k-1}),
    P_k = P_{k-1} - (A_k P_{k-1})^+ A_k P_{k-1}.
    Starting from x = 0 this is the minimum-norm lexicographic optimum. With a
    positive definite metric M and target t, the final step is
    x = x_L + P (P M P)^+ P M (t - x_L).
    """
    def pinv(M, scale):
        U, s, Vt = np.linalg.svd(M, full_matrices=False)
        keep = s > rcond * max(s[0] if s.size else 0.0, scale)
        return (Vt[keep].T / s[keep]) @ U[:, keep].T

    x = np.zeros(n)
    P = np.eye(n)
    for A, b in eq_levels:
        AP = A @ P
        AP_pinv = pinv(AP, np.linalg.norm(A, 2))
        x = x + AP_pinv @ (b - A @ x)
        P = P - AP_pinv @ AP
    if metric is not None:
        t = np.zeros(n) if target is None else target
        PMP = P @ metric @ P
        x = x + P @ pinv(PMP, np.linalg.norm(metric, 2)) @ P @ metric @ (t - x)
    elif target is not None:
        x = x + P @ (target - x)
    return x


def level_cost(lv: Level, x: np.ndarray) -> float:
    cost = 0.0
    if lv.A is not None:
        r = np.asarray(lv.A) @ x - np.asarray(lv.b)
        cost += float(r @ r)
    if lv.C is not None:
        cx = np.asarray(lv.C) @ x
        lo = np.full(cx.shape, -np.inf) if lv.lower is None else np.asarray(lv.lower, float)
        up = np.full(cx.shape, np.inf) if lv.upper is None else np.asarray(lv.upper, float)
        d = np.maximum(cx - up, 0.0) + np.minimum(cx - lo, 0.0)
        cost += float(d @ d)
    return cost


def quadprog_cascade(levels, n, delta=1e-9):
    """Independent cascade: quadprog directly, each level in (x, w) over the full x.

    Earlier levels are held by fixing their equality residuals (independent rows
    only) and keeping every inequality row within its optimal violation. Returns
    the optimal cost of each level. ``delta`` regularises x (quadprog needs PD).
    """
    held_E = np.zeros((0, n))
    held_e = np.zeros(0)
    held_G = np.zeros((0, n))
    held_lo = np.zeros(0)
    held_up = np.zeros(0)
    costs = []
    for lv in levels:
        A = np.zeros((0, n)) if lv.A is None else np.asarray(lv.A, float)
        b = np.zeros(0) if lv.A is None else np.asarray(lv.b, float)
        C = np.zeros((0, n)) if lv.C is None else np.asarray(lv.C, float)
        mi = C.shape[0]
        lo = np.full(mi, -np.inf) if lv.lower is None else np.asarray(lv.lower, float)
        up = np.full(mi, np.inf) if lv.upper is None else np.asarray(lv.upper, float)
        nv = n + mi
        H = np.zeros((nv, nv))
        H[:n, :n] = A.T @ A + delta * np.eye(n)
        H[n:, n:] = np.eye(mi)
        f = np.zeros(nv)
        f[:n] = A.T @ b
        # quadprog: min 1/2 v'Hv - f'v  s.t.  Cq' v >= bq, first meq equalities
        rows, rhs = [], []
        for e_row, e_val in zip(held_E, held_e):
            rows.append(np.r_[e_row, np.zeros(mi)])
            rhs.append(e_val)
        meq = len(rows)
        for g, gl, gu in zip(held_G, held_lo, held_up):
            if np.isfinite(gl):
                rows.append(np.r_[g, np.zeros(mi)])
                rhs.append(gl)
            if np.isfinite(gu):
                rows.append(np.r_[-g, np.zeros(mi)])
                rhs.append(-gu)
        for i in range(mi):
            unit = np.zeros(mi)
            unit[i] = -1.0
            if np.isfinite(lo[i]):
                rows.append(np.r_[C[i], unit])
                rhs.append(lo[i])
            if np.isfinite(up[i]):
                rows.append(np.r_[-C[i], -unit])
                rhs.append(-up[i])
        if rows:
            v = quadprog.solve_qp(H, f, np.array(rows).T, np.array(rhs, dtype=float), meq)[0]
        else:
            v = quadprog.solve_qp(H, f)[0]
        x = v[:n]
        costs.append(level_cost(lv, x))
        # hold the level: residuals and violations
        for a in A:
            stacked = np.vstack([held_E, a])
            if np.linalg.matrix_rank(stacked, tol=1e-8 * max(1.0, np.abs(stacked).max())) > \
                    held_E.shape[0]:
                held_E = stacked
        held_e = held_E @ x
        if mi:
            cx = C @ x
            held_G = np.vstack([held_G, C])
            held_lo = np.r_[held_lo, np.minimum(lo, cx) - 1e-9]
            held_up = np.r_[held_up, np.maximum(up, cx) + 1e-9]
        gx = held_G @ x
        held_lo = np.minimum(held_lo, gx - 1e-9)
        held_up = np.maximum(held_up, gx + 1e-9)
    return np.array(costs)


def random_levels(rng, n, shapes, conflict=True):
    """Random levels: ``shapes`` is a list of (m_eq, m_in, two_sided, deficient)."""
    x_ref = rng.standard_normal(n)
    levels, rows = [], []
    for k, (me, mi, two, deficient) in enumerate(shapes):
        A = b = C = lo = up = None
        if me:
            A = rng.standard_normal((me, n))
            if deficient and me > 1:
                A[me // 2:] = rng.standard_normal((me - me // 2, me // 2 or 1)) @ A[: me // 2 or 1]
            if conflict and rows and me > 1:
                A[0] = rng.standard_normal(len(rows)) @ np.array(rows)
            b = A @ x_ref + rng.standard_normal(me)
        if mi:
            C = rng.standard_normal((mi, n))
            if deficient and mi > 1:
                C[mi // 2:] = rng.standard_normal((mi - mi // 2, mi // 2 or 1)) @ C[: mi // 2 or 1]
            centre = C @ x_ref + rng.uniform(-2.0, 2.0, mi)
            half = rng.uniform(0.1, 1.0, mi)
            up = centre + half
            lo = centre - half if two else None
        levels.append(Level(A=A, b=b, C=C, lower=lo, upper=up, name=f"L{k}"))
        rows += [r for m in (A, C) if m is not None for r in m]
    return levels


def cost_tol(ref):
    return 1e-6 * np.maximum(1.0, np.abs(ref))


# ------------------------------------------------------------ equality-only


@pytest.mark.parametrize("seed", range(6))
def test_equality_only_matches_recursive_pseudo_inverse(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(6, 14))
    sizes = rng.integers(1, n // 2 + 2, size=int(rng.integers(2, 5)))
    eq = []
    for m in sizes:
        A = rng.standard_normal((int(m), n))
        eq.append((A, rng.standard_normal(int(m))))
    levels = [Level(A=A, b=b) for A, b in eq]
    ref = pinv_recursion(eq, n)
    for backend, algorithm in SOLVERS:
        sol = solve(levels, backend=backend, algorithm=algorithm)
        np.testing.assert_allclose(sol.x, ref, atol=1e-8, rtol=0)


@pytest.mark.parametrize("seed", range(4))
def test_equality_only_with_final_metric_and_target(seed):
    rng = np.random.default_rng(100 + seed)
    n = 12
    eq = [(rng.standard_normal((3, n)), rng.standard_normal(3)),
          (rng.standard_normal((4, n)), rng.standard_normal(4))]
    levels = [Level(A=A, b=b) for A, b in eq]
    B = rng.standard_normal((n, n))
    M = B @ B.T + 0.1 * np.eye(n)  # positive definite
    t = rng.standard_normal(n)
    for backend, algorithm in SOLVERS:
        sol = solve(levels, backend=backend, algorithm=algorithm, final_metric=M, final_target=t)
        np.testing.assert_allclose(sol.x, pinv_recursion(eq, n, M, t), atol=1e-8, rtol=0)
        # target only (identity metric): the projection of t on the optimal set
        sol = solve(levels, backend=backend, algorithm=algorithm, final_target=t)
        np.testing.assert_allclose(sol.x, pinv_recursion(eq, n, None, t), atol=1e-8, rtol=0)


@pytest.mark.parametrize("backend", ["proxsuite", "native"])
def test_semidefinite_metric_ties_broken_by_minimum_norm(backend):
    rng = np.random.default_rng(7)
    n = 8
    A = rng.standard_normal((2, n))
    b = rng.standard_normal(2)
    W = np.zeros((n, n))
    W[:3, :3] = np.diag([1.0, 2.0, 3.0])  # metric on the first 3 variables only
    t = rng.standard_normal(n)
    sol = solve([Level(A=A, b=b)], backend=backend, final_metric=W, final_target=t)
    R = np.sqrt(W)
    ref = pinv_recursion([(A, b), (R, R @ t), (np.eye(n), np.zeros(n))], n)
    np.testing.assert_allclose(sol.x, ref, atol=1e-8)


def test_conflicting_and_rank_deficient_equalities():
    rng = np.random.default_rng(3)
    n = 6
    A0 = rng.standard_normal((2, n))
    b0 = rng.standard_normal(2)
    # level 1 repeats a row of level 0 with another target (conflict) and holds two
    # identical rows (rank deficient)
    a = rng.standard_normal(n)
    A1 = np.vstack([A0[0], a, a])
    b1 = np.array([b0[0] + 1.0, 0.5, 0.5])
    levels = [Level(A=A0, b=b0, name="top"), Level(A=A1, b=b1, name="low")]
    ref = pinv_recursion([(A0, b0), (A1, b1)], n)
    for backend, algorithm in SOLVERS:
        sol = solve(levels, backend=backend, algorithm=algorithm)
        np.testing.assert_allclose(sol.x, ref, atol=1e-8)
        top, low = sol.levels
        assert top.satisfied
        assert not low.satisfied
        np.testing.assert_allclose(low.cost, 1.0, atol=1e-9)  # the conflicting row only
        assert low.sigma_min == 0.0  # 3 rows, rank 1 in the free directions
        s = np.linalg.svd(A0, compute_uv=False)
        np.testing.assert_allclose(top.sigma_min, s[-1], rtol=1e-10)


# --------------------------------------------------------- planted optima


@pytest.mark.parametrize(("backend", "algorithm"), COMBOS)
def test_planted_bound_then_conflicting_task(backend, algorithm):
    # level 0: x0 <= 1; level 1: x0 = 2, x1 = 3  ->  x = (1, 3, 0), costs (0, 1)
    levels = [
        Level(C=[[1.0, 0.0, 0.0]], upper=[1.0], name="limit"),
        Level(A=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], b=[2.0, 3.0], name="task"),
    ]
    sol = solve(levels, backend=backend, algorithm=algorithm)
    np.testing.assert_allclose(sol.x, [1.0, 3.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(sol.costs, [0.0, 1.0], atol=1e-6)
    assert sol.levels[0].active.tolist() == [0]
    assert sol.levels[0].violated.size == 0
    assert sol.levels[0].satisfied and not sol.levels[1].satisfied


@pytest.mark.parametrize(("backend", "algorithm"), COMBOS)
def test_planted_box_and_tasks(backend, algorithm):
    # level 0: -1 <= x <= 1; level 1: x0 + x1 = 5 (best: x0 = x1 = 1, cost 9);
    # level 2: x2 = 0.5, x3 >= 0.25 (one-sided); min norm: others 0.
    n = 5
    levels = [
        Level(C=np.eye(n), lower=-np.ones(n), upper=np.ones(n), name="box"),
        Level(A=[[1.0, 1.0, 0.0, 0.0, 0.0]], b=[5.0], name="sum"),
        Level(A=[[0.0, 0.0, 1.0, 0.0, 0.0]], b=[0.5], C=[[0.0, 0.0, 0.0, 1.0, 0.0]],
              lower=[0.25], name="mixed"),
    ]
    sol = solve(levels, backend=backend, algorithm=algorithm)
    np.testing.assert_allclose(sol.x, [1.0, 1.0, 0.5, 0.25, 0.0], atol=1e-6)
    np.testing.assert_allclose(sol.costs, [0.0, 9.0, 0.0], atol=1e-6)
    assert sorted(sol.levels[0].active.tolist()) == [0, 1]
    assert sol.levels[2].active.tolist() == [0]


@pytest.mark.parametrize(("backend", "algorithm"), COMBOS)
def test_planted_violated_inequalities(backend, algorithm):
    # level 0 asks x0 >= 2 and x0 <= 1: best x0 = 1.5, both rows violated by 0.5;
    # level 1 asks x0 = 0 (cannot move) and x1 = 1.
    levels = [
        Level(C=[[1.0, 0.0], [1.0, 0.0]], lower=[2.0, -np.inf], upper=[np.inf, 1.0]),
        Level(A=np.eye(2), b=[0.0, 1.0]),
    ]
    sol = solve(levels, backend=backend, algorithm=algorithm)
    np.testing.assert_allclose(sol.x, [1.5, 1.0], atol=1e-6)
    np.testing.assert_allclose(sol.costs, [0.5, 2.25], atol=1e-6)
    top = sol.levels[0]
    assert top.violated.tolist() == [0, 1]
    np.testing.assert_allclose(top.violation_in, [-0.5, 0.5], atol=1e-6)
    assert not top.satisfied


@pytest.mark.parametrize(("backend", "algorithm"), COMBOS)
def test_planted_active_constraint_minimum_norm(backend, algorithm):
    # x0 + x1 >= 2 at the top; then x = 0 wanted: the closest point is (1, 1)
    levels = [Level(C=[[1.0, 1.0]], lower=[2.0]), Level(A=np.eye(2), b=[0.0, 0.0])]
    sol = solve(levels, backend=backend, algorithm=algorithm)
    np.testing.assert_allclose(sol.x, [1.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(sol.costs, [0.0, 2.0], atol=1e-6)
    assert sol.levels[0].active.tolist() == [0]


# ------------------------------------------- random problems, every backend

RANDOM_SHAPES = [
    [(2, 0, True, False), (0, 6, True, False), (4, 0, True, False), (3, 3, False, True)],
    [(0, 8, True, False), (3, 2, True, True), (6, 0, True, False)],
    [(3, 3, False, False), (2, 4, True, False), (2, 2, True, True), (5, 0, True, False)],
]


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("shapes", range(len(RANDOM_SHAPES)))
def test_random_against_independent_cascade(seed, shapes):
    rng = np.random.default_rng(1000 * shapes + seed)
    n = 10
    levels = random_levels(rng, n, RANDOM_SHAPES[shapes])
    ref = quadprog_cascade(levels, n)
    for backend, algorithm in SOLVERS:
        sol = solve(levels, backend=backend, algorithm=algorithm)
        assert np.all(np.abs(sol.costs - ref) <= cost_tol(ref)), (algorithm, sol.costs, ref)
        # the reported costs are the costs at x
        np.testing.assert_allclose(sol.costs, [level_cost(lv, sol.x) for lv in levels],
                                   rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize(("backend", "algorithm"), COMBOS)
def test_backends_and_algorithms_agree(backend, algorithm):
    ref_solver = HierarchicalSolver("proxsuite", "basis")
    solver = HierarchicalSolver(backend, algorithm)
    for seed in range(3):
        rng = np.random.default_rng(50 + seed)
        levels = random_levels(rng, 10, RANDOM_SHAPES[seed])
        ref = ref_solver.solve(levels)
        sol = solver.solve(levels)
        assert sol.backend == backend and sol.algorithm == algorithm
        assert np.all(np.abs(sol.costs - ref.costs) <= cost_tol(ref.costs)), (
            sol.costs, ref.costs)
        # the minimum-norm optimum is unique
        np.testing.assert_allclose(sol.x, ref.x, atol=1e-4)
        for a, b in zip(sol.levels, ref.levels):
            assert a.violated.tolist() == b.violated.tolist()


@pytest.mark.parametrize("backend", ["proxsuite", "native"])
@pytest.mark.parametrize("seed", range(4))
def test_lower_levels_never_raise_higher_costs(seed, backend):
    rng = np.random.default_rng(200 + seed)
    levels = random_levels(rng, 8, RANDOM_SHAPES[seed % 3])
    full = solve(levels, backend=backend).costs
    for k in range(1, len(levels)):
        truncated = solve(levels[:k], backend=backend).costs
        assert np.all(np.abs(full[:k] - truncated) <= cost_tol(truncated))


@pytest.mark.parametrize("backend", ["proxsuite", "native"])
def test_persistent_solver_matches_fresh_solves(backend):
    solver = HierarchicalSolver(backend, "basis")
    rng = np.random.default_rng(9)
    base = random_levels(rng, 12, RANDOM_SHAPES[0])
    for step in range(5):
        # same shapes, drifting data (a control loop)
        levels = [
            Level(A=None if lv.A is None else lv.A + 0.01 * step,
                  b=lv.b, C=lv.C, lower=lv.lower, upper=lv.upper, name=lv.name)
            for lv in base
        ]
        a = solver.solve(levels)
        b = solve(levels, backend=backend)
        np.testing.assert_allclose(a.costs, b.costs, rtol=1e-6, atol=1e-8)
        np.testing.assert_allclose(a.x, b.x, atol=1e-6)


@pytest.mark.parametrize("backend", ["proxsuite", "native"])
def test_solution_record(backend):
    levels = [Level(C=np.eye(3), lower=-np.ones(3), upper=np.ones(3), name="b"),
              Level(A=np.eye(3)[:2], b=[1.0, 2.0], name="a")]
    sol = solve(levels, backend=backend)
    assert isinstance(sol, Solution)
    assert sol.x.shape == (3,)
    assert all(isinstance(lv, LevelReport) for lv in sol.levels)
    assert [lv.name for lv in sol.levels] == ["b", "a"]
    assert set(sol.timings) >= {"total", "level_0", "level_1", "final"}
    assert sol.timings["total"] > 0.0
    np.testing.assert_allclose(sol.x, [1.0, 1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(sol.levels[1].residual_eq, [0.0, -1.0], atol=1e-9)
    np.testing.assert_allclose(sol.levels[0].violation_in, [0.0, 0.0, 0.0], atol=1e-8)
    assert sol.levels[0].active.tolist() == [0, 1]
    assert sol.levels[0].violated.size == 0
    np.testing.assert_allclose(sol.levels[1].cost, 1.0, atol=1e-9)
    assert sol.backend == backend and sol.algorithm == "basis"
    with pytest.raises(AttributeError):
        sol.levels[0].cost = 1.0  # frozen


def test_empty_and_unconstrained_levels():
    sol = solve([Level(A=np.zeros((0, 4)), b=np.zeros(0)), Level(C=np.ones((1, 4)))])
    np.testing.assert_allclose(sol.x, np.zeros(4))
    assert sol.levels[0].sigma_min == float("inf")
    sol = solve([Level(), Level(A=np.eye(2), b=[1.0, 1.0])])
    np.testing.assert_allclose(sol.x, [1.0, 1.0], atol=1e-12)


# ------------------------------------------------------------- bad input


BAD = [
    ([Level(A=np.ones((2, 3)), b=np.ones(3))], "level 0", "field b"),
    ([Level(A=np.ones((2, 3)), b=np.ones(2)), Level(A=np.ones((1, 4)), b=[1.0], name="hand")],
     "level 1 ('hand')", "field A"),
    ([Level(A=[[1.0, np.nan]], b=[0.0])], "level 0", "field A: contains NaN"),
    ([Level(A=[[1.0, np.inf]], b=[0.0])], "level 0", "field A: contains inf"),
    ([Level(A=[[1.0, 0.0]], b=[np.inf])], "level 0", "field b: contains inf"),
    ([Level(A=[[1.0, 0.0]], b=[np.nan])], "level 0", "field b: contains NaN"),
    ([Level(C=[[1.0, np.nan]], upper=[1.0])], "level 0", "field C: contains NaN"),
    ([Level(C=[[1.0, np.inf]], upper=[1.0])], "level 0", "field C: contains inf"),
    ([Level(C=[[1.0, 0.0]], lower=[np.nan])], "level 0", "field lower: contains NaN"),
    ([Level(C=[[1.0, 0.0]], upper=[np.nan])], "level 0", "field upper: contains NaN"),
    ([Level(C=[[1.0, 0.0]], lower=[2.0], upper=[1.0])], "level 0", "lower > upper at row 0"),
    ([Level(C=[[1.0, 0.0]], lower=[np.inf])], "level 0", "field lower: contains +inf"),
    ([Level(C=np.ones((2, 2)), lower=np.zeros(3))], "level 0", "field lower"),
    ([Level(b=[1.0])], "level 0", "field b: given without A"),
    ([Level(lower=[1.0])], "level 0", "field lower: given without C"),
    ([Level(A=np.ones((2, 2, 2)))], "level 0", "field A"),
    ([Level(A=[["a", "b"]])], "level 0", "field A"),
    (["not a level"], "level 0", "expected hqp.solver.Level"),
]


@pytest.mark.parametrize("backend", ["proxsuite", "native"])
@pytest.mark.parametrize(("levels", "where", "what"), BAD)
def test_malformed_levels_raise(levels, where, what, backend):
    with pytest.raises(hqp.InvalidLevel) as err:
        solve(levels, backend=backend)
    assert where in str(err.value)
    assert what in str(err.value)
    assert isinstance(err.value, hqp.HQPError) and isinstance(err.value, ValueError)


def test_other_bad_input_raises():
    ok = [Level(A=np.eye(2), b=np.zeros(2))]
    with pytest.raises(hqp.UnknownBackend, match="unknown backend 'nope'.*proxsuite"):
        solve(ok, backend="nope")
    with pytest.raises(hqp.UnknownName, match="algorithm"):
        solve(ok, algorithm="weighted")
    with pytest.raises(hqp.InvalidInput, match="final_metric"):
        solve(ok, final_metric=np.ones((3, 3)))
    with pytest.raises(hqp.InvalidInput, match="final_metric: not symmetric"):
        solve(ok, final_metric=[[1.0, 1.0], [0.0, 1.0]])
    with pytest.raises(hqp.InvalidInput, match="final_metric: not positive semidefinite"):
        solve(ok, final_metric=-np.eye(2))
    with pytest.raises(hqp.InvalidInput, match="final_target"):
        solve(ok, final_target=[np.nan, 0.0])
    with pytest.raises(hqp.InvalidInput, match="rank_tol"):
        solve(ok, rank_tol=0.0)
    with pytest.raises(hqp.InvalidLevel, match="cannot infer the number of variables"):
        solve([Level()])
    with pytest.raises(hqp.InvalidLevel, match="sequence"):
        solve(Level(A=np.eye(2), b=np.zeros(2)))


@pytest.mark.parametrize(("n", "levels"), [(40, 5), (80, 5)])
def test_benchmark_hierarchies_agree(n, levels):
    # regression: a row that the QP tolerance made look violated must not be pinned
    from hqp.bench.problems import random_hierarchy
    from hqp.bench.solver_suite import level_specs

    rng = np.random.default_rng(1000 * n + levels)
    hierarchy = random_hierarchy(rng, n, level_specs(n, levels))
    ref = solve(hierarchy, backend="quadprog", algorithm="cascade").costs
    for backend, algorithm in [("proxsuite", "basis"), ("proxsuite", "cascade"),
                               ("daqp", "basis")]:
        costs = solve(hierarchy, backend=backend, algorithm=algorithm).costs
        assert np.all(np.abs(costs - ref) <= cost_tol(ref)), (backend, algorithm, costs, ref)


def test_last_resort_fallback_is_logged_at_debug_level(caplog):
    # A backend that never returns a finite point: quadprog takes over (same minimiser). It is
    # part of normal operation on real stacks (the headline demo meets it), so no warning
    # (issue 19): debug records only, the first on each QP slot said so.
    import logging

    from hqp.solver.backends import QPBackend
    from hqp.solver.qp import solve_qp

    class Broken(QPBackend):
        name = "broken-for-test"

        def solve(self, slot, H, g, E, e, C, lo, up):
            return np.full(H.shape[0], np.nan), False

    H, g = np.eye(2), np.array([-1.0, -4.0])
    C, lo, up = np.eye(2), np.full(2, -1.0), np.full(2, 1.0)
    backend = Broken()
    with caplog.at_level(logging.DEBUG, logger="hqp.solver.qp"):
        for _ in range(5):
            v, _ok = solve_qp(backend, ("test", 0), H, g, None, None, C, lo, up)
            np.testing.assert_allclose(v, [1.0, 1.0], atol=1e-9)
        solve_qp(backend, ("test", 1), H, g, None, None, C, lo, up)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert sum("first time on this QP" in r.getMessage() for r in caplog.records) == 2
    assert sum("trying quadprog" in r.getMessage() for r in caplog.records) == 6
