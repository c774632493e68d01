"""A level's weak-direction threshold in the controller (issue 17): the stack's setting, the
levels it builds, the native step against the Python step, the feasibility report, and no
allocation in the native step with the filter on."""

from __future__ import annotations

import numpy as np
import pytest
from _sizing import sized

import hqp
from hqp import robots
from hqp.control.native import NativeStepMirror
from hqp.control.presets import standing_controller
from hqp.model import RobotState
from hqp.solver import HierarchicalSolver
from hqp.tasks.base import Category
from hqp.tasks.position import PositionTask

pytest.importorskip("hqp._core._ext")

THRESHOLD = 0.05
"""Above the g1 hand level's sigma_min while standing (about 0.014: the rows of a position
task projected on what the physics and the contacts leave free), so that it filters."""


def _reaching(name="g1", **kw):
    """A standing controller with the right hand sent 1.5 m ahead (out of reach)."""
    robot = robots.load(name)
    kw.setdefault("max_torque_rate", None)  # the stack's levels alone, as the oracles build
    ctrl = standing_controller(robot, backend="daqp", **kw)
    model = ctrl.model
    hand = PositionTask(model, robot.hands[1], name="hand", kp=30.0)
    model.update(robot.q_standing, np.zeros(model.nv))
    hand.set_goal(model.frame_placement(robot.hands[1]).translation + np.array([1.5, 0.0, 0.0]))
    ctrl.add_task(hand, Category.OPERATIONAL, t=-10.0)  # ramped in long before t = 0
    return robot, ctrl


def lv_cost(lv, x):
    cost = 0.0
    if lv.A is not None:
        cost += float(np.sum((lv.A @ x - lv.b) ** 2))
    if lv.C is not None:
        cx = lv.C @ x
        cost += float(np.sum(np.maximum(cx - lv.upper, 0) ** 2 + np.maximum(lv.lower - cx, 0) ** 2))
    return cost


def test_the_stack_sets_checks_and_builds_the_threshold():
    robot, ctrl = _reaching()
    stack = ctrl.stack
    assert stack.weak_thresholds == (0.0,) * stack.n_levels
    stack.set_weak_threshold(Category.OPERATIONAL, THRESHOLD)
    k = stack.level_of(Category.OPERATIONAL)
    assert stack.weak_threshold(k) == THRESHOLD
    assert stack.weak_threshold(stack.level_names[k]) == THRESHOLD
    ctrl.model.update(robot.q_standing, np.zeros(ctrl.model.nv))
    built = stack.build(ctrl.model, ctrl.layout, ctrl.dt, 0.0)
    for lv, index in zip(built.levels, built.level_index):
        assert lv.weak_threshold == (THRESHOLD if index == k else 0.0)
    for bad in (-1.0, float("nan"), float("inf"), "x", True):
        with pytest.raises(hqp.HQPError, match="set_weak_threshold"):
            stack.set_weak_threshold(Category.OPERATIONAL, bad)
    with pytest.raises(hqp.HQPError, match="unknown level"):
        stack.set_weak_threshold("no-such-level", 0.1)
    assert stack.weak_threshold(k) == THRESHOLD  # a refused value changes nothing


def test_the_native_step_filters_as_the_python_solver_on_the_same_levels():
    """The mirror's levels carry the threshold; its x equals the native solver's on the
    Python levels (1e-8 where no QP ran), its level costs those of cold solves by the Python
    basis algorithm (the filter does not depend on the warm start's point of the optimal
    sets above), with the same weak directions."""
    robot, ctrl = _reaching()
    ctrl.stack.set_weak_threshold(Category.OPERATIONAL, THRESHOLD)
    model, layout, stack = ctrl.model, ctrl.layout, ctrl.stack
    mirror = NativeStepMirror(robot, ctrl)
    oracle = HierarchicalSolver("native")
    python = HierarchicalSolver("daqp")
    rng = np.random.default_rng(7)
    filtered = 0
    for i in range(8):
        q = robot.q_standing.copy()
        q[7:] += rng.normal(scale=0.003, size=model.na)
        v = rng.normal(scale=0.01, size=model.nv)
        t = 0.001 * (i + 1)
        model.update(q, v)
        built = stack.build(model, layout, ctrl.dt, t)
        x, _tau = mirror.step(q, v, t)
        ref = oracle.solve(built.levels)
        py = python.solve(built.levels)
        weak = [int(w) for w in mirror.step_core.weak_directions()]
        assert weak == [lv.weak_directions for lv in ref.levels]
        assert weak == [lv.weak_directions for lv in py.levels]
        filtered += sum(weak) > 0
        if ref.qp_count == 0:
            np.testing.assert_allclose(x, ref.x, rtol=0, atol=1e-8 * max(1, np.abs(ref.x).max()))
        # the level costs of x: within the contract's 1e-6 of the Python solvers' (or their
        # own spread: the posture level has more rows than free directions here)
        refs = np.array([HierarchicalSolver(b).solve(built.levels).costs
                         for b in ("native", "daqp", "quadprog")])
        costs = np.array([lv_cost(lv, x) for lv in built.levels])
        best, spread = refs.min(axis=0), np.ptp(refs, axis=0)
        assert np.all(costs - best <= 1e-6 * np.maximum(1.0, best) + spread), (costs, refs)
    assert filtered == 8


@pytest.mark.parametrize("native", [True, False])
def test_the_report_gives_the_weak_directions_of_the_task_level(native):
    robot, ctrl = _reaching(native=native)
    state = RobotState(robot.q_standing.copy(), np.zeros(ctrl.model.nv))
    for i in range(3):
        cmd = ctrl.step(state, 0.001 * i)
    assert cmd.report["hand"].weak_directions == 0
    ctrl.stack.set_weak_threshold(Category.OPERATIONAL, THRESHOLD)
    for i in range(3, 6):
        cmd = ctrl.step(state, 0.001 * i)
    if native:
        assert ctrl.native is not None and ctrl.native.steps >= 3, ctrl.native.unsupported
    assert cmd.report["hand"].weak_directions >= 1
    assert cmd.report["com"].weak_directions == 0  # the balance level has no threshold
    assert np.isfinite(cmd.tau).all()


def test_a_native_step_with_the_filter_allocates_nothing():
    from conftest import checked_core
    _ext_checked = checked_core()

    robot, ctrl = _reaching()
    ctrl.stack.set_weak_threshold(Category.OPERATIONAL, THRESHOLD)
    mirror = NativeStepMirror(robot, ctrl, core=_ext_checked)
    core, q, v = sized(robot, ctrl, mirror, seed=11)
    for i in range(3, 15):
        mirror.push_goals(0.001 * i)
        core.step(q, v, ctrl.dt, forbid_malloc=True)  # raises on an allocation
        assert np.isfinite(core.tau).all()
        assert sum(core.weak_directions()) >= 1
