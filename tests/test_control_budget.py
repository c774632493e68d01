"""The work budget of the native step's solve (``WholeBodyController(work_budget=...)``).

A pushed standing loop on g1 with a small budget: every step's solve stays within its budget
(deterministic work units, not seconds), the levels whose QP the budget cut are named in the
report, and the levels above the first cut level are exact: their costs at the step's x equal
the optima of an unbounded solve of the same levels by the Python reference algorithm.
"""

from __future__ import annotations

import numpy as np
import pytest

import hqp
from hqp.errors import InvalidInput
from hqp.solver import HierarchicalSolver

PRIMAL_WORK = 25  # a primal active-set iteration's units (LevelQP::kPrimalWork)


def _cost(level, x):
    cost = 0.0
    if level.A is not None:
        cost += float(np.sum((np.asarray(level.A) @ x - np.asarray(level.b)) ** 2))
    if level.C is not None:
        cx = np.asarray(level.C) @ x
        lo = np.full(cx.shape, -np.inf) if level.lower is None else level.lower
        up = np.full(cx.shape, np.inf) if level.upper is None else level.upper
        cost += float(np.sum(np.maximum(cx - up, 0.0) ** 2 + np.maximum(lo - cx, 0.0) ** 2))
    return cost


@pytest.mark.slow
def test_a_budgeted_step_keeps_the_levels_above_the_cut_exact():
    budget = 300
    robot = hqp.robots.load("g1")
    controller = hqp.standing_controller(robot, work_budget=budget)
    sim = hqp.Simulator(robot)
    reference = HierarchicalSolver("daqp")
    cut_steps = checked = 0
    for k in range(450):
        command = controller.step(sim.state(), k * sim.dt)
        mirror = controller._native_levels
        assert mirror is not None
        core = mirror.step_core
        assert core.work_used <= budget + PRIMAL_WORK, (k, core.work_used)
        cut = core.cut_levels()
        notes = [n for n in command.report.notes if "work budget" in n]
        assert bool(cut) == bool(notes), (k, cut, notes)
        if cut:
            cut_steps += 1
            if checked < 12:
                built, _solution = mirror.built()
                first = min(built.level_index.index(mirror.stack_level(c)) for c in cut)
                optimum = reference.solve(built.levels[:first])
                x = core.x
                for j in range(first):
                    best = optimum.levels[j].cost
                    assert _cost(built.levels[j], x) <= best + 1e-6 * max(1.0, best), (k, j)
                checked += 1
        force = np.array([150.0, 0.0, 0.0]) if 100 <= k < 200 else None
        sim.step(command.tau, force)
    assert cut_steps > 0 and checked > 0, "the budget never bound: the test proves nothing"


def test_the_budget_is_checked():
    robot = hqp.robots.load("paper-humanoid")
    for bad in (-1, 2.5):
        with pytest.raises(InvalidInput, match="work_budget"):
            hqp.standing_controller(robot, work_budget=bad)
    assert hqp.standing_controller(robot, work_budget=None).work_budget is None
    assert hqp.standing_controller(robot, work_budget=400).work_budget == 400
