"""The native solver's primal active-set QP (``PrimalQP``, issue 17's thin feasible sets).

Where DAQP's first attempt fails on a level QP, the native hierarchy starts a primal
active-set method at the point it knows to be feasible (the levels above's solution, the
level's slacks at their clamp). Its claims, each checked against an independent computation:
every iterate stays feasible, and a solve that says it converged ends at a KKT point (the
multipliers of the rows at their bounds found by scipy's NNLS, the objective no higher than
ProxQP's at a point as feasible). The data: random least-squares QPs with rank-deficient
Hessians and degenerate starts, and level QPs recorded at paper-humanoid's steps after a
331 N push (``tests/data/thin_level_qps.npz``: the operational level, a rank-3 objective over
14-18 free directions under 106 carried rows, 4-19 of them active at the start), on which
DAQP, ProxQP, OSQP and quadprog failed or returned points 1e-6 outside the rows
(docs/design/control.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.optimize as so

from hqp._core import _ext

DATA = Path(__file__).parent / "data"
FEAS_TOL = 1e-9
KKT_TOL = 1e-7


def _objective(H: np.ndarray, g: np.ndarray, v: np.ndarray) -> float:
    return float(0.5 * v @ H @ v + g @ v)


def _violation(C: np.ndarray, lo: np.ndarray, up: np.ndarray, v: np.ndarray) -> float:
    """Largest violation of a row relative to its norm (0 inside)."""
    cv = C @ v
    scale = np.maximum(1.0, np.linalg.norm(C, axis=1))
    with np.errstate(invalid="ignore"):
        out = np.maximum(np.nan_to_num(cv - up, nan=0.0, neginf=0.0),
                         np.nan_to_num(lo - cv, nan=0.0, neginf=0.0))
    return float(max(0.0, np.max(out / scale))) if C.shape[0] else 0.0


def _kkt_residual(H, g, C, lo, up, v) -> float:
    """``min ||H v + g + C_u^T mu_u - C_l^T mu_l||`` over ``mu >= 0`` on the rows at a bound
    (scipy's NNLS), relative to ``|H v + g|``."""
    grad = H @ v + g
    cv = C @ v
    scale = np.maximum(1.0, np.linalg.norm(C, axis=1))
    at_up = np.isfinite(up) & (up - cv <= 1e-8 * scale)
    at_lo = np.isfinite(lo) & (cv - lo <= 1e-8 * scale)
    A = np.hstack([C[at_up].T, -C[at_lo].T])
    if A.shape[1] == 0:
        return float(np.linalg.norm(grad) / max(1.0, np.linalg.norm(grad)))
    _mu, res = so.nnls(A, -grad, maxiter=20 * A.shape[1])
    return float(res / max(1.0, np.linalg.norm(grad)))


def _random_qp(rng: np.random.Generator, n: int, m: int, rank: int, active: float):
    """A least-squares QP (``H = M^T M``, ``g = -M^T b``) whose rows hold at ``v0``, a share
    ``active`` of them at a bound there, some as thin bands (``lo = up``), some one-sided."""
    M = rng.standard_normal((rank, n))
    H = M.T @ M
    g = -M.T @ (10.0 * rng.standard_normal(rank))
    C = rng.standard_normal((m, n))
    C[: m // 4] *= rng.uniform(0.02, 1.0, (m // 4, 1))  # rows of different norms
    v0 = rng.standard_normal(n)
    cv = C @ v0
    below = np.where(rng.random(m) < active, 0.0, rng.uniform(0.0, 2.0, m))
    above = np.where(rng.random(m) < active, 0.0, rng.uniform(0.0, 2.0, m))
    lo, up = cv - below, cv + above
    thin = rng.random(m) < 0.1
    lo[thin] = up[thin] = cv[thin]
    lo[rng.random(m) < 0.2] = -np.inf
    up[rng.random(m) < 0.2] = np.inf
    return H, g, C, lo, up, v0


def _check(H, g, C, lo, up, v0, label: str) -> np.ndarray:
    v, ok, iterations = _ext.primal_qp(H, g, C, lo, up, v0, 20 * (len(g) + len(lo)))
    assert ok, f"{label}: no convergence after {iterations} working-set changes"
    assert _violation(C, lo, up, v) <= FEAS_TOL, label
    assert _kkt_residual(H, g, C, lo, up, v) <= KKT_TOL, label
    assert _objective(H, g, v) <= _objective(H, g, v0) + 1e-9 * max(1.0, abs(_objective(H, g, v0)))
    return v


@pytest.mark.parametrize("seed", range(12))
def test_random_degenerate_least_squares_end_at_kkt_points(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 30))
    m = int(rng.integers(n, 4 * n))
    rank = int(rng.integers(1, n))
    H, g, C, lo, up, v0 = _random_qp(rng, n, m, rank, active=0.3)
    v = _check(H, g, C, lo, up, v0, f"seed {seed}")
    # against ProxQP (independent; at a point it reports within the same feasibility)
    import proxsuite

    qp = proxsuite.proxqp.dense.QP(n, 0, m)
    qp.settings.eps_abs = 1e-10
    qp.settings.max_iter = 100000
    qp.init(H, g, None, None, C, np.maximum(lo, -1e20), np.minimum(up, 1e20))
    qp.solve()
    x = qp.results.x
    if (qp.results.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
            and _violation(C, lo, up, x) <= FEAS_TOL):
        fx, fv = _objective(H, g, x), _objective(H, g, v)
        assert fv <= fx + 1e-7 * max(1.0, abs(fx)), (fv, fx)


def test_a_strictly_convex_qp_equals_the_closed_form_without_rows():
    """No row binding: the unconstrained minimiser ``-H^-1 g``."""
    rng = np.random.default_rng(7)
    B = rng.standard_normal((8, 5))
    H = B.T @ B + np.eye(5)
    g = rng.standard_normal(5)
    C = rng.standard_normal((3, 5))
    lo, up = np.full(3, -1e6), np.full(3, 1e6)
    v, ok, _ = _ext.primal_qp(H, g, C, lo, up, np.zeros(5), 100)
    assert ok
    np.testing.assert_allclose(v, -np.linalg.solve(H, g), rtol=1e-10, atol=1e-10)


def _thin_qps():
    z = np.load(DATA / "thin_level_qps.npz")
    names = sorted({k.split("_")[0] for k in z.files})
    return [(name, *(z[f"{name}_{k}"] for k in ("H", "g", "C", "lo", "up"))) for name in names]


@pytest.mark.parametrize("qp", _thin_qps(), ids=lambda q: q[0])
def test_the_recorded_thin_level_qps_are_solved_exactly(qp):
    name, H, g, C, lo, up = qp
    # the start the hierarchy gives: the levels above's solution (these levels have no
    # slacks), feasible to rounding
    v0 = np.zeros(len(g))
    assert _violation(C, lo, up, v0) <= 1e-12
    v = _check(H, g, C, lo, up, v0, name)
    assert np.linalg.norm(v) > 0.0 or np.linalg.norm(H @ v0 + g) == 0.0


def test_the_primal_qp_allocates_nothing():
    """Eigen's run-time check (the _ext_checked build) around a solve that changes its
    working set many times."""
    from conftest import checked_core
    _ext_checked = checked_core()

    assert _ext_checked.malloc_checked
    name, H, g, C, lo, up = _thin_qps()[0]
    v, ok, iterations = _ext_checked.primal_qp(H, g, C, lo, up, np.zeros(len(g)), 1000,
                                               forbid_malloc=True)
    assert ok and iterations > 5


def test_a_pushed_step_that_failed_the_native_solve_now_solves():
    """paper-humanoid 0.238 s after a 331 N push (0.1 s at 0.3 s): without the primal method the
    native solve ends with "level 5: the native QP (DAQP) returned a non-finite solution" (and
    the step goes to the Python step). The primal method now solves the level DAQP could not
    (in the absorbing pass); the levels' costs are the Python basis algorithm's on its exact
    backends to the contract, or within their own spread below the balance level: on this
    thin set quadprog and DAQP end 17 % apart on the operational level (ProxQP returns no
    point at all)."""
    from hqp.solver import HierarchicalSolver, Level

    z = np.load(DATA / "push_step_paper_humanoid.npz")
    levels = []
    for i in range(7):
        rows = {k: z[f"{i}_{k}"] for k in ("A", "b", "C", "lower", "upper") if f"{i}_{k}" in z}
        levels.append(Level(name=str(z[f"{i}_name"]), **rows))
    _ext.reset_qp_stats()
    sol = HierarchicalSolver("native", "basis").solve(levels)
    calls, ok, *_ = _ext.qp_stats()
    assert calls[31] > 0 and ok[31] > 0  # the primal method ran and converged
    refs = np.array([HierarchicalSolver(b, "basis").solve(levels).costs
                     for b in ("quadprog", "daqp")])
    costs = np.array(sol.costs)
    np.testing.assert_allclose(costs[:5], refs[0, :5], rtol=1e-6, atol=1e-6)
    low, high = refs.min(axis=0), refs.max(axis=0)
    assert np.all(costs[5:] >= low[5:] * (1 - 1e-6)) and np.all(costs[5:] <= high[5:] * (1 + 1e-6))


def test_a_degenerate_vertex_that_cycled_under_the_most_negative_multiplier_rule():
    """A random QP (39 variables, 153 rows) whose degenerate optimum made the most-negative
    multiplier rule drop and re-add the same rows for 3840 changes (measured); after n
    changes without progress the drop follows Bland's rule, and it converges."""
    rng = np.random.default_rng(1234)
    n = int(rng.integers(4, 40))
    m = int(rng.integers(n, 4 * n))
    rank = int(rng.integers(1, n))
    H, g, C, lo, up, v0 = _random_qp(rng, n, m, rank, active=float(rng.uniform(0, 0.8)))
    assert (n, m, rank) == (39, 153, 38)
    _check(H, g, C, lo, up, v0, "seed 1234")
