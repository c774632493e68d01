"""A level's ``weak_threshold``: the filter of its weak directions (issue 17).

Checked against an independent closed form (an SVD of the projected level), for exactness
where every singular value reaches the threshold, continuity through it, boundedness at a
singularity, the same result on every algorithm and backend (the C++ core against the
Python basis algorithm), the report, and bad input.
"""

from __future__ import annotations

import numpy as np
import pytest

import hqp
from hqp.solver import HierarchicalSolver, Level, solve

BACKENDS = ("proxsuite", "daqp", "quadprog", "native")


def _level_with_singular_values(rng, s, n):
    """A ``(len(s), n)`` matrix ``U diag(s) V^T`` with random orthonormal ``U``, ``V``."""
    m = len(s)
    U, _ = np.linalg.qr(rng.standard_normal((m, m)))
    V, _ = np.linalg.qr(rng.standard_normal((n, m)))
    return U @ np.diag(s) @ V.T, U, V


def _filtered_step(U, s, V, b, thr):
    """The closed form: ``sum_i f(s_i) / s_i * v_i u_i^T b`` with ``f = min(1, (s/thr)^2)``."""
    f = np.minimum(1.0, (s / thr) ** 2) if thr > 0 else np.ones_like(s)
    return V @ (f / s * (U.T @ b))


@pytest.mark.parametrize("backend", BACKENDS)
def test_one_level_against_the_closed_form(backend):
    rng = np.random.default_rng(1)
    n = 7
    s = np.array([3.0, 0.8, 0.05, 2e-4])
    A, U, V = _level_with_singular_values(rng, s, n)
    b = rng.standard_normal(4)
    for thr in (1e-5, 0.01, 0.1, 1.0, 5.0):
        sol = solve([Level(A=A, b=b, weak_threshold=thr)], backend=backend)
        assert np.allclose(sol.x, _filtered_step(U, s, V, b, thr), rtol=0, atol=1e-9)
        assert sol.levels[0].weak_directions == int(np.count_nonzero(s < thr))
        # the cost is the level's own, against b
        r = A @ sol.x - b
        assert sol.levels[0].cost == pytest.approx(r @ r, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_threshold_below_every_singular_value_changes_nothing(backend):
    """The solver contract's exactness clause: well-conditioned levels keep their exact
    result, bit for bit (the filter touches no direction at or above its threshold)."""
    rng = np.random.default_rng(2)
    n = 9
    A0 = rng.standard_normal((3, n))
    A1 = rng.standard_normal((4, n))
    C1 = rng.standard_normal((5, n))
    b0, b1 = rng.standard_normal(3), rng.standard_normal(4)

    def levels(thr):
        return [Level(A=A0, b=b0, weak_threshold=thr),
                Level(A=A1, b=b1, C=C1, lower=-0.3 * np.ones(5), upper=0.3 * np.ones(5),
                      weak_threshold=thr),
                Level(A=np.eye(n)[:3], b=np.ones(3))]

    ref = HierarchicalSolver(backend=backend).solve(levels(0.0))
    smallest = min(lv.sigma_min for lv in ref.levels[:2])
    out = HierarchicalSolver(backend=backend).solve(levels(0.5 * smallest))
    assert np.array_equal(out.x, ref.x)
    assert [lv.weak_directions for lv in out.levels] == [0, 0, 0]


def test_the_step_is_continuous_through_the_threshold_and_vanishes_at_a_singularity():
    rng = np.random.default_rng(3)
    n = 6
    thr = 0.1
    U, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    V, _ = np.linalg.qr(rng.standard_normal((n, 3)))
    b = rng.standard_normal(3)
    sigmas = np.concatenate([np.geomspace(1e-7, thr, 40), np.linspace(thr, 3 * thr, 40)[1:]])
    steps = []
    for s_min in sigmas:
        s = np.array([2.0, 1.0, s_min])
        sol = solve([Level(A=U @ np.diag(s) @ V.T, b=b, weak_threshold=thr)], backend="native")
        steps.append(V[:, 2] @ sol.x)  # the step along the weak direction
    steps = np.array(steps)
    c = U[:, 2] @ b
    # bounded by |u^T b| / thr (its value at the threshold), monotone in s_min on both sides
    assert np.all(np.abs(steps) <= abs(c) / thr * (1 + 1e-9))
    assert np.abs(steps[0]) < 1e-5 * abs(c) / thr
    mid = np.argmin(np.abs(sigmas - thr))
    assert steps[mid] == pytest.approx(c / thr, rel=1e-9)
    # continuity: neighbouring samples differ by at most the largest slope times the spacing
    gaps = np.abs(np.diff(steps))
    assert gaps.max() <= abs(c) / thr ** 2 * np.diff(sigmas).max() * (1 + 1e-6)
    # without the filter the same step grows as 1/s_min
    sol = solve([Level(A=U @ np.diag([2.0, 1.0, 1e-7]) @ V.T, b=b)], backend="native")
    assert abs(V[:, 2] @ sol.x) == pytest.approx(abs(c) / 1e-7, rel=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_weak_directions_are_those_left_by_the_levels_above(backend):
    """A level well conditioned alone but nearly singular on the optimal set above: the
    threshold sees its projection ``A Z`` (the hierarchy paper's ``J N``), not ``A``."""
    eps, thr = 1e-3, 0.01
    A0 = np.array([[1.0, 0.0, 0.0, 0.0]])  # level 0 fixes x0 = 0
    A1 = np.array([[1.0, eps, 0.0, 0.0]])  # alone: singular value ~1; on x0 = 0: eps
    b1 = np.array([1.0])
    alone = solve([Level(A=A1, b=b1, weak_threshold=thr)], backend=backend)
    assert alone.levels[0].weak_directions == 0
    assert alone.levels[0].satisfied
    sol = solve([Level(A=A0, b=[0.0]), Level(A=A1, b=b1, weak_threshold=thr)],
                backend=backend)
    assert sol.levels[1].weak_directions == 1
    assert sol.levels[1].sigma_min == pytest.approx(eps, rel=1e-9)
    # the closed form on the free set: the target scaled by (eps / thr)^2
    assert sol.x[1] == pytest.approx((eps / thr) ** 2 / eps, rel=1e-8)
    assert not sol.levels[1].satisfied  # the filtered level reports its real residual
    assert sol.levels[1].cost == pytest.approx((1 - (eps / thr) ** 2) ** 2, rel=1e-8)
    plain = solve([Level(A=A0, b=[0.0]), Level(A=A1, b=b1)], backend=backend)
    assert plain.x[1] == pytest.approx(1 / eps, rel=1e-8)


def _random_hierarchy(rng, n, thr):
    levels = []
    for k in range(3):
        m, mi = 3 + k, 4
        s = np.geomspace(1.0, 10.0 ** -(k + 2), m)
        A, _, _ = _level_with_singular_values(rng, s, n)
        C = rng.standard_normal((mi, n))
        levels.append(Level(A=A, b=rng.standard_normal(m), C=C, lower=-0.2 * np.ones(mi),
                            upper=0.2 * np.ones(mi), name=f"l{k}", weak_threshold=thr))
    return levels


@pytest.mark.parametrize("seed", range(8))
def test_the_native_core_matches_the_python_basis_algorithm_and_the_cascade(seed):
    rng = np.random.default_rng(10 + seed)
    n = 12
    levels = _random_hierarchy(rng, n, 0.05)
    native = solve(levels, backend="native")
    assert sum(lv.weak_directions for lv in native.levels) > 0
    # the exact active-set backends of the Python basis algorithm agree to rounding;
    # ProxQP's tolerance (1e-7 relative on level 0 here) is amplified by the levels below,
    # so it is held to the contract on the first level only
    for backend in ("daqp", "quadprog", "proxsuite"):
        ref = solve(levels, backend=backend)
        assert [lv.weak_directions for lv in ref.levels] == [
            lv.weak_directions for lv in native.levels]
        if backend == "proxsuite":
            assert abs(ref.costs[0] - native.costs[0]) <= 1e-6 * max(1.0, native.costs[0])
        else:
            assert np.allclose(native.costs, ref.costs, rtol=1e-8, atol=1e-10), backend
            assert np.allclose(native.x, ref.x, rtol=0, atol=1e-7 * max(1, np.abs(ref.x).max()))
    cascade = solve(levels, backend="daqp", algorithm="cascade")
    assert [lv.weak_directions for lv in cascade.levels] == [
        lv.weak_directions for lv in native.levels]
    assert np.allclose(native.costs, cascade.costs, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("backend", ("proxsuite", "native"))
@pytest.mark.parametrize("value", (-1e-3, float("nan"), float("inf"), "big", True, None))
def test_a_bad_threshold_is_refused_naming_the_level_and_the_field(backend, value):
    A = np.eye(3)
    with pytest.raises(hqp.HQPError, match=r"level 1 \('arm'\), field weak_threshold"):
        solve([Level(A=A, b=np.zeros(3)), Level(A=A, b=np.ones(3), name="arm",
                                                 weak_threshold=value)], backend=backend)


def test_a_numpy_or_integer_threshold_is_accepted():
    A = np.diag([1.0, 1e-3])
    b = np.ones(2)
    ref = solve([Level(A=A, b=b, weak_threshold=0.1)], backend="native")
    for value in (np.float64(0.1), np.float32(0.1)):
        sol = solve([Level(A=A, b=b, weak_threshold=value)], backend="native")
        assert np.allclose(sol.x, ref.x, rtol=1e-6)
    sol = solve([Level(A=A, b=b, weak_threshold=1)], backend="native")
    assert sol.x[1] == pytest.approx(1e-3, rel=1e-9)  # (1e-3 / 1)^2 / 1e-3
