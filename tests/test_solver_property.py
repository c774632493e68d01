"""Property test: well-formed random hierarchies never raise and never return NaN or inf."""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hqp.solver import HierarchicalSolver, Level

SOLVERS = {alg: HierarchicalSolver("proxsuite", alg) for alg in ("basis", "cascade")}
SOLVERS["native"] = HierarchicalSolver("native")


@st.composite
def hierarchies(draw):
    n = draw(st.integers(1, 7))
    n_levels = draw(st.integers(1, 4))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    levels = []
    for _ in range(n_levels):
        kind = draw(st.sampled_from(["eq", "in", "both", "empty", "zero", "dup"]))
        me = draw(st.integers(0, 4))
        mi = draw(st.integers(0, 4))
        scale = draw(st.sampled_from([1e-2, 1.0, 1e2]))
        A = b = C = lo = up = None
        if kind in ("eq", "both", "zero", "dup") and me:
            A = scale * rng.standard_normal((me, n))
            if kind == "zero":
                A[0] = 0.0
            if kind == "dup" and me > 1:
                A[1] = A[0]
            b = scale * rng.standard_normal(me)
        if kind in ("in", "both", "dup") and mi:
            C = scale * rng.standard_normal((mi, n))
            centre = scale * rng.standard_normal(mi)
            half = scale * rng.uniform(0.0, 2.0, mi)
            lo = centre - half
            up = centre + half
            side = rng.integers(0, 3, mi)
            lo[side == 1] = -np.inf
            up[side == 2] = np.inf
        levels.append(Level(A=A, b=b, C=C, lower=lo, upper=up))
    if all(lv.A is None and lv.C is None for lv in levels):
        levels.append(Level(A=np.eye(n), b=np.ones(n)))
    return levels


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(levels=hierarchies(), algorithm=st.sampled_from(["basis", "cascade", "native"]))
def test_random_hierarchies_never_raise_nor_return_nan(levels, algorithm):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = SOLVERS[algorithm].solve(levels)
    assert np.all(np.isfinite(sol.x))
    for rep in sol.levels:
        assert np.isfinite(rep.cost) and rep.cost >= 0.0
        assert rep.sigma_min >= 0.0


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(levels=hierarchies())
def test_native_core_matches_the_python_basis_algorithm(levels):
    """The C++ core against its oracle: same level costs (contract tolerance), same x."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = HierarchicalSolver("daqp").solve(levels)
        sol = HierarchicalSolver("native").solve(levels)
    tol = 1e-6 * np.maximum(1.0, ref.costs)
    assert np.all(np.abs(sol.costs - ref.costs) <= tol), (sol.costs, ref.costs)
    for a, b in zip(sol.levels, ref.levels):
        assert a.satisfied == b.satisfied or abs(a.cost - b.cost) <= 1e-12
