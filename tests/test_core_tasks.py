"""Native task kernels against the Python tasks (the oracle): rows equal to 1e-10.

At 10 random states of each robot, with random goals and feedforward, and with gains whose
saturations (eq. 27-28) are active in some draws and not in others.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hqp import robots
from hqp.layout import Layout
from hqp.tasks.com import CoMTask
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask
from hqp.tasks.reference import PDReference

from test_core_model import native_model

core = pytest.importorskip("hqp._core._ext")

NO_SCALE = np.zeros(0)


def _gains(task):
    r = task.reference
    return r.kp, r.kv, r.max_velocity, r.max_acceleration


def native_kernel(task, nat):
    """The kernel that mirrors a Python tracking task (its frame, selection and scale)."""
    scale = NO_SCALE if task.scale is None else np.asarray(task.scale, dtype=float)
    if isinstance(task, PositionTask):
        return core.VectorTracking("frame_position", nat.frame_id(task.frame),
                                   np.asarray(task.axes, dtype=np.int32), np.zeros(0, np.int32),
                                   scale, *_gains(task))
    if isinstance(task, CoMTask):
        return core.VectorTracking("com", -1, np.arange(task.goal_size, dtype=np.int32),
                                   np.zeros(0, np.int32), scale, *_gains(task))
    if isinstance(task, PostureTask):
        return core.VectorTracking("joints", -1, task._q_index.astype(np.int32),
                                   task._v_index.astype(np.int32), scale, *_gains(task))
    raise TypeError(task)


def _tasks(robot, py, rng):
    sat = dict(max_velocity=0.3, max_acceleration=2.0)
    return [
        PositionTask(py, robot.hands[0], kp=50.0),
        PositionTask(py, robot.hands[1], axes="xz", kp=80.0, kv=10.0, **sat),
        CoMTask(py, kp=30.0),
        CoMTask(py, horizontal=True, kp=30.0, max_acceleration=0.5, name="com_xy"),
        PostureTask(py, kp=20.0, weights=rng.uniform(0.5, 2.0, py.na)),
        PostureTask.symmetry(py, kp=10.0, **sat),
    ]


@pytest.mark.parametrize("name", robots.NAMES)
def test_tracking_kernels_equal_the_python_rows(name):
    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    layout = Layout.build(py.nv, [])
    n = layout.n + 7  # columns beyond qdd stay zero
    rng = np.random.default_rng(3)
    tasks = _tasks(robot, py, rng)
    kernels = [native_kernel(t, nat) for t in tasks]
    for _ in range(10):
        q = py.random_configuration(rng)
        v = rng.normal(size=py.nv)
        py.update(q, v)
        nat.update(q, v)
        for task, kernel in zip(tasks, kernels):
            m = task.goal_size
            goal = task.value(py) + rng.normal(scale=0.2, size=m)
            vel, acc = rng.normal(size=m), rng.normal(size=m)
            task.set_goal(goal, vel, acc)
            kernel.set_goal(goal, vel, acc)
            rows = task.rows(py, layout, 1e-3, 0.0)
            A, b = kernel.write(nat, n)
            scale = max(1.0, np.abs(rows.b).max())
            np.testing.assert_allclose(A[:, :layout.n], rows.A, rtol=0, atol=1e-10 * max(
                1.0, np.abs(rows.A).max()), err_msg=task.name)
            assert not A[:, layout.n:].any()
            np.testing.assert_allclose(b, rows.b, rtol=0, atol=1e-10 * scale, err_msg=task.name)
            np.testing.assert_allclose(kernel.reference_acceleration,
                                       task.reference_acceleration(), rtol=0, atol=1e-10 * scale)


def test_pd_feedback_equals_the_python_reference_with_and_without_saturation():
    rng = np.random.default_rng(0)
    for kp, kv, vmax, amax in [(100.0, None, math.inf, math.inf), (100.0, 5.0, 0.1, math.inf),
                               (25.0, 10.0, math.inf, 0.5), (9.0, 6.0, 0.2, 1.0),
                               (0.0, 3.0, 1.0, 1.0)]:
        ref = PDReference(kp, kv, vmax, amax)
        for _ in range(20):
            e, rate = rng.normal(size=4), rng.normal(size=4)
            out = core.pd_feedback(e, rate, ref.kp, ref.kv, ref.max_velocity,
                                   ref.max_acceleration)
            np.testing.assert_allclose(out, ref.feedback(e, rate), rtol=1e-15, atol=1e-15)
