"""A torque-rate level in conflict, recorded: g1, the centre of mass sent 5 cm forward in
0.4 s (``tests/test_sim_conflict.py``), t = 0.549 s of the unperturbed run on an AMD EPYC.

Seven levels: physics, contact limits, the servo's torque-rate level (4 N m around the last
torques), joint limits (viability bounds on the accelerations), balance, operational,
posture. The contact limits let no torque change within the rate band: the rate level is in
conflict, and the least-squares optimum of its violations spreads them over every joint, the
right wrist roll's 0.8 N m share among them. On its 4e-4 kg m^2 that is 19556 rad/s^2: the
joint-limit level below cannot act, and in the closed loop the wrist passed its limit by
0.31 rad before the joint limits had a recovery deceleration (it now stops the wrist at its
limit in the steps after; the one-step acceleration stays). Every solver finds the same optimum (the
formulation, not a solver, does this).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hqp.solver import HierarchicalSolver, Level

DATA = Path(__file__).parent / "data" / "rate_conflict_g1.npz"
WRIST = 26
"""The right wrist roll's index among the actuated joints."""


def _levels() -> list[Level]:
    z = np.load(DATA)
    levels = []
    for i in range(7):
        rows = {k: z[f"{i}_{k}"] for k in ("A", "b", "C", "lower", "upper") if f"{i}_{k}" in z}
        levels.append(Level(name=str(z[f"{i}_name"]), **rows))
    return levels


def _joint_limit_violation(levels: list[Level], x: np.ndarray) -> float:
    jl = levels[3]
    v = jl.C @ x
    return float(np.max(np.maximum(v - jl.upper, jl.lower - v)))


def test_the_rate_level_in_conflict_spins_the_wrist_with_every_solver() -> None:
    levels = _levels()
    assert [lv.name for lv in levels][2:4] == ["torque_rate", "joint_limits"]
    ref = HierarchicalSolver("quadprog", "basis").solve(levels)
    assert ref.costs[2] > 1.0  # the rate level in conflict
    for backend in ("daqp", "native"):
        sol = HierarchicalSolver(backend, "basis").solve(levels)
        np.testing.assert_allclose(sol.costs, ref.costs, rtol=1e-6, atol=1e-6)
    qdd = ref.x[6:6 + 29]
    assert abs(qdd[WRIST]) > 1e4 and int(np.argmax(np.abs(qdd))) == WRIST
    # the joint-limit level above the rate level: its bounds nearly met (it is in conflict
    # too, by 74 rad/s^2), no acceleration above 110 rad/s^2, the torque steps large instead
    swapped = HierarchicalSolver("quadprog", "basis").solve(
        [levels[0], levels[1], levels[3], levels[2], *levels[4:]])
    assert np.abs(swapped.x[6:6 + 29]).max() < 110.0
    assert _joint_limit_violation(levels, swapped.x) < 75.0


@pytest.mark.xfail(strict=True, reason="issue 17, open: a level in conflict above the joint "
                   "limits (here the torque-rate level) pins every joint's torque at its "
                   "least-squares optimum, so the joint-limit level cannot brake a light joint "
                   "that optimum accelerates")
def test_a_rate_level_in_conflict_leaves_the_joints_within_reach_of_their_bounds() -> None:
    levels = _levels()
    sol = HierarchicalSolver("native", "basis").solve(levels)
    assert np.abs(sol.x[6:6 + 29]).max() < 1e3  # the bounds here are about +-50 rad/s^2


def test_the_rate_band_held_would_need_the_soles_to_tip() -> None:
    """Why the rate level yields at that step: holding every torque within 4 N m of the last
    (the rate level above the contact limits) leaves the contact wrenches far outside their
    cones: one sole's centre-of-pressure row by 6.0 N m and its yaw-torque rows by up to
    5.7 N m, where the 10 % sole margin of the contact limits would give 1.2 N m (0.1 x its
    0.085 m half length x its 139 N). Relaxing that margin would not hold the band: the
    conflict is the soles', not a solver's."""
    levels = _levels()
    held = HierarchicalSolver("quadprog", "basis").solve([levels[0], levels[2], levels[1]])
    assert held.costs[1] < 1e-9  # the band can be held...
    limits = levels[1]
    v = limits.C @ held.x
    excess = np.maximum(v - limits.upper, limits.lower - v)
    torque_rows = np.abs(limits.C[:, :35]).sum(axis=1) > 0  # tau rows first, then the soles
    assert np.all(excess[torque_rows] < 1e-9)
    sole = excess[29:46]  # the first sole's 17 wrench-cone rows
    # rows 5-8: centre of pressure, 9-16: yaw torque (ContactLimits' local_limits order)
    assert sole[5:9].max() > 5.0 and sole[9:17].max() > 5.0
