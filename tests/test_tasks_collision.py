"""Capsule distances against finite differences and sampling; damper rows; bad input."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError, InvalidFrame, InvalidGain, UnknownName
from hqp.model import RobotModel
from hqp.model.layout import Layout
from hqp.model.world import Box, Capsule, Sphere, World
from hqp.tasks.base import Category
from hqp.tasks.collision import (
    CapsuleProxy,
    ObstacleAvoidance,
    SelfCollision,
    closest_parameters,
)


@pytest.fixture(scope="module")
def robot() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


def proxies() -> list[CapsuleProxy]:
    return [
        CapsuleProxy("r_forearm", "rarm_lowerarm_body", [0.0, 0.0, 0.0], [0.0, 0.0, -0.3], 0.04),
        CapsuleProxy("l_forearm", "larm_lowerarm_body", [0.0, 0.05, 0.0], [0.1, 0.0, -0.3], 0.05),
        CapsuleProxy("chest", "chest2_body", [0.0, -0.2, 0.1], [0.0, 0.2, 0.1], 0.1),
    ]


def moving_world() -> World:
    return World([
        Sphere("ball", [0.3, 0.1, 0.2], 0.1, velocity=[0.1, 0.0, 0.2]),
        Capsule("pole", [0.2, -0.5, 0.0], [0.3, 0.5, 0.5], 0.05, velocity=[0.0, 0.3, -0.1]),
    ])


def test_distance_derivatives_match_finite_differences(robot: RobotModel) -> None:
    """d_dot vs FD of d, J qdd + drift vs FD of d_dot, along q (+) (s v + s^2 qdd / 2)."""
    rng = np.random.default_rng(21)
    world = moving_world()
    px = proxies()
    tasks = [
        ObstacleAvoidance("obs", world, px[:2]),
        SelfCollision("self", [(px[0], px[1]), (px[0], px[2]), (px[1], px[2])]),
    ]
    other = RobotModel(robot.model, name="fd")
    eps = 1e-6
    interior = 0
    for _ in range(12):
        q = robot.random_configuration(rng)
        v = rng.normal(size=robot.nv)
        qdd = rng.normal(size=robot.nv)
        robot.update(q, v)
        for task in tasks:
            dists = task.distances(robot)

            def at(s: float, task=task, q=q, v=v, qdd=qdd):
                other.update(other.integrate(q, s * v + 0.5 * s * s * qdd), v + s * qdd)
                for ob in world:
                    ob.translate(s * ob.velocity)
                out = task.distances(other)
                for ob in world:
                    ob.translate(-s * ob.velocity)
                return out

            plus, minus = at(eps), at(-eps)
            for d0, dp, dm in zip(dists, plus, minus):
                fd_rate = (dp.d - dm.d) / (2 * eps)
                fd_acc = (dp.d_dot - dm.d_dot) / (2 * eps)
                acc = d0.jacobian @ qdd + d0.drift
                np.testing.assert_allclose(d0.d_dot, fd_rate, atol=1e-6 * (1 + abs(fd_rate)))
                np.testing.assert_allclose(acc, fd_acc, atol=1e-5 * (1 + abs(fd_acc)))
            # The rate is affine in v with slope J.
            dv = rng.normal(size=robot.nv)
            other.update(q, v + dv)
            for d0, d1 in zip(dists, task.distances(other)):
                np.testing.assert_allclose(d1.d_dot - d0.d_dot, d0.jacobian @ dv, atol=1e-9)
        # Count robot-robot pairs whose closest points are interior on both segments.
        for a, b in tasks[1].pairs:
            sa = robot.frame_placement(a.frame)
            sb = robot.frame_placement(b.frame)
            pa, pb = sa.act(a.point_a), sb.act(b.point_a)
            s, t = closest_parameters(pa, sa.rotation @ (a.point_b - a.point_a),
                                      pb, sb.rotation @ (b.point_b - b.point_a))
            interior += (0 < s < 1) and (0 < t < 1)
    assert interior > 0


def _sampled_distance(a1, b1, r1, a2, b2, r2) -> float:
    s = np.linspace(0.0, 1.0, 201)
    p1 = a1[None] + s[:, None] * (b1 - a1)[None]
    p2 = a2[None] + s[:, None] * (b2 - a2)[None]
    return float(np.min(np.linalg.norm(p1[:, None] - p2[None], axis=2))) - r1 - r2


def test_distance_value_against_sampling(robot: RobotModel) -> None:
    rng = np.random.default_rng(22)
    px = proxies()
    world = moving_world()
    task = ObstacleAvoidance("obs", world, px)
    for _ in range(10):
        robot.update(robot.random_configuration(rng), np.zeros(robot.nv))
        for (p, ob), d in zip([(p, o) for p in px for o in world], task.distances(robot)):
            T = robot.frame_placement(p.frame)
            a2, b2 = ob.segment
            ref = _sampled_distance(T.act(p.point_a), T.act(p.point_b), p.radius, a2, b2, ob.radius)
            assert ref - 2e-3 <= d.d <= ref + 1e-12


def test_closest_parameters_cases() -> None:
    z = np.zeros(3)
    ex, ey = np.eye(3)[0], np.eye(3)[1]
    assert closest_parameters(z, ex, ey + 0.5 * ex, ey) == (0.5, 0.0)  # end of the second
    s, t = closest_parameters(z, ex, np.array([0.5, -0.5, 1.0]), ey)
    np.testing.assert_allclose((s, t), (0.5, 0.5))  # crossing segments
    assert closest_parameters(z, z, ex, z) == (0.0, 0.0)  # two points
    assert closest_parameters(z, 2 * ex, ex + ey, z) == (0.5, 0.0)  # point to segment
    s, t = closest_parameters(z, ex, ey, ex)  # parallel
    assert s == 0.0 and t == 0.0


def test_damper_rows(robot: RobotModel) -> None:
    rng = np.random.default_rng(23)
    world = World([Sphere("ball", [0.0, 0.0, 0.0], 0.1)])
    px = proxies()[:1]
    dt = 1e-3
    task = ObstacleAvoidance("obs", world, px, d_safe=0.05, d_influence=0.3, xi=0.4)
    assert task.category is Category.COLLISION
    layout = Layout.build(robot.nv, [])
    seen_near = seen_far = False
    for _ in range(20):
        robot.update(robot.random_configuration(rng), rng.normal(size=robot.nv))
        T = robot.frame_placement(px[0].frame)
        world.move("ball", T.act(np.array([0.0, 0.0, -0.15])) + rng.uniform(-0.5, 0.5, 3))
        rows = task.rows(robot, layout, dt, 0.0)
        (d,) = task.distances(robot)
        np.testing.assert_allclose(rows.C[0, : robot.nv], d.jacobian)
        np.testing.assert_allclose(task.error(), [d.d - 0.05])
        assert task.pair_names == ("r_forearm|ball",)
        if d.d < 0.3:
            seen_near = True
            d_dot_min = -0.4 * (d.d - 0.05) / 0.25
            np.testing.assert_allclose(rows.lower[0], (d_dot_min - d.d_dot) / dt - d.drift)
            # The row asks exactly: d_dot after one period >= the damper's bound.
            qdd = rows.lower[0] * d.jacobian / (d.jacobian @ d.jacobian)
            np.testing.assert_allclose(d.d_dot + dt * (d.jacobian @ qdd + d.drift), d_dot_min)
        else:
            seen_far = True
            assert rows.lower[0] == -np.inf
    assert seen_near and seen_far


def test_damper_keeps_distance_in_closed_loop() -> None:
    """A fixed-base arm whose hand is driven into a sphere, projected on the row each step."""
    arm = RobotModel(pin.buildSampleModelManipulator(), name="arm", floating_base=False)
    forearm = CapsuleProxy("forearm", "lowerarm_body", [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.05)
    q, v = arm.neutral(), np.zeros(arm.nv)
    q[1], q[3] = 0.6, 0.8
    arm.update(q, v)
    hand = arm.frame_placement("effector_body").translation
    world = World([Sphere("ball", hand + np.array([0.0, 0.5, 0.0]), 0.1)])
    task = ObstacleAvoidance("obs", world, [forearm], d_safe=0.05, d_influence=0.3, xi=0.5,
                             kv=50.0)
    layout = Layout.build(arm.nv)
    dt = 4e-3
    start = task.distances(arm)[0].d
    lowest, active = np.inf, 0
    for _ in range(500):
        arm.update(q, v)
        J = arm.frame_jacobian("effector_body")[:3]
        err = world.get("ball").position - arm.frame_placement("effector_body").translation
        a_des = 25.0 * err - 10.0 * (J @ v) - arm.frame_drift("effector_body")[:3]
        Jp = np.linalg.pinv(J)
        qdd = Jp @ a_des - (np.eye(arm.nv) - Jp @ J) @ (10.0 * v)
        rows = task.rows(arm, layout, dt, 0.0)
        c, lo = rows.C[0], rows.lower[0]
        if c @ qdd < lo:
            qdd = qdd + (lo - c @ qdd) * c / (c @ c)
            active += 1
        q = arm.integrate(q, dt * v + 0.5 * dt * dt * qdd)
        v = v + dt * qdd
        lowest = min(lowest, task.error()[0])
    assert start > 0.3
    assert active > 250  # the row was binding
    assert lowest >= 0.0  # never closer than d_safe
    assert lowest < 0.01  # and it approached it


def test_collision_errors(robot: RobotModel) -> None:
    world = World([Sphere("ball", [0, 0, 0], 0.1), Box("table", [1, 0, 0], [0.5, 0.5, 0.02])])
    bad = CapsuleProxy("x", "no_frame", [0, 0, 0], [0, 0, 1], 0.1)
    layout = Layout.build(robot.nv)
    task = ObstacleAvoidance("obs", world, [bad], obstacles=["ball"])
    with pytest.raises(InvalidFrame, match="ObstacleAvoidance 'obs': unknown frame 'no_frame'"):
        task.rows(robot, layout, 1e-3, 0.0)
    with pytest.raises(InvalidGain, match="radius"):
        CapsuleProxy("x", "chest2_body", [0, 0, 0], [0, 0, 1], -0.1)
    with pytest.raises(HQPError, match="point_a"):
        CapsuleProxy("x", "chest2_body", [0, 0], [0, 0, 1], 0.1)
    good = proxies()[:1]
    with pytest.raises(InvalidGain, match="d_influence"):
        ObstacleAvoidance("obs", world, good, obstacles=["ball"], d_safe=0.2, d_influence=0.1)
    with pytest.raises(InvalidGain, match="xi"):
        ObstacleAvoidance("obs", world, good, obstacles=["ball"], xi=-1.0)
    with pytest.raises(HQPError, match="box"):
        ObstacleAvoidance("obs", world, good, obstacles=["table"])
    with pytest.raises(UnknownName, match="obstacle 'wall'.*ball, table"):
        ObstacleAvoidance("obs", world, good, obstacles=["wall"])
    with pytest.raises(HQPError, match="no capsule proxies"):
        ObstacleAvoidance("obs", world, [])
    with pytest.raises(HQPError, match="same frame"):
        SelfCollision("self", [(good[0], good[0])])
    # Default obstacle set: spheres and capsules of the world (the box is a scene object).
    robot.update(robot.neutral(), np.zeros(robot.nv))
    rows = ObstacleAvoidance("obs", world, good).rows(robot, layout, 1e-3, 0.0)
    assert rows.n_in == 1


def test_capsule_records_are_accepted() -> None:
    from hqp.robots.robot import BodyCapsule

    record = BodyCapsule("shin", "rleg_elbow_body", (0.0, 0.0, 0.0), (0.0, 0.0, -0.3), 0.05)
    proxy = CapsuleProxy.of(record)
    assert proxy.frame == "rleg_elbow_body" and proxy.radius == 0.05
    np.testing.assert_array_equal(proxy.point_b, [0.0, 0.0, -0.3])
    assert CapsuleProxy.of(proxy) is proxy
    task = SelfCollision("self", [(record, proxies()[0])])
    assert task.pairs[0][0].frame == "rleg_elbow_body"
    with pytest.raises(HQPError, match="not a capsule record"):
        CapsuleProxy.of(object())
