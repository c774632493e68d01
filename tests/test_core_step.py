"""The native control step against the Python step (the oracle) on the standing stacks.

For each robot's standing controller, at states around standing (and at recorded states):
the native step's levels equal ``Stack.build``'s to 1e-10, its ``x`` equals the native
solver's on the Python levels to 1e-8, its torques ``joint_torques`` of that ``x``.
"""

from __future__ import annotations

import numpy as np
import pytest

from hqp import robots
from hqp.control.native import NativeStepMirror
from hqp.control.presets import standing_controller
from hqp.model import RobotState
from hqp.solver import HierarchicalSolver
from hqp.tasks.dynamics import joint_torques

pytest.importorskip("hqp._core._ext")


def lv_cost(lv, x):
    cost = 0.0
    if lv.A is not None:
        cost += float(np.sum((lv.A @ x - lv.b) ** 2))
    if lv.C is not None:
        cx = lv.C @ x
        cost += float(np.sum(np.maximum(cx - lv.upper, 0) ** 2 + np.maximum(lv.lower - cx, 0) ** 2))
    return cost


def _close(a, b, what, tol=1e-10):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, what
    f = np.isfinite(b)
    np.testing.assert_array_equal(np.isfinite(a), f, err_msg=what)
    if f.any():
        np.testing.assert_allclose(a[f], b[f], rtol=0, atol=tol * max(1.0, np.abs(b[f]).max()),
                                   err_msg=what)


def _standing(name):
    robot = robots.load(name)
    ctrl = standing_controller(robot, backend="daqp")
    ctrl.step(RobotState(robot.q_standing.copy(), np.zeros(ctrl.model.nv)), 0.0)
    return robot, ctrl


def _check_levels(mirror, built, n):
    levels = mirror.step_core.levels()
    assert [k for k, *_ in levels] == list(built.level_index)
    for (_k, A, b, C, lo, up), lv in zip(levels, built.levels):
        _close(A, np.zeros((0, n)) if lv.A is None else lv.A, f"{lv.name} A")
        _close(b, np.zeros(0) if lv.b is None else lv.b, f"{lv.name} b")
        _close(C, np.zeros((0, n)) if lv.C is None else lv.C, f"{lv.name} C")
        if lv.C is not None:
            _close(lo, lv.lower, f"{lv.name} lower")
            _close(up, lv.upper, f"{lv.name} upper")


@pytest.mark.parametrize("name", robots.NAMES)
def test_native_step_equals_the_python_step_while_standing(name):
    """A calm sequence (a control loop near rest: after the first steps the warm-started
    active sets settle every level, no QP point): x to 1e-8 of the native solver's on the
    Python levels, torques those of x."""
    robot, ctrl = _standing(name)
    model, layout, stack = ctrl.model, ctrl.layout, ctrl.stack
    mirror = NativeStepMirror(robot, ctrl)
    oracle = HierarchicalSolver("native")
    rng = np.random.default_rng(4)
    q1 = robot.q_standing.copy()
    q1[7:] += rng.normal(scale=0.003, size=model.na)
    v1 = rng.normal(scale=0.01, size=model.nv)
    exact = 0
    for i in range(10):
        s = min(1.0, i / 5.0)  # drift from standing to (q1, v1), then hold
        q = (1 - s) * robot.q_standing + s * q1
        q[3:7] /= np.linalg.norm(q[3:7])
        v = s * v1
        t = 0.001 * (i + 1)
        model.update(q, v)
        built = stack.build(model, layout, ctrl.dt, t)
        x, tau = mirror.step(q, v, t)
        _check_levels(mirror, built, layout.n)
        ref = oracle.solve(built.levels)
        assert mirror.step_core.qp_count == ref.qp_count
        if ref.qp_count == 0:
            exact += 1
            _close(x, ref.x, "x", 1e-8)
        _close(tau, joint_torques(model, layout, x), "tau", 1e-10)
    assert exact >= 3


@pytest.mark.parametrize("name", robots.NAMES)
def test_native_step_meets_the_contract_at_agitated_states(name):
    """Fast joints (DAQP points on several levels): the levels to 1e-10, the level costs of
    x within the contract's 1e-6 of the Python solvers' (or within their own spread)."""
    robot, ctrl = _standing(name)
    model, layout, stack = ctrl.model, ctrl.layout, ctrl.stack
    mirror = NativeStepMirror(robot, ctrl)
    rng = np.random.default_rng(5)
    for i in range(6):
        q = robot.q_standing.copy()
        q[7:] += rng.normal(scale=0.02, size=model.na)
        v = rng.normal(scale=0.2, size=model.nv)
        t = 0.001 * (i + 1)
        model.update(q, v)
        built = stack.build(model, layout, ctrl.dt, t)
        x, tau = mirror.step(q, v, t)
        _check_levels(mirror, built, layout.n)
        refs = np.array([HierarchicalSolver(b).solve(built.levels).costs
                         for b in ("native", "daqp", "quadprog")])
        costs = np.array([lv_cost(lv, x) for lv in built.levels])
        best, spread = refs.min(axis=0), np.ptp(refs, axis=0)
        assert np.all(costs - best <= 1e-6 * np.maximum(1.0, best) + spread), (costs, refs)
        _close(tau, joint_torques(model, layout, x), "tau", 1e-10)


def test_mirror_refuses_what_it_cannot_run():
    """A state-dependent joint-limit bound (qdd_max=None) and a task without a kernel."""
    from hqp.control.native import NotSupported
    from hqp.tasks.effort import EffortTask
    from hqp.tasks.joint_limits import JointLimits

    robot, ctrl = _standing("g1")
    ctrl.stack.add(JointLimits(name="jl_state", qdd_max=None), "joint_limits")
    with pytest.raises(NotSupported, match="qdd_max=None"):
        NativeStepMirror(robot, ctrl)
    robot, ctrl = _standing("g1")
    ctrl.stack.add(EffortTask(ctrl.model), "posture")
    with pytest.raises(NotSupported, match="no native kernel"):
        NativeStepMirror(robot, ctrl)


def test_controller_suite_row_of_the_native_core_is_the_native_step():
    """The contract's whole-step row ``hqp/basis/native`` runs the native step."""
    from hqp.bench import suite_controller as sc

    assert sc.NATIVE_STEP == "hqp/basis/native"
    robot = robots.load("g1")
    sts = sc.states("g1", count=2)
    stepper = sc._Stepper(sc.NATIVE_STEP, robot, sts)
    cmd = stepper()
    stepper()
    assert stepper.ctrl.native is not None and stepper.ctrl.native.steps >= 1
    assert np.isfinite(cmd.tau).all() and cmd.report.tasks
    n, levels, rows = sc._shape({sc.NATIVE_STEP: stepper})
    assert n == stepper.ctrl.last_x.size and levels >= 5 and rows > n
