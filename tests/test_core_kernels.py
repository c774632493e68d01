"""The kernels of the operational and collision primitives against their Python tasks.

Gaze, pose, hybrid force/position, internal forces, capsule distances (obstacle avoidance
and self-collision) and minimum effort: at 10 random states of each robot their rows equal
the Python task's to 1e-10, and their Jacobians and drifts pass the finite-difference checks
of the Python tasks (``tests/task_fd.py``, the collision test's for the distances).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from task_fd import check_kinematics
from test_core_model import native_model

from hqp import robots
from hqp.layout import ContactType, Layout
from hqp.model.world import Capsule, Sphere, World
from hqp.tasks.collision import ObstacleAvoidance, SelfCollision
from hqp.tasks.effort import EffortTask
from hqp.tasks.gaze import GazeTask
from hqp.tasks.hybrid import HybridTask
from hqp.tasks.internal_forces import COMPONENTS, InternalForcesTask
from hqp.tasks.pose import PoseTask
from hqp.tasks.reference import MinimumJerk, MinimumJerkPose
from hqp.tasks.tracking import TaskKinematics

core = pytest.importorskip("hqp._core._ext")

I32 = np.int32


def _gains(task):
    r = task.reference
    return r.kp, r.kv, r.max_velocity, r.max_acceleration


def _close(a, b, what):
    b = np.asarray(b, dtype=float)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * max(1.0, float(np.abs(b).max(
        initial=0.0))), err_msg=what)


def gaze_kernel(task, nat):
    return core.GazeKernel(nat.frame_id(task.frame), task.axis, task._P, *_gains(task))


def pose_kernel(task, nat, layout):
    """The kernel of a PoseTask or HybridTask (as hqp.control.native builds it)."""
    linear, angular, start, force = np.arange(3), np.arange(3), 0, np.zeros(0, int)
    if isinstance(task, HybridTask):
        slot = layout.contact(task.contact)
        linear = task._linear
        angular = task._angular if slot.kind is ContactType.SURFACE else np.zeros(0, int)
        start, force = slot.start, task._force_index
    ang = task.angular_reference
    return core.PoseKernel(nat.frame_id(task.frame), linear.astype(I32), angular.astype(I32),
                           isinstance(task, HybridTask), *_gains(task), ang.max_velocity,
                           ang.max_acceleration, int(start), np.asarray(force, dtype=I32))


def internal_kernel(task, nat, layout):
    s1, s2 = task._slots(layout)
    names = COMPONENTS if s1.size == 6 else ("tension",)
    index = np.array([names.index(c) for c in task.components(layout)], dtype=I32)
    return core.InternalForcesKernel(nat.frame_id(s1.frame), s1.size, s1.start,
                                     nat.frame_id(s2.frame), s2.start, index)


def distance_kernel(task, nat):
    kernel = core.DistanceKernel(task.d_safe, task.d_influence, task.xi,
                                 0.0 if task.kv is None else task.kv)
    if isinstance(task, SelfCollision):
        for a, b in task.pairs:
            kernel.add_pair(nat.frame_id(a.frame), a.point_a, a.point_b, a.radius,
                            nat.frame_id(b.frame), b.point_a, b.point_b, b.radius)
    else:
        for p in task.proxies:
            for k, _o in enumerate(task.selected_obstacles()):
                kernel.add_obstacle_pair(nat.frame_id(p.frame), p.point_a, p.point_b, p.radius, k)
    return kernel


def push_obstacles(task, kernel, shift=0.0):
    """The obstacles' segments ``shift`` seconds along their velocities (none: self-collision)."""
    if isinstance(task, SelfCollision):
        return
    for k, o in enumerate(task.selected_obstacles()):
        a, b = o.segment
        kernel.set_obstacle(k, a + shift * o.velocity, b + shift * o.velocity, o.velocity,
                            o.radius)


def _layout(robot, py):
    """The robot's contacts (surface soles) and a point contact on each hand."""
    entries = [(c.name, c.frame, c.kind) for c in robot.contacts]
    entries += [(f"point_{h}", h, ContactType.POINT) for h in robot.hands]
    return Layout.build(py.nv, entries)


def _set_goal(task, kernel, g):
    if isinstance(task, PoseTask):
        kernel.set_goal(g.position, g.velocity, g.acceleration)
        if isinstance(task, HybridTask):
            kernel.set_force(task._force)
    else:
        kernel.set_goal(g.position, g.velocity, g.acceleration)


def _tracking_tasks(robot, py):
    sat = dict(max_velocity=0.3, max_acceleration=2.0)
    head = robot.head_frame or robot.base_frame
    foot = robot.contacts[0]
    return [
        GazeTask(py, head, kp=25.0, name="gaze"),
        GazeTask(py, robot.hands[0], axis=(0.3, -1.0, 0.2), kp=16.0, kv=3.0, name="hand_gaze",
                 **sat),
        PoseTask(py, robot.hands[1], kp=50.0),
        PoseTask(py, robot.hands[0], kp=40.0, kv=9.0, max_angular_velocity=0.4,
                 max_angular_acceleration=3.0, name="sat_pose", **sat),
        HybridTask(py, foot.frame, foot.name, kp=30.0, name="hybrid_fz"),
        HybridTask(py, foot.frame, foot.name, force_axes=("fx", "fz", "ty"), kp=30.0,
                   name="hybrid_mixed", **sat),
        HybridTask(py, robot.hands[1], f"point_{robot.hands[1]}", force_axes=("fy",), kp=20.0,
                   name="hybrid_point"),
    ]


def _random_goal(task, py, rng):
    if isinstance(task, PoseTask):
        H = py.frame_placement(task.frame) * pin.exp6(rng.normal(scale=0.3, size=6))
        task.set_goal(H.homogeneous, rng.normal(size=6), rng.normal(size=6))
        if isinstance(task, HybridTask):
            task.set_force(rng.normal(scale=50.0, size=len(task.force_axes)))
    else:  # a target around the head, in front of the ray in most draws
        M = py.frame_placement(task.frame)
        target = M.translation + M.rotation @ (task.axis + rng.normal(scale=0.5, size=3))
        task.set_goal(target, rng.normal(size=3), rng.normal(size=3))


@pytest.mark.parametrize("name", robots.NAMES)
def test_gaze_pose_and_hybrid_kernels_equal_the_python_rows(name):
    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    layout = _layout(robot, py)
    rng = np.random.default_rng(5)
    tasks = _tracking_tasks(robot, py)
    kernels = []
    for task in tasks:
        kernels.append(gaze_kernel(task, nat) if isinstance(task, GazeTask)
                       else pose_kernel(task, nat, layout))
    for _ in range(10):
        q = py.random_configuration(rng)
        v = rng.normal(size=py.nv)
        py.update(q, v)
        nat.update(q, v)
        for task, kernel in zip(tasks, kernels):
            _random_goal(task, py, rng)
            _set_goal(task, kernel, task.goal_at(0.0))
            rows = task.rows(py, layout, 1e-3, 0.0)
            A, b = kernel.write(nat, layout.n)
            _close(A, rows.A, f"{task.name} A")
            _close(b, rows.b, f"{task.name} b")
            _close(kernel.error, -task.error(), f"{task.name} error")
            _close(kernel.reference_acceleration, task.reference_acceleration(),
                   f"{task.name} a_fb")


def _kernel_kinematics(task, kernel, nat, layout):
    """The kernel's (e, de/dt, J, drift) at a Python model's state, the goal at time t."""
    nv = nat.nv

    def kinematics(model, t):
        nat.update(model.q, model.v)
        _set_goal(task, kernel, task.goal_at(t))
        A, _b = kernel.write(nat, layout.n)
        k = len(kernel.error)
        return TaskKinematics(kernel.error, kernel.rate, A[:k, :nv], kernel.drift)

    return kinematics


@pytest.mark.parametrize("name", robots.NAMES)
def test_gaze_pose_and_hybrid_kernels_pass_the_finite_difference_checks(name):
    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    layout = _layout(robot, py)
    rng = np.random.default_rng(6)
    for task in _tracking_tasks(robot, py):
        if isinstance(task, PoseTask):
            task.set_trajectory(MinimumJerkPose(pin.SE3.Random(), pin.SE3.Random(), 1.0, 0.0))
            kernel = pose_kernel(task, nat, layout)
        else:
            task.set_trajectory(MinimumJerk(np.array([2.0, 0.5, 1.0]),
                                            np.array([1.0, -1.0, 2.0]), 1.0))
            kernel = gaze_kernel(task, nat)
        check_kinematics(py, _kernel_kinematics(task, kernel, nat, layout), rng, n=10)


def _internal_tasks(robot, py):
    feet = [c.name for c in robot.contacts[:2]]
    points = [f"point_{h}" for h in robot.hands]
    return [
        InternalForcesTask(py, feet),
        InternalForcesTask(py, feet[::-1], ["moment_vertical", "tension", "shear_vertical"],
                           name="some"),
        InternalForcesTask(py, feet, list(COMPONENTS), name="all"),
        InternalForcesTask(py, points, name="hands"),
    ]


@pytest.mark.parametrize("name", robots.NAMES)
def test_internal_forces_kernel_equals_the_python_rows(name):
    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    layout = _layout(robot, py)
    rng = np.random.default_rng(7)
    tasks = _internal_tasks(robot, py)
    kernels = [internal_kernel(t, nat, layout) for t in tasks]
    for trial in range(10):
        q = py.random_configuration(rng)
        py.update(q, np.zeros(py.nv))
        nat.update(q, np.zeros(py.nv))
        for task, kernel in zip(tasks, kernels):
            k = len(task.components(layout))
            if trial % 2:
                task.set_goal(rng.normal(scale=20.0, size=k))
            kernel.set_goal(task.goal_of(k))
            rows = task.rows(py, layout, 1e-3, 0.0)
            A, b = kernel.write(nat, layout.n)
            _close(A, rows.A, f"{task.name} A")
            _close(b, rows.b, f"{task.name} b")


def _distance_tasks(robot, py, rng):
    caps = list(robot.capsules)
    hand = py.frame_placement(robot.hands[1]).translation
    world = World([
        Sphere("ball", hand + rng.normal(scale=0.1, size=3), 0.1, velocity=[0.1, 0.0, 0.2]),
        Capsule("pole", hand + [0.2, -0.3, -0.2], hand + [0.1, 0.3, 0.3], 0.05,
                velocity=[0.0, 0.3, -0.1]),
    ])
    pairs = [(a, b) for i, a in enumerate(caps) for b in caps[i + 1:] if a.frame != b.frame]
    pick = rng.choice(len(pairs), size=min(12, len(pairs)), replace=False)
    return [
        ObstacleAvoidance("avoid", world, caps, d_influence=2.0),
        ObstacleAvoidance("avoid_ball", world, caps[:3], ["ball"], d_safe=0.02, d_influence=0.5,
                          xi=0.5, kv=40.0),
        SelfCollision("self", [pairs[i] for i in pick], d_influence=1.0),
    ]


@pytest.mark.parametrize("name", robots.NAMES)
def test_distance_kernels_equal_the_python_rows(name):
    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    layout = Layout.build(py.nv, [(c.name, c.frame, c.kind) for c in robot.contacts])
    rng = np.random.default_rng(8)
    py.update(robot.q_standing, np.zeros(py.nv))
    tasks = _distance_tasks(robot, py, rng)
    kernels = [distance_kernel(t, nat) for t in tasks]
    world = tasks[0].world
    active = 0
    for trial in range(10):
        q = robot.q_standing.copy()
        q[7:] += rng.normal(scale=0.3, size=py.na)
        v = rng.normal(size=py.nv)
        py.update(q, v)
        nat.update(q, v)
        world.step(0.05)
        dt = [1e-3, 2e-3][trial % 2]
        for task, kernel in zip(tasks, kernels):
            push_obstacles(task, kernel)
            rows = task.rows(py, layout, dt, 0.0)
            C, lo, up = kernel.write(nat, dt, layout.n)
            _close(C, rows.C, f"{task.name} C")
            np.testing.assert_array_equal(np.isinf(lo), np.isinf(rows.lower))
            f = np.isfinite(rows.lower)
            _close(lo[f], rows.lower[f], f"{task.name} lower")
            np.testing.assert_array_equal(up, rows.upper)
            _close(kernel.margins, task.error(), f"{task.name} margins")
            active += int(f.sum())
    assert active > 20  # rows with a finite bound, not only the -inf of distant pairs


@pytest.mark.parametrize("name", robots.NAMES)
def test_distance_kernels_pass_the_finite_difference_checks(name):
    """d_dot vs FD of d, J qdd + drift vs FD of d_dot (the obstacles moving with time)."""
    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    rng = np.random.default_rng(9)
    py.update(robot.q_standing, np.zeros(py.nv))
    for task in _distance_tasks(robot, py, rng):
        kernel = distance_kernel(task, nat)

        def kinematics(model, t, task=task, kernel=kernel):
            nat.update(model.q, model.v)
            push_obstacles(task, kernel, t)
            C, _lo, _up = kernel.write(nat, 1e-3, py.nv)
            return TaskKinematics(kernel.distance, kernel.rate, C, kernel.drift)

        check_kinematics(py, kinematics, rng, n=10, t=0.0)


@pytest.mark.parametrize("name", robots.NAMES)
def test_effort_rows_of_the_native_step_equal_the_python_rows(name):
    """EffortTask has no kernel object: its rows, diag(w) S [M | -J^T], are the step's own;
    read from a native step's level."""
    from hqp.robots.robot import ROOT_JOINT

    robot = robots.load(name)
    py = robot.model()
    layout = _layout(robot, py)
    frames = [(n, p, T.homogeneous) for n, (p, T) in robot.extra_frames.items()]
    nat = native_model(robot)
    slots = [(nat.frame_id(c.frame), c.kind.value, c.start) for c in layout.contacts]
    rng = np.random.default_rng(10)
    tasks = [EffortTask(py), EffortTask(py, normalize=False, name="raw")]
    steps = []
    for task in tasks:
        step = core.NativeStep(str(robot.urdf_path), ROOT_JOINT, frames, py.nv_base, slots, 1,
                               1e-9, True, True)
        step.add_effort(0, 1.0, np.asarray(task._w, dtype=float))
        steps.append(step)
    for _ in range(10):
        q = py.random_configuration(rng)
        v = rng.normal(size=py.nv)
        py.update(q, v)
        for task, step in zip(tasks, steps):
            step.step(q, v, 1e-3)
            (_level, A, b, _C, _lo, _up), = step.levels()
            rows = task.rows(py, layout, 1e-3, 0.0)
            _close(A, rows.A, f"{task.name} A")
            _close(b, rows.b, f"{task.name} b")


def cop_kernel(task, nat, layout):
    """The kernel of a CoPTask (as hqp.control.native builds it)."""
    slots = [(nat.frame_id(c.frame), c.size, c.start) for c in task._slots(layout)]
    return core.CoPKernel(slots, np.nan if task.height is None else task.height, task._scale)


@pytest.mark.parametrize("name", robots.NAMES)
def test_cop_kernel_equals_the_python_rows(name):
    """The support's CoP rows: every contact (surface and point slots), the feet alone, one
    foot; the plane at a fixed height and at the feet's mean height (recomputed per state)."""
    from hqp.tasks.cop import CoPTask

    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    layout = _layout(robot, py)
    feet = [c.name for c in robot.contacts[:2]]
    tasks = [CoPTask(py), CoPTask(py, feet, height=0.02, name="feet"),
             CoPTask(py, feet[:1], name="one_foot"),
             CoPTask(py, [feet[0], f"point_{robot.hands[0]}"], height=-0.1, name="foot_hand")]
    kernels = [cop_kernel(t, nat, layout) for t in tasks]
    rng = np.random.default_rng(12)
    for _ in range(10):
        q = py.random_configuration(rng)
        py.update(q, np.zeros(py.nv))
        nat.update(q, np.zeros(py.nv))
        for task, kernel in zip(tasks, kernels):
            task.set_goal(rng.normal(scale=0.2, size=2))
            kernel.set_goal(task.goal_at(0.0))
            rows = task.rows(py, layout, 1e-3, 0.0)
            A, b = kernel.write(nat, layout.n)
            assert np.abs(rows.A).max() > 0.0
            _close(A, rows.A, f"{task.name} A")
            _close(b, rows.b, f"{task.name} b")
