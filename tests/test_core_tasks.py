"""Native task kernels against the Python tasks (the oracle): rows equal to 1e-10.

At 10 random states of each robot, with random goals and feedforward, and with gains whose
saturations (eq. 27-28) are active in some draws and not in others.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_core_model import native_model

from hqp import robots
from hqp.layout import Layout
from hqp.tasks.centroidal import CentroidalMomentumTask
from hqp.tasks.com import CoMTask
from hqp.tasks.orientation import OrientationTask, jlog3_rate_times
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask
from hqp.tasks.reference import PDReference

core = pytest.importorskip("hqp._core._ext")

NO_SCALE = np.zeros(0)


def _gains(task):
    r = task.reference
    return r.kp, r.kv, r.max_velocity, r.max_acceleration


def native_kernel(task, nat):
    """The kernel that mirrors a Python tracking task (its frame, selection and scale)."""
    scale = getattr(task, "scale", None)
    scale = NO_SCALE if scale is None else np.asarray(scale, dtype=float)
    if isinstance(task, PositionTask):
        return core.VectorTracking("frame_position", nat.frame_id(task.frame),
                                   np.asarray(task.axes, dtype=np.int32), np.zeros(0, np.int32),
                                   scale, *_gains(task))
    if isinstance(task, CoMTask):
        return core.VectorTracking("com", -1, np.arange(task.goal_size, dtype=np.int32),
                                   np.zeros(0, np.int32), scale, *_gains(task))
    if isinstance(task, CentroidalMomentumTask):
        return core.VectorTracking("centroidal", -1, task.components.astype(np.int32),
                                   np.zeros(0, np.int32), NO_SCALE, *_gains(task))
    if isinstance(task, OrientationTask):
        return core.OrientationTracking(nat.frame_id(task.frame), *_gains(task))
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
        CentroidalMomentumTask(py, gain=8.0),
        CentroidalMomentumTask(py, "all", gain=5.0, max_rate=3.0, name="momentum"),
        OrientationTask(py, robot.base_frame, kp=40.0),
        OrientationTask(py, robot.hands[0], kp=60.0, kv=12.0, max_velocity=0.5,
                        max_acceleration=4.0, name="hand_orientation"),
    ]


def _random_goal(task, py, rng):
    """A goal near the current value, with feedforward: (goal, velocity, acceleration)."""
    import pinocchio as pin

    if isinstance(task, OrientationTask):
        R = task.value(py) @ pin.exp3(rng.normal(scale=0.4, size=3))
        return R, rng.normal(size=3), rng.normal(size=3)
    if isinstance(task, CentroidalMomentumTask):
        m = len(task.components)
        return task.value(py) + rng.normal(size=m), rng.normal(size=m), None
    m = task.goal_size
    return task.value(py) + rng.normal(scale=0.2, size=m), rng.normal(size=m), rng.normal(size=m)


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
            goal, vel, acc = _random_goal(task, py, rng)
            if acc is None:  # momentum: the goal and its rate
                task.set_goal(goal, vel)
                kernel.set_goal(goal, vel, np.zeros_like(vel))
            else:
                task.set_goal(goal, vel, acc)
                kernel.set_goal(goal, vel, acc)
            rows = task.rows(py, layout, 1e-3, 0.0)
            A, b = kernel.write(nat, n)
            scale = max(1.0, np.abs(rows.b).max())
            np.testing.assert_allclose(A[:, :layout.n], rows.A, rtol=0, atol=1e-10 * max(
                1.0, np.abs(rows.A).max()), err_msg=task.name)
            assert not A[:, layout.n:].any()
            np.testing.assert_allclose(b, rows.b, rtol=0, atol=1e-10 * scale, err_msg=task.name)
            if hasattr(task, "reference_acceleration"):
                np.testing.assert_allclose(kernel.reference_acceleration,
                                           task.reference_acceleration(), rtol=0,
                                           atol=1e-10 * scale)


def test_jlog3_rate_times_equals_the_python_function():
    rng = np.random.default_rng(2)
    for scale in (1e-4, 1e-2, 0.5, 3.0):  # both branches of the series
        for _ in range(20):
            e = rng.normal(size=3)
            e *= scale / np.linalg.norm(e)
            de, xi = rng.normal(size=3), rng.normal(size=3)
            np.testing.assert_allclose(core.jlog3_rate_times(e, de, xi),
                                       jlog3_rate_times(e, de, xi), rtol=1e-13, atol=1e-15)


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


def _contacts(robot, py):
    from hqp.layout import ContactType
    from hqp.tasks.contact import Contact

    out = []
    for k, c in enumerate(robot.contacts):
        out.append(Contact(c.name, c.frame, c.kind, mu=c.friction, half_length=c.half_length,
                           half_width=c.half_width, f_min=5.0 * k, f_max=800.0 + k,
                           kp=(20.0 if k == 0 else 0.0), kd=(3.0 if k == 0 else 0.0),
                           model=py))
    # a point contact on a hand too (3 entries)
    out.append(Contact("hand", robot.hands[0], ContactType.POINT, mu=0.4, model=py))
    return out


@pytest.mark.parametrize("name", robots.NAMES)
def test_physics_kernels_equal_the_python_rows(name):
    """[M | -J_c^T], the contact condition rows (kp/kd, inactive) and the wrench-cone limits."""
    import pinocchio as pin

    from hqp.tasks.dynamics import contact_dynamics_matrix

    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    contacts = _contacts(robot, py)
    layout = Layout.build(py.nv, [c.layout_entry() for c in contacts])
    slots = [(nat.frame_id(c.frame), c.kind.value, layout.contact(c.name).start)
             for c in contacts]
    rng = np.random.default_rng(9)
    kernels = []
    for c, (frame, size, start) in zip(contacts, slots):
        kernels.append(core.ContactKernel(frame, size, start, c.mu, c.half_length, c.half_width,
                                          c.f_min, c.max_normal_force, c.kp, c.kd))
    for trial in range(10):
        q = py.random_configuration(rng)
        v = rng.normal(size=py.nv)
        py.update(q, v)
        nat.update(q, v)
        G = contact_dynamics_matrix(py, layout)
        _close_rows(core.contact_dynamics(nat, slots), G, "[M | -J^T]")
        for c, kernel in zip(contacts, kernels):
            active = trial % 3 != 2
            if not active:
                c.deactivate()
                kernel.deactivate()
            elif trial % 2:  # a given reference placement of the kp term
                ref = py.frame_placement(c.frame) * pin.exp6(rng.normal(scale=0.05, size=6))
                c.activate(ref)
                kernel.activate(ref.homogeneous)
            elif trial == 0:  # the placement at the first rows becomes the reference
                c.activate()
                kernel.activate()
            rows = c.rows(py, layout, 1e-3, 0.0)
            A, b = kernel.write(nat, layout.n)
            _close_rows(A, rows.A, c.name + " A")
            _close_rows(b, rows.b, c.name + " b")
            lim = c.limit_rows(py, layout)
            C, lo, up = kernel.write_limits(nat, layout.n)
            _close_rows(C, lim.C, c.name + " C")
            np.testing.assert_array_equal(lo, lim.lower)
            np.testing.assert_array_equal(up, lim.upper)


def _close_rows(a, b, what):
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * max(1.0, float(np.abs(b).max())),
                               err_msg=what)


def test_wrench_cone_equals_the_python_cone():
    from hqp.layout import ContactType
    from hqp.tasks.contact import Contact

    for kind, mu, X, Y in [(ContactType.SURFACE, 0.7, 0.1, 0.05), (ContactType.POINT, 0.3, 0, 0),
                           (ContactType.SURFACE, 1.2, 0.12, 0.04)]:
        c = Contact("c", "f", kind, mu=mu, half_length=X, half_width=Y)
        np.testing.assert_array_equal(core.contact_local_limits(kind.value, mu, X, Y),
                                      c.local_limits())


@pytest.mark.parametrize("name", robots.NAMES)
def test_joint_limit_bounds_equal_the_python_bounds(name):
    """Viable bounds at states inside, at and past the limits, slow and fast, for several
    settings (acceleration bounds on/off, reserve, recovery, velocity and approach times,
    margins)."""
    from hqp.tasks.joint_limits import JointLimits

    robot = robots.load(name)
    py = robot.model()
    na = py.na
    rng = np.random.default_rng(21)
    settings = [
        dict(qdd_max=50.0),
        dict(qdd_max=rng.uniform(5.0, 80.0, na), braking=rng.uniform(0.5, 5.0, na), reserve=4.0,
             velocity_time=0.05, position_margin=0.02, velocity_scale=0.8),
        dict(qdd_max=30.0, braking=2.0, acceleration_bounds=False, inactive_beyond=200.0),
        dict(qdd_max=rng.uniform(5.0, 80.0, na), braking=rng.uniform(0.5, 5.0, na), reserve=2.0,
             velocity_time=0.02, approach_time=0.02),
        dict(qdd_max=rng.uniform(5.0, 80.0, na), braking=rng.uniform(0.5, 5.0, na), reserve=2.0,
             velocity_time=0.02, recovery=np.where(rng.random(na) < 0.5,
                                                   rng.uniform(10.0, 3e4, na), 0.0)),
    ]
    for kwargs in settings:
        jl = JointLimits(**kwargs)
        for trial in range(12):
            q = py.random_configuration(rng)
            lo, hi = py.q_lower, py.q_upper
            span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
            if trial % 3 == 1:  # some joints past their limits, some at them
                pick = rng.random(na) < 0.3
                q[py.actuated_q] = np.where(pick, hi + rng.uniform(-0.01, 0.05, na) * span,
                                            q[py.actuated_q])
            v = rng.normal(scale=[0.3, 3.0, 30.0][trial % 3], size=py.nv)
            py.update(q, v)
            dt = [1e-3, 2e-3, 5e-3][trial % 3]
            lb, ub = jl.bounds(py, dt)
            nlb, nub = core.joint_limit_bounds(
                py.q[py.actuated_q], py.v[py.actuated], lo + jl.position_margin,
                hi - jl.position_margin, jl.velocity_scale * py.v_max, jl.max_acceleration(py),
                jl.braking_deceleration(py), dt, jl.reserve, jl.velocity_time,
                jl.inactive_beyond, jl.acceleration_bounds, jl.approach_time,
                jl.recovery_deceleration(py))
            for a, b in ((nlb, lb), (nub, ub)):
                np.testing.assert_array_equal(np.isinf(a), np.isinf(b))
                f = np.isfinite(b)
                np.testing.assert_allclose(a[f], b[f], rtol=1e-12, atol=1e-12)
