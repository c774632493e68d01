"""The null-space torque law (seed 003 eq. 11-23) against the HQP solver and closed forms."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from hqp.errors import HQPError
from hqp.model import RobotModel
from hqp.nullspace import prioritized_torques
from hqp.robots.erd import erd_robots_dir

ERD = erd_robots_dir()

FIXED_ROBOTS = {
    "panda": "panda_description/urdf/panda.urdf",
    "g1-fixed": "g1_description/urdf/g1_29dof_rev_1_0.urdf",
}


@functools.lru_cache(maxsize=None)
def fixed_robot(name: str) -> RobotModel:
    """A fixed-base robot model (no free flyer) from example-robot-data."""
    return RobotModel.from_urdf(ERD / FIXED_ROBOTS[name], floating_base=False)


def random_state(model: RobotModel, rng: np.random.Generator) -> None:
    """Update ``model`` at a random configuration and a random velocity (Coriolis terms)."""
    q = model.random_configuration(rng)
    v = rng.normal(scale=1.0, size=model.nv)
    model.update(q, v)


def random_stack(
    model: RobotModel, rng: np.random.Generator, n_levels: int, free: int
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Random levels of rows mixing frame Jacobians (random frames, weights, targets).

    Each row is a random combination of the Jacobian rows of a few random frames; the stacked
    rows have full row rank, so every level is feasible, and leave ``free`` directions of
    redundancy.
    """
    budget = model.nv - free
    sizes = rng.multinomial(budget - n_levels, np.ones(n_levels) / n_levels) + 1
    frames = [f.name for f in model.model.frames if f.parentJoint > 0]
    levels = []
    for m in sizes:
        picked = rng.choice(frames, size=4, replace=False)
        Jf = np.vstack([model.frame_jacobian(str(f)) for f in picked])
        levels.append((rng.normal(size=(m, Jf.shape[0])) @ Jf, rng.normal(scale=2.0, size=m)))
    J_all = np.vstack([J for J, _ in levels])
    if np.linalg.matrix_rank(J_all) < budget:  # a rank-deficient draw: draw again
        return random_stack(model, rng, n_levels, free)
    return levels


def hqp_solve(levels, M, h, target_zero=False):
    """HQP of the same levels with ``final_metric = M``, ``final_target = -M^-1 h`` (or 0)."""
    from hqp.solver import Level, solve

    target = np.zeros(M.shape[0]) if target_zero else -np.linalg.solve(M, h)
    sol = solve([Level(A=J, b=a) for J, a in levels], final_metric=M, final_target=target)
    return sol


def test_law_reaches_every_level_and_obeys_dynamics():
    rng = np.random.default_rng(1)
    nv = 10
    A = rng.normal(size=(nv, nv))
    M = A @ A.T + nv * np.eye(nv)
    h = rng.normal(scale=10.0, size=nv)
    levels = [(rng.normal(size=(m, nv)), rng.normal(size=m)) for m in (3, 2, 3)]
    sol = prioritized_torques(M, h, levels, method="literal")
    for J, a in levels:
        np.testing.assert_allclose(J @ sol.qdd, a, atol=1e-10)
    np.testing.assert_allclose(M @ sol.qdd + h, sol.tau, atol=1e-10)
    # The whitened implementation computes the same law (torques, eigenvalues, forces).
    wh = prioritized_torques(M, h, levels)
    np.testing.assert_allclose(wh.tau, sol.tau, atol=1e-9)
    for lw, ll in zip(wh.levels, sol.levels):
        np.testing.assert_allclose(lw.eigenvalues, ll.eigenvalues, rtol=1e-9)
        np.testing.assert_allclose(lw.force, ll.force, rtol=1e-8, atol=1e-9)
    # eq. 18: the null space of level k has no acceleration effect on the levels above.
    Minv = np.linalg.inv(M)
    for k in range(1, len(levels) + 1):
        for J, _ in levels[:k]:
            np.testing.assert_allclose(J @ Minv @ sol.null_spaces[k].T, 0.0, atol=1e-10)
    assert all(lv.rank == lv.eigenvalues.size and lv.satisfied for lv in sol.levels)


def test_law_matches_closed_form_min_torque():
    """Fixed base: tau minimises tau^T M^-1 tau under all task accelerations (KKT solve)."""
    rng = np.random.default_rng(2)
    nv = 9
    A = rng.normal(size=(nv, nv))
    M = A @ A.T + np.eye(nv)
    h = rng.normal(scale=5.0, size=nv)
    levels = [(rng.normal(size=(m, nv)), rng.normal(size=m)) for m in (2, 2, 1)]
    sol = prioritized_torques(M, h, levels)
    J = np.vstack([J for J, _ in levels])
    a = np.concatenate([a for _, a in levels])
    kkt = np.block([[M, J.T], [J, np.zeros((len(a), len(a)))]])
    qdd = np.linalg.solve(kkt, np.concatenate([-h, a]))[:nv]
    np.testing.assert_allclose(sol.qdd, qdd, atol=1e-9)


def test_singular_level_is_inverted_on_its_range():
    """eq. 22-23: a level that repeats rows of a level above has zero eigenvalues."""
    rng = np.random.default_rng(3)
    nv = 7
    A = rng.normal(size=(nv, nv))
    M = A @ A.T + np.eye(nv)
    h = rng.normal(size=nv)
    J1 = rng.normal(size=(2, nv))
    J2 = np.vstack([J1[:1], rng.normal(size=(1, nv))])  # its first row conflicts with level 0
    a1, a2 = rng.normal(size=2), rng.normal(size=2)
    sol = prioritized_torques(M, h, [(J1, a1), (J2, a2)])
    lv = sol.levels[1]
    assert lv.rank == 1 and lv.singular
    assert lv.eigenvalues[-1] < 1e-12 * lv.eigenvalues[0]
    np.testing.assert_allclose(J1 @ sol.qdd, a1, atol=1e-10)  # the higher level wins
    np.testing.assert_allclose(J2[1] @ sol.qdd, a2[1], atol=1e-10)  # controllable direction
    assert not lv.satisfied


def test_bad_input_raises():
    M = np.eye(3)
    with pytest.raises(HQPError, match="level 0 J"):
        prioritized_torques(M, np.zeros(3), [(np.ones((1, 2)), np.zeros(1))])
    with pytest.raises(HQPError, match="positive definite"):
        prioritized_torques(-M, np.zeros(3), [])
    with pytest.raises(HQPError, match="NaN"):
        prioritized_torques(M, np.array([0.0, np.nan, 0.0]), [])
    with pytest.raises(HQPError, match="internal_forces"):
        prioritized_torques(M, np.zeros(3), [], internal_forces="squeeze")


@pytest.mark.parametrize("robot", sorted(FIXED_ROBOTS))
def test_fixed_base_law_equals_hqp_with_inertia_metric(robot):
    model = fixed_robot(robot)
    rng = np.random.default_rng(10)
    gaps = []
    for trial in range(6):
        random_state(model, rng)
        M, h = model.M, model.h
        levels = random_stack(model, rng, n_levels=int(rng.integers(2, 5)), free=3)
        law = prioritized_torques(M, h, levels)
        hqp = hqp_solve(levels, M, h)
        qdd = hqp.x
        tau = M @ qdd + h
        scale_tau = max(1.0, np.abs(law.tau).max())
        scale_qdd = max(1.0, np.abs(law.qdd).max())
        np.testing.assert_allclose(qdd, law.qdd, rtol=0, atol=1e-8 * scale_qdd)
        np.testing.assert_allclose(tau, law.tau, rtol=0, atol=1e-8 * scale_tau)
        for (J, a), lv in zip(levels, hqp.levels):
            assert lv.satisfied
            np.testing.assert_allclose(J @ law.qdd, a, atol=1e-8)
        # final_target = 0 minimises qdd^T M qdd instead: a different point of the same set.
        zero = hqp_solve(levels, M, h, target_zero=True)
        tau0 = M @ zero.x + h
        gaps.append(np.linalg.norm(tau0 - law.tau))
    # The difference is the M-projection of M^-1 h on the redundancy: far above solver noise.
    assert min(gaps) > 0.5, gaps  # [N m]; measured 0.72 (g1-fixed) and 6.7 (panda)


@pytest.mark.parametrize("robot", sorted(FIXED_ROBOTS))
def test_fixed_base_agrees_on_exactly_conflicting_levels(robot):
    """Beyond the contract: with well separated zero singular values, infeasible levels agree."""
    model = fixed_robot(robot)
    rng = np.random.default_rng(20)
    random_state(model, rng)
    M, h = model.M, model.h
    levels = random_stack(model, rng, n_levels=2, free=4)
    J0, a0 = levels[0]
    conflict = (np.vstack([J0[:1], levels[1][0][:1]]), rng.normal(size=2))
    levels = [levels[0], conflict, levels[1]]
    law = prioritized_torques(M, h, levels)
    hqp = hqp_solve(levels, M, h)
    assert not hqp.levels[1].satisfied and not law.levels[1].satisfied
    np.testing.assert_allclose(hqp.x, law.qdd, atol=1e-8 * max(1.0, np.abs(law.qdd).max()))
