"""Fast paths of the control primitives equal the plain computations they replace."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError
from hqp.model import RobotModel
from hqp.model.geometry import cross3
from hqp.model.layout import ContactType, Layout
from hqp.tasks.base import Rows
from hqp.tasks.contact import Contact, wrench_cone_local
from hqp.tasks.dynamics import FloatingBaseDynamics, generalized_contact_matrix, torque_map
from hqp.tasks.orientation import jlog3_rate, jlog3_rate_times
from hqp.tasks.posture import PostureTask
from hqp.tasks.reference import PDReference


@pytest.fixture(scope="module")
def robot() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


def test_cross3_is_np_cross_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    for _ in range(2000):
        a = rng.normal(size=3) * 10.0 ** rng.uniform(-6, 6)
        b = rng.normal(size=3) * 10.0 ** rng.uniform(-6, 6)
        np.testing.assert_array_equal(cross3(a, b), np.cross(a, b))
    np.testing.assert_array_equal(cross3([0.0, 0.0, 1.0], [1.0, 2.0, 3.0]), [-2.0, 1.0, 0.0])


@pytest.mark.parametrize("scale", [0.0, 1e-4, 5e-3, 0.3, 2.5])
def test_jlog3_rate_times_matches_the_matrix(scale: float) -> None:
    """Both branches of the series (theta below and above 1e-2), and exactly at zero."""
    rng = np.random.default_rng(1)
    for _ in range(50):
        e = rng.normal(size=3)
        e *= scale / max(np.linalg.norm(e), 1e-300)
        de, xi = rng.normal(size=3), rng.normal(size=3)
        ref = jlog3_rate(e, de) @ xi
        np.testing.assert_allclose(jlog3_rate_times(e, de, xi), ref, rtol=0,
                                   atol=1e-13 * max(1.0, np.abs(ref).max()))


def test_pd_feedback_saturations_unchanged() -> None:
    """The norm is skipped only without saturation; with one, the law of eq. 27-28 holds."""
    rng = np.random.default_rng(2)
    for vmax, amax in ((math.inf, math.inf), (0.1, math.inf), (math.inf, 0.5), (0.2, 0.3)):
        ref = PDReference(50.0, None, vmax, amax)
        for _ in range(20):
            e, r = rng.normal(size=3), rng.normal(size=3)
            kp, kv = ref.kp, ref.kv
            v_des = -(kp / kv) * e
            n = float(np.linalg.norm(v_des))
            if n > vmax:
                v_des = v_des * (vmax / n)
            a = -kv * (r - v_des)
            n = float(np.linalg.norm(a))
            if n > amax:
                a = a * (amax / n)
            np.testing.assert_array_equal(ref.feedback(e, r), a)


def test_rows_stack_is_vstack() -> None:
    rng = np.random.default_rng(3)
    n = 5
    parts = [
        Rows(A=rng.normal(size=(2, n)), b=rng.normal(size=2)),
        Rows(C=rng.normal(size=(3, n)), lower=rng.normal(size=3), upper=None),
        Rows(A=rng.normal(size=(1, n)), b=rng.normal(size=1), C=rng.normal(size=(1, n)),
             lower=None, upper=np.ones(1)),
        Rows(),
    ]
    out = Rows.stack(parts, n)
    np.testing.assert_array_equal(out.A, np.vstack([parts[0].A, parts[2].A]))
    np.testing.assert_array_equal(out.b, np.concatenate([parts[0].b, parts[2].b]))
    np.testing.assert_array_equal(out.C, np.vstack([parts[1].C, parts[2].C]))
    np.testing.assert_array_equal(out.lower, [*parts[1].lower, -np.inf])
    np.testing.assert_array_equal(out.upper, [np.inf, np.inf, np.inf, 1.0])
    assert out.A is not parts[0].A
    with pytest.raises(HQPError, match="columns"):
        Rows.stack([parts[0], Rows(A=np.zeros((1, n + 1)), b=np.zeros(1))], n)


def _layout(robot: RobotModel, cs: list[Contact]) -> Layout:
    return Layout.build(robot.nv, [c.layout_entry() for c in cs])


def test_dynamics_and_torque_map_columns(robot: RobotModel) -> None:
    """``[M | -J_c^T]`` rows built in place equal the generalized contact matrix's."""
    cs = [Contact("foot", "rleg_effector_body"),
          Contact("hand", "rarm_effector_body", ContactType.POINT)]
    layout = _layout(robot, cs)
    rng = np.random.default_rng(4)
    robot.update(robot.random_configuration(rng), rng.normal(size=robot.nv))
    JT = generalized_contact_matrix(robot, layout)
    T, t0 = torque_map(robot, layout)
    np.testing.assert_array_equal(T, np.hstack([robot.M, -JT])[robot.actuated])
    np.testing.assert_array_equal(t0, robot.h[robot.actuated])
    rows = FloatingBaseDynamics().rows(robot, layout, 1e-3, 0.0)
    np.testing.assert_array_equal(rows.A, np.hstack([robot.M, -JT])[:6])
    np.testing.assert_array_equal(rows.b, -robot.h[:6])


def test_contact_limit_rows_follow_changed_parameters(robot: RobotModel) -> None:
    """The local cone is cached per (mu, sole); a change of either rebuilds it."""
    c = Contact("foot", "rleg_effector_body", mu=0.8, half_length=0.1, half_width=0.05)
    layout = _layout(robot, [c])
    rng = np.random.default_rng(5)
    robot.update(robot.random_configuration(rng), np.zeros(robot.nv))
    R = robot.frame_placement(c.frame).rotation
    rot = np.kron(np.eye(2), R.T)
    for mu, X in ((0.8, 0.1), (0.5, 0.1), (0.5, 0.2)):
        c.mu, c.half_length = mu, X
        G = wrench_cone_local(ContactType.SURFACE, mu, X, 0.05)
        local = np.vstack([G[:4], [[0, 0, 1.0, 0, 0, 0]], G[4:]])
        rows = c.limit_rows(robot, layout)
        np.testing.assert_allclose(rows.C[:, layout.nv:], local @ rot, rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="read-only"):
        c.local_limits()[0, 0] = 1.0
    # A layout whose slot has another frame is still refused after the cache was filled.
    other = Layout.build(robot.nv, [("foot", "lleg_effector_body", ContactType.SURFACE)])
    with pytest.raises(HQPError, match="layout slot"):
        c.limit_rows(robot, other)


def test_posture_jacobian_shared_and_read_only(robot: RobotModel) -> None:
    task = PostureTask(robot, list(robot.joint_names[:4]), kp=10.0)
    task.set_goal(np.zeros(4))
    _, _, J, drift = task.measure(robot)
    expected = np.zeros((4, robot.nv))
    expected[np.arange(4), robot.nv_base + np.arange(4)] = 1.0
    np.testing.assert_array_equal(J, expected)
    np.testing.assert_array_equal(drift, np.zeros(4))
    with pytest.raises(ValueError, match="read-only"):
        J[0, 0] = 2.0


def test_contact_dynamics_shared_per_update_results_independent(robot: RobotModel) -> None:
    """One ``[M | -J_c^T]`` per update and layout; the rows handed out are writeable copies."""
    from hqp.tasks.dynamics import contact_dynamics_matrix, joint_torques

    cs = [Contact("foot", "rleg_effector_body")]
    layout = _layout(robot, cs)
    rng = np.random.default_rng(6)
    robot.update(robot.random_configuration(rng), rng.normal(size=robot.nv))
    G = contact_dynamics_matrix(robot, layout)
    assert contact_dynamics_matrix(robot, layout) is G and not G.flags.writeable
    T, _ = torque_map(robot, layout)
    T[:] = 0.0  # a caller's copy: the shared matrix is untouched
    assert np.abs(contact_dynamics_matrix(robot, layout)).max() > 0.0
    x = rng.normal(size=layout.n)
    J = robot.frame_jacobian("rleg_effector_body")
    tau = robot.M @ x[: robot.nv] + robot.h - J.T @ x[robot.nv:]
    np.testing.assert_allclose(joint_torques(robot, layout, x), tau[robot.actuated], rtol=0,
                               atol=1e-12 * max(1.0, np.abs(tau).max()))
    robot.update(robot.random_configuration(rng), rng.normal(size=robot.nv))
    assert contact_dynamics_matrix(robot, layout) is not G


def test_contact_dynamics_with_slots_out_of_order(robot: RobotModel) -> None:
    """A hand-made layout whose slots are not back to back is filled slot by slot."""
    from hqp.model.layout import ContactSlot

    nv = robot.nv
    layout = Layout(nv, (ContactSlot("b", "rarm_effector_body", ContactType.POINT, nv + 6),
                         ContactSlot("a", "rleg_effector_body", ContactType.SURFACE, nv)))
    rng = np.random.default_rng(8)
    robot.update(robot.random_configuration(rng), rng.normal(size=robot.nv))
    T, _ = torque_map(robot, layout)
    Ja = robot.frame_jacobian("rleg_effector_body")
    Jb = robot.frame_jacobian("rarm_effector_body")[:3]
    np.testing.assert_array_equal(T, np.hstack([robot.M, -Ja.T, -Jb.T])[robot.actuated])
    np.testing.assert_array_equal(
        generalized_contact_matrix(robot, layout), np.hstack([Ja.T, Jb.T]))
