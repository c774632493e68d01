"""Floating-base dynamics rows and torque limits against pinocchio's ABA and RNEA."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError, InvalidFrame
from hqp.model import RobotModel
from hqp.model.layout import ContactType, Layout
from hqp.tasks.base import Category
from hqp.tasks.dynamics import FloatingBaseDynamics, joint_torques, torque_map
from hqp.tasks.torque_limits import TorqueLimits

CONTACTS = [
    ("right_foot", "rleg_effector_body", ContactType.SURFACE),
    ("left_foot", "lleg_effector_body", ContactType.SURFACE),
    ("hand", "rarm_effector_body", ContactType.POINT),
]


@pytest.fixture(scope="module")
def robot() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


def external_forces(robot: RobotModel, data: pin.Data, layout: Layout, x: np.ndarray):
    """Contact wrenches of ``x`` (world axes at the frame origins) as joint-local pin.Forces."""
    model = robot.model
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    for slot in layout.contacts:
        frame = model.frames[robot.frame_id(slot.frame)]
        f = x[slot.slice]
        force = f[:3]
        torque = f[3:] if slot.size == 6 else np.zeros(3)
        p = data.oMf[robot.frame_id(slot.frame)].translation
        world = pin.Force(force, torque + np.cross(p, force))  # about the world origin
        fext[frame.parentJoint] += data.oMi[frame.parentJoint].actInv(world)
    return fext


def test_dynamics_rows_match_aba_and_rnea(robot: RobotModel) -> None:
    rng = np.random.default_rng(3)
    layout = Layout.build(robot.nv, CONTACTS)
    task = FloatingBaseDynamics()
    assert task.category is Category.PHYSICS
    data = robot.model.createData()
    for _ in range(10):
        q = robot.random_configuration(rng)
        v = rng.normal(size=robot.nv)
        robot.update(q, v)
        pin.framesForwardKinematics(robot.model, data, q)
        f = rng.normal(scale=50.0, size=layout.n - layout.nv)
        tau = rng.normal(scale=20.0, size=robot.na)
        x = np.concatenate([np.zeros(robot.nv), f])
        fext = external_forces(robot, data, layout, x)
        tau_full = np.concatenate([np.zeros(6), tau])
        qdd = pin.aba(robot.model, data, q, v, tau_full, fext)
        x[: robot.nv] = qdd
        rows = task.rows(robot, layout, 1e-3, 0.0)
        assert rows.A.shape == (6, layout.n)
        scale = 1.0 + np.abs(rows.b).max() + np.abs(f).max()
        np.testing.assert_allclose(rows.A @ x, rows.b, atol=1e-9 * scale)
        np.testing.assert_allclose(joint_torques(robot, layout, x), tau, atol=1e-9 * scale)
        np.testing.assert_allclose(task.torques(robot, layout, x), tau, atol=1e-9 * scale)
        # RNEA with the same external forces gives [0, tau].
        rnea = pin.rnea(robot.model, data, q, v, qdd, fext)
        np.testing.assert_allclose(rnea, tau_full, atol=1e-8 * scale)
        # A wrong contact force violates the rows.
        x_bad = x.copy()
        x_bad[layout.nv + 2] += 1.0
        assert np.abs(rows.A @ x_bad - rows.b).max() > 1e-3


def test_fixed_base_has_no_dynamics_rows() -> None:
    robot = RobotModel(pin.buildSampleModelManipulator(), name="arm", floating_base=False)
    layout = Layout.build(robot.nv)
    rows = FloatingBaseDynamics().rows(robot, layout, 1e-3, 0.0)
    assert rows.n_eq == 0 and rows.n_in == 0
    rng = np.random.default_rng(0)
    q, v, qdd = robot.random_configuration(rng), rng.normal(size=6), rng.normal(size=6)
    robot.update(q, v)
    np.testing.assert_allclose(
        joint_torques(robot, layout, qdd),
        pin.rnea(robot.model, robot.model.createData(), q, v, qdd),
        atol=1e-9,
    )


def test_torque_limit_rows_at_their_bounds(robot: RobotModel) -> None:
    rng = np.random.default_rng(4)
    layout = Layout.build(robot.nv, CONTACTS)
    tau_max = rng.uniform(5.0, 50.0, robot.na)
    task = TorqueLimits(tau_max=tau_max)
    assert task.category is Category.CONTACT_LIMITS
    data = robot.model.createData()
    for _ in range(10):
        q = robot.random_configuration(rng)
        v = rng.normal(size=robot.nv)
        robot.update(q, v)
        pin.framesForwardKinematics(robot.model, data, q)
        rows = task.rows(robot, layout, 1e-3, 0.0)
        f = rng.normal(scale=50.0, size=layout.n - layout.nv)
        signs = rng.choice([-1.0, 1.0], robot.na)
        for factor, feasible in ((1.0, True), (1.001, False), (0.5, True)):
            tau = factor * signs * tau_max
            x = np.concatenate([np.zeros(robot.nv), f])
            fext = external_forces(robot, data, layout, x)
            tau_full = np.concatenate([np.zeros(6), tau])
            x[: robot.nv] = pin.aba(robot.model, data, q, v, tau_full, fext)
            Cx = rows.C @ x
            inside = np.all(Cx >= rows.lower - 1e-7) and np.all(Cx <= rows.upper + 1e-7)
            assert inside == feasible
        T, t0 = torque_map(robot, layout)
        np.testing.assert_allclose(T @ x + t0, tau, atol=1e-8 * (1 + np.abs(f).max()))


def test_torque_limits_default_and_errors(robot: RobotModel) -> None:
    layout = Layout.build(robot.nv)
    robot.update(robot.neutral(), np.zeros(robot.nv))
    rows = TorqueLimits(scale=0.5).rows(robot, layout, 1e-3, 0.0)
    t0 = robot.h[robot.actuated]
    np.testing.assert_allclose(rows.upper, 0.5 * robot.tau_max - t0)
    np.testing.assert_allclose(rows.lower, -0.5 * robot.tau_max - t0)
    with pytest.raises(HQPError, match="TorqueLimits 'torque_limits': tau_max"):
        TorqueLimits(tau_max=-1.0)
    with pytest.raises(HQPError, match="scale"):
        TorqueLimits(scale=0.0)
    with pytest.raises(HQPError, match="3 entries"):
        TorqueLimits(tau_max=[1.0, 2.0, 3.0]).rows(robot, layout, 1e-3, 0.0)
    bad = Layout.build(robot.nv, [("c", "no_such_frame", ContactType.POINT)])
    with pytest.raises(InvalidFrame, match="FloatingBaseDynamics 'dynamics'.*universe"):
        FloatingBaseDynamics().rows(robot, bad, 1e-3, 0.0)
    with pytest.raises(HQPError, match="nv="):
        FloatingBaseDynamics().rows(robot, Layout.build(3), 1e-3, 0.0)
