"""The active-set warm start (hqp.solver.active_set) against QPs and against cold solves."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import quadprog
from scipy.optimize import nnls as _nnls
from test_solver import RANDOM_SHAPES, cost_tol, level_cost, quadprog_cascade, random_levels

from hqp.bench.problems import random_hierarchy
from hqp.bench.solver_suite import drifting, level_specs
from hqp.solver import ALGORITHMS, HierarchicalSolver, Level, available_backends, supports
from hqp.solver.active_set import CarriedRows, Guess, LevelRows, guess_from_point, solve_guess

BACKENDS = available_backends()


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def _level_qp(A, b, C, lo, up, G, gl, gu):
    """Reference optimal cost of ``||A v - b||^2 + ||dist(C v, [lo, up])||^2`` s.t.
    ``gl <= G v <= gu``, by quadprog over ``(v, w)`` with a 1e-10 regularisation."""
    nv, mi = A.shape[1], C.shape[0]
    H = np.zeros((nv + mi, nv + mi))
    H[:nv, :nv] = A.T @ A + 1e-10 * np.eye(nv)
    H[nv:, nv:] = np.eye(mi)
    f = np.r_[A.T @ b, np.zeros(mi)]
    rows, rhs = [], []
    for i in range(mi):
        u = np.zeros(mi)
        u[i] = -1.0
        rows += [np.r_[C[i], u], np.r_[-C[i], -u]]
        rhs += [lo[i], -up[i]]
    for i in range(G.shape[0]):
        rows += [np.r_[G[i], np.zeros(mi)], np.r_[-G[i], np.zeros(mi)]]
        rhs += [gl[i], -gu[i]]
    v = quadprog.solve_qp(H, f, np.array(rows).T, np.array(rhs))[0][:nv]
    cv = C @ v
    d = np.maximum(cv - up, 0.0) + np.minimum(cv - lo, 0.0)
    r = A @ v - b
    return float(r @ r + d @ d)


def _random_level_problem(rng, nv=8, ma=3, mc=6, p=5):
    A = rng.standard_normal((ma, nv))
    b = 3.0 * rng.standard_normal(ma)
    C = rng.standard_normal((mc, nv))
    centre = rng.standard_normal(mc)
    lo = centre - rng.uniform(0.1, 0.5, mc)
    up = centre + rng.uniform(0.1, 0.5, mc)
    G = rng.standard_normal((p, nv))
    gc = rng.uniform(-0.2, 0.2, p)  # contains v = 0
    gl = gc - rng.uniform(0.3, 1.0, p)
    gu = gc + rng.uniform(0.3, 1.0, p)
    return A, b, C, lo, up, G, gl, gu


@pytest.mark.parametrize("seed", range(8))
def test_verified_guess_is_the_level_optimum(seed):
    """A point accepted by the KKT check has the QP's optimal cost and is feasible."""
    rng = np.random.default_rng(seed)
    A, b, C, lo, up, G, gl, gu = _random_level_problem(rng)
    ones_c, ones_g = np.ones(C.shape[0]), np.ones(G.shape[0])
    ref_cost = _level_qp(A, b, C, lo, up, G, gl, gu)
    # cold: from the least-squares point
    v0 = np.linalg.lstsq(A, b, rcond=None)[0]
    rows = LevelRows(A, b, C, lo, up, ones_c, ones_c)
    carried = CarriedRows(G, gl, gu, ones_g, ones_g)
    guess = guess_from_point(C @ v0, rows, G @ v0, carried, -1e-9)
    v, guess, _its = solve_guess(rows, carried, guess, 1e-9, 1.0, max_iter=20)
    assert v is not None, "the active-set updates did not settle on a small random level"
    cv = C @ v
    d = np.maximum(cv - up, 0.0) + np.minimum(cv - lo, 0.0)
    r = A @ v - b
    cost = float(r @ r + d @ d)
    assert abs(cost - ref_cost) <= 1e-7 * max(1.0, ref_cost), (cost, ref_cost)
    assert np.all(G @ v >= gl - 1e-9) and np.all(G @ v <= gu + 1e-9)
    # the verified guess, given again, is accepted at once with the same point
    v2, _g, its = solve_guess(rows, carried, guess, 1e-9, 1.0)
    assert its == 1
    np.testing.assert_allclose(v2, v, atol=1e-10)


def test_wrong_guess_is_rejected_or_corrected():
    """Holding a row whose multiplier has the wrong sign is not accepted as optimal."""
    # min (v - 2)^2 s.t. -1 <= v <= 1: optimum v = 1 (upper bound held).
    A, b = np.array([[1.0]]), np.array([2.0])
    C = np.zeros((0, 1))
    G, gl, gu = np.array([[1.0]]), np.array([-1.0]), np.array([1.0])
    e0, one = np.zeros(0), np.ones(1)
    wrong = Guess(np.zeros(0, dtype=np.int8), np.array([-1], dtype=np.int8))  # lower held
    rows = LevelRows(A, b, C, e0, e0, e0, e0)
    carried = CarriedRows(G, gl, gu, one, one)
    v, _g, _its = solve_guess(rows, carried, wrong, 1e-9, 1.0, max_iter=0)
    assert v is None
    v, g, _its = solve_guess(rows, carried, wrong, 1e-9, 1.0)
    np.testing.assert_allclose(v, [1.0], atol=1e-12)
    assert g.w.tolist() == [1]


def test_stale_guess_at_an_infinite_bound_is_harmless():
    A, b = np.array([[1.0, 0.0]]), np.array([1.0])
    C = np.array([[0.0, 1.0]])
    lo, up = np.array([-np.inf]), np.array([0.5])
    one = np.ones(1)
    stale = Guess(np.array([-1], dtype=np.int8), np.zeros(0, dtype=np.int8))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no NaN arithmetic (it warned before the fix)
        v, g, _its = solve_guess(LevelRows(A, b, C, lo, up, one, one), None, stale, 1e-9, 1.0)
    # the row held at its (now infinite) lower bound is released: the true minimiser
    np.testing.assert_allclose(v, [1.0, 0.0], atol=1e-15)
    assert not g.s.any()
    # the same for a carried row (held in w) whose upper bound became infinite
    G = np.array([[0.0, 1.0]])
    held = Guess(np.zeros(1, dtype=np.int8), np.array([1], dtype=np.int8))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        v, g, _its = solve_guess(
            LevelRows(A, b, C, lo, up, one, one),
            CarriedRows(G, np.array([-1.0]), np.array([np.inf]), one, one), held, 1e-9, 1.0)
    np.testing.assert_allclose(v, [1.0, 0.0], atol=1e-15)
    solver = HierarchicalSolver("proxsuite")
    levels = [Level(A=A, b=b), Level(C=C, lower=[-1.0], upper=[0.5]), Level(A=np.eye(2))]
    solver.solve(levels)  # row 0 of level 1 held at its lower bound -1
    levels[1] = Level(C=C, lower=lo, upper=[0.5])
    levels[2] = Level(A=np.eye(2), b=[0.0, -5.0])
    sol = solver.solve(levels)
    np.testing.assert_allclose(sol.x, [1.0, -5.0], atol=1e-9)


DRIFT_CASES = [(backend, algorithm) for backend in BACKENDS for algorithm in ALGORITHMS
               if backend != "osqp" and supports(backend, algorithm)]
"""OSQP's accuracy (1e-6 relative) is checked elsewhere; native runs the basis algorithm only."""


@pytest.mark.parametrize(("backend", "algorithm"), DRIFT_CASES)
def test_warm_start_matches_cold_solves_on_a_drifting_sequence(backend, algorithm):
    """A persistent warm-started solver gives the costs of fresh solves without it."""
    rng = np.random.default_rng(7)
    base = random_hierarchy(rng, 20, level_specs(20, 4))
    warm = HierarchicalSolver(backend, algorithm, warm_start=True)
    qps = {"warm": 0, "cold": 0}
    for levels in drifting(base, 12, rng):
        a = warm.solve(levels)
        b = HierarchicalSolver(backend, algorithm, warm_start=False).solve(levels)
        tol = cost_tol(b.costs)
        assert np.all(np.abs(a.costs - b.costs) <= tol), (a.costs, b.costs)
        np.testing.assert_allclose(a.x, b.x, atol=1e-5)
        qps["warm"] += a.qp_count
        qps["cold"] += b.qp_count
    # in a control loop the warm start settles most level QPs without the backend
    assert qps["warm"] <= 0.25 * qps["cold"], qps


@pytest.mark.parametrize("seed", range(3))
def test_warm_started_solver_against_independent_cascade(seed):
    rng = np.random.default_rng(300 + seed)
    n = 10
    solvers = {a: HierarchicalSolver("proxsuite", a) for a in ALGORITHMS}
    for step in range(3):
        levels = random_levels(rng, n, RANDOM_SHAPES[seed])
        shifted = [Level(A=lv.A, b=lv.b, C=lv.C,
                         lower=None if lv.lower is None else lv.lower + 0.05 * step,
                         upper=None if lv.upper is None else lv.upper + 0.05 * step)
                   for lv in levels]
        ref = quadprog_cascade(shifted, n)
        for algorithm, solver in solvers.items():
            sol = solver.solve(shifted)
            assert np.all(np.abs(sol.costs - ref) <= cost_tol(ref)), (algorithm, sol.costs, ref)
            np.testing.assert_allclose(sol.costs, [level_cost(lv, sol.x) for lv in shifted],
                                       rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_unvalidated_path_gives_the_validated_result(algorithm):
    """``validate=False`` (levels built by the stack) changes nothing on valid levels."""
    rng = np.random.default_rng(11)
    for seed in range(3):
        levels = random_levels(rng, 10, RANDOM_SHAPES[seed])
        levels.append(Level(name="empty"))
        # DAQP, a direct active-set method: the two paths give the same numbers up to BLAS's
        # last bit (memory alignment). ProxQP is iterative and carries such bits to its own
        # tolerance (3.8e-10 apart seen on a fresh CI machine): not a test of validation.
        a = HierarchicalSolver("daqp", algorithm).solve(levels)
        b = HierarchicalSolver("daqp", algorithm).solve(levels, validate=False)
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
        for ra, rb in zip(a.levels, b.levels):
            assert ra.name == rb.name
            np.testing.assert_allclose(ra.cost, rb.cost, rtol=1e-10, atol=1e-14)
            np.testing.assert_array_equal(ra.active, rb.active)
    # malformed input is still caught by default
    with pytest.raises(ValueError, match="level 0"):
        HierarchicalSolver("proxsuite", algorithm).solve([Level(A=np.eye(2), b=[np.nan, 0.0])])


# Thin feasible sets: carried rows active over a level's whole optimal set ------------------

def _thin_hierarchy():
    """x1 <= 0, x2 <= 1 and their sum x1 + x2 <= 1 (dependent), x3 <= 5 (never reached);
    level 1 asks x1 + x2 = 3 (in conflict: the optimal set is x1 = 0, x2 = 1 alone, the three
    rows there with positive multipliers); level 2 asks x1 - x2 = 5 and x3 = 1, of which only
    x3 is left to it."""
    L0 = Level(C=np.array([[1.0, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1]]),
               upper=np.array([0.0, 1, 1, 5]), name="limits")
    L1 = Level(A=np.array([[1.0, 1, 0]]), b=np.array([3.0]), name="conflict")
    L2 = Level(A=np.array([[1.0, -1, 0], [0, 0, 1]]), b=np.array([5.0, 1]), name="below")
    return [L0, L1, L2]


def test_held_multipliers_are_a_dual_solution_positive_only_where_the_level_pushes():
    """At the conflicting level's optimum the held rows' multipliers, by NNLS, reproduce the
    gradient (stationarity) with mu >= 0; the row held at its bound that the cost does not
    push against (multiplier 0, x2 <= 1 seen from a level that wants x2 = 1) gets none."""
    from hqp.solver.active_set import held_multipliers

    G = np.array([[1.0, 0], [0, 1], [1, 1]])
    carried = CarriedRows(G, np.full(3, -np.inf), np.array([0.0, 1, 1]), np.ones(3), np.ones(3))
    v = np.array([0.0, 1.0])
    pushing = LevelRows(np.array([[1.0, 1]]), np.array([3.0]), np.zeros((0, 2)), np.zeros(0),
                        np.zeros(0), np.zeros(0), np.zeros(0))
    mu = held_multipliers(pushing, carried, Guess(np.zeros(0, np.int8),
                                                  np.ones(3, np.int8)), v)
    grad = pushing.A.T @ (pushing.A @ v - pushing.b)
    assert np.all(mu >= 0)
    scale = 3.0  # mu is in units of the dual scale max(1, max|M| max(1, max|d|))
    np.testing.assert_allclose(G.T @ (scale * mu), -grad, atol=1e-12)
    assert mu.max() > 1e-6
    # a level that is met exactly at the vertex pushes against nothing
    met = LevelRows(np.array([[0.0, 1]]), np.array([1.0]), np.zeros((0, 2)), np.zeros(0),
                    np.zeros(0), np.zeros(0), np.zeros(0))
    mu0 = held_multipliers(met, carried, Guess(np.zeros(0, np.int8), np.ones(3, np.int8)), v)
    np.testing.assert_allclose(mu0, 0.0, atol=1e-15)
    # past the target (the cost pulls away from the bounds): no multipliers of the right
    # sign exist, nothing is claimed
    assert held_multipliers(pushing, carried, Guess(np.zeros(0, np.int8), np.ones(3, np.int8)),
                            np.array([3.0, 1.0])) is None


@pytest.mark.parametrize("backend", ["native", "daqp", "quadprog", "proxsuite"])
def test_a_level_below_a_thin_optimal_set_gets_what_is_left(backend):
    """The rows the conflicting level pushes against fix x1 and x2 for the levels below
    (equalities of the basis, not a set of no width): level 2 gets x3 = 1 exactly and its
    x1 - x2 = 5 stays unmet, whatever the backend; the same point as the cascade's."""
    if backend not in BACKENDS:
        pytest.skip(f"{backend} not installed")
    levels = _thin_hierarchy()
    sol = HierarchicalSolver(backend, "basis").solve(levels)
    np.testing.assert_allclose(sol.x, [0.0, 1.0, 1.0], atol=1e-8)
    np.testing.assert_allclose(sol.costs, [0.0, 4.0, 36.0], atol=1e-7)
    ref = HierarchicalSolver("daqp", "cascade").solve(levels)
    np.testing.assert_allclose(sol.x, ref.x, atol=1e-6)


def _solve_guess_both(impl, level, carried, w):
    """One level's active-set warm start by the Python reference or the native twin."""
    s0 = np.zeros(level.C.shape[0], np.int8)
    if impl == "python":
        v, guess, _its = solve_guess(level, carried, Guess(s0, w.astype(np.int8)), 1e-9, 1.0)
        return v, guess.w
    core = pytest.importorskip("hqp._core._ext")
    v, _s, w_last = core.active_set_solve(
        level.A, level.b, level.C, level.lo, level.up, level.los, level.ups, carried.G,
        carried.gl, carried.gu, carried.gls, carried.gus, s0.astype(np.int32),
        w.astype(np.int32), 1e-9, 1.0, 6)
    return v, w_last


@pytest.mark.parametrize("impl", ["python", "native"])
def test_a_dependent_held_row_inside_its_band_takes_no_multiplier(impl):
    """Held rows v1 <= 0 and -v1 <= 5 (dependent: the same direction), the level asking
    v = (-1, 0). The guess holding both gives v = (0, 0) (or (-5, 0)), where the row solved
    for has the wrong sign and the other lies inside its band. Letting the inactive row take
    the multiplier (NNLS on both, as an earlier version did) accepted that non-optimal point; the
    verified minimiser is (-1, 0) with no row held, in the reference and the native core."""
    level = LevelRows(np.eye(2), np.array([-1.0, 0.0]), np.zeros((0, 2)), np.zeros(0),
                      np.zeros(0), np.zeros(0), np.zeros(0))
    G = np.array([[1.0, 0.0], [-1.0, 0.0]])
    carried = CarriedRows(G, np.full(2, -np.inf), np.array([0.0, 5.0]), np.ones(2),
                          np.array([1.0, 5.0]))
    v, w = _solve_guess_both(impl, level, carried, np.ones(2))
    assert v is not None
    np.testing.assert_allclose(v, [-1.0, 0.0], atol=1e-12)
    assert not np.any(w)


@pytest.mark.parametrize("impl", ["python", "native"])
def test_dependent_held_rows_at_their_bound_share_the_multiplier(impl):
    """A degenerate vertex: v1 <= 0, v2 <= 0 and v1 + v2 <= 0 all held at (0, 0), the level
    asking v = (1, 2). The triangular solve gives the dependent row no multiplier; NNLS over
    the three rows at their bound finds the signs right, and the guess verifies at once with
    the cost's gradient matched by the multipliers (checked here independently)."""
    level = LevelRows(np.eye(2), np.array([1.0, 2.0]), np.zeros((0, 2)), np.zeros(0),
                      np.zeros(0), np.zeros(0), np.zeros(0))
    G = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    carried = CarriedRows(G, np.full(3, -np.inf), np.zeros(3), np.ones(3), np.ones(3))
    v, w = _solve_guess_both(impl, level, carried, np.ones(3))
    assert v is not None
    np.testing.assert_allclose(v, [0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(w, [1, 1, 1])
    # an independent check: the KKT point of min ||v - (1, 2)||^2 s.t. G v <= 0 is (0, 0)
    mu, res = _nnls(G.T, -(v - level.b))
    assert res < 1e-12 and np.all(mu >= 0)
