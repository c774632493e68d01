"""Contact rows: motion constraint against finite differences, the wrench cone at its edges."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import linprog

from hqp import HQPError, InvalidFrame, InvalidGain
from hqp.model import RobotModel
from hqp.model.layout import ContactType, Layout
from hqp.tasks.base import Category
from hqp.tasks.contact import Contact, ContactLimits, wrench_cone_local

MU, X, Y = 0.8, 0.11, 0.06
M = MU / math.sqrt(2.0)


@pytest.fixture(scope="module")
def robot() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


def contacts() -> list[Contact]:
    return [
        Contact("foot", "rleg_effector_body", mu=MU, half_length=X, half_width=Y),
        Contact("hand", "rarm_effector_body", ContactType.POINT, mu=MU),
    ]


def make_layout(robot: RobotModel, cs: list[Contact]) -> Layout:
    return Layout.build(robot.nv, [c.layout_entry() for c in cs])


FEET = {
    "sample": ("rleg_effector_body", "rarm_effector_body"),
    "paper-humanoid": ("left_foot", "right_hand"),
    "g1": ("left_foot", "right_hand"),
    "talos": ("left_foot", "right_hand"),
}


@pytest.mark.parametrize("name", sorted(FEET))
def test_motion_rows_predict_finite_difference_acceleration(name: str) -> None:
    if name == "sample":
        robot = RobotModel(pin.buildSampleModelHumanoid(), name="sample")
    else:
        from hqp.robots import load

        robot = load(name).model()
    rng = np.random.default_rng(5)
    foot, hand = FEET[name]
    cs = [
        Contact("foot", foot, mu=MU, half_length=X, half_width=Y),
        Contact("hand", hand, ContactType.POINT, mu=MU),
    ]
    layout = make_layout(robot, cs)
    other = RobotModel(robot.model, name="fd")
    eps = 1e-6
    for _ in range(10):
        q = robot.random_configuration(rng)
        v = rng.normal(size=robot.nv)
        qdd = rng.normal(size=robot.nv)
        robot.update(q, v)
        x = np.concatenate([qdd, rng.normal(size=layout.n - layout.nv)])
        for c in cs:
            rows = c.rows(robot, layout, 1e-3, 0.0)
            assert rows.A.shape == (c.size, layout.n)
            predicted = rows.A @ x - rows.b  # classical acceleration of the frame (gains zero)

            def vel(s: float, c: Contact = c, q=q, v=v, qdd=qdd) -> np.ndarray:
                other.update(other.integrate(q, s * v + 0.5 * s * s * qdd), v + s * qdd)
                return other.frame_velocity(c.frame)[: c.size]

            fd = (vel(eps) - vel(-eps)) / (2 * eps)
            np.testing.assert_allclose(predicted, fd, atol=1e-5 * (1 + np.abs(fd).max()))


def test_stabilisation_gains(robot: RobotModel) -> None:
    rng = np.random.default_rng(6)
    c = Contact("foot", "rleg_effector_body", kp=100.0, kd=20.0)
    layout = make_layout(robot, [c])
    q = robot.random_configuration(rng)
    v = rng.normal(size=robot.nv)
    robot.update(q, v)
    T = robot.frame_placement(c.frame)
    offset = pin.SE3(pin.exp3(np.array([0.01, -0.02, 0.03])), np.array([0.02, 0.0, -0.01]))
    c.activate(T * offset)  # reference displaced in the frame
    rows = c.rows(robot, layout, 1e-3, 0.0)
    ref = c.reference
    e = np.concatenate([T.translation - ref.translation, pin.log3(T.rotation @ ref.rotation.T)])
    qdd = rng.normal(size=robot.nv)
    x = np.concatenate([qdd, np.zeros(6)])
    acc = robot.frame_jacobian(c.frame) @ qdd + robot.frame_drift(c.frame)
    vel = robot.frame_velocity(c.frame)
    tol = 1e-9 * (1 + np.abs(acc).max())
    np.testing.assert_allclose(rows.A @ x - rows.b, acc + 100.0 * e + 20.0 * vel, atol=tol)
    np.testing.assert_allclose(c.error(), -e)
    # Without a given reference, the placement at the first rows() is captured: e = 0.
    c.activate()
    rows = c.rows(robot, layout, 1e-3, 0.0)
    np.testing.assert_allclose(rows.A @ x - rows.b, acc + 20.0 * vel, atol=tol)


def test_inactive_contact_holds_its_slot_at_zero(robot: RobotModel) -> None:
    cs = contacts()
    layout = make_layout(robot, cs)
    robot.update(robot.neutral(), np.zeros(robot.nv))
    for c in cs:
        c.deactivate()
        rows = c.rows(robot, layout, 1e-3, 0.0)
        slot = layout.contact(c.name)
        expected = np.zeros((c.size, layout.n))
        expected[:, slot.slice] = np.eye(c.size)
        np.testing.assert_array_equal(rows.A, expected)
        np.testing.assert_array_equal(rows.b, np.zeros(c.size))
        limits = ContactLimits(c).rows(robot, layout, 1e-3, 0.0)
        assert np.all(np.isinf(limits.lower)) and np.all(np.isinf(limits.upper))
        c.activate()
        assert c.rows(robot, layout, 1e-3, 0.0).A[:, : layout.nv].any()


def _feasible(rows, x: np.ndarray, tol: float = 1e-9) -> bool:
    Cx = rows.C @ x
    return bool(np.all(Cx >= rows.lower - tol) and np.all(Cx <= rows.upper + tol))


def _world(c: Contact, robot: RobotModel, layout: Layout, local: np.ndarray) -> np.ndarray:
    R = robot.frame_placement(c.frame).rotation
    x = layout.zeros()
    f = R @ local[:3] if c.size == 3 else np.concatenate([R @ local[:3], R @ local[3:]])
    x[layout.contact(c.name).slice] = f
    return x


def test_friction_pyramid_cop_and_yaw_at_their_edges(robot: RobotModel) -> None:
    rng = np.random.default_rng(7)
    cs = contacts()
    layout = make_layout(robot, cs)
    for _ in range(10):
        robot.update(robot.random_configuration(rng), np.zeros(robot.nv))  # random sole rotation
        for c in cs:
            limits = ContactLimits(c)
            assert limits.category is Category.CONTACT_LIMITS
            rows = limits.rows(robot, layout, 1e-3, 0.0)
            assert rows.n_in == (17 if c.size == 6 else 5)
            fz = rng.uniform(10.0, 500.0)
            pad = [0.0] * (c.size - 3)
            edges = [[M, 0, 1], [-M, 0, 1], [0, M, 1], [0, -M, 1], [M, M, 1], [-M, M, 1]]
            for e in edges:
                on = fz * np.array(e + pad, dtype=float)
                assert _feasible(rows, _world(c, robot, layout, on), 1e-9 * fz)
                out = on.copy()
                out[:2] *= 1.001
                assert not _feasible(rows, _world(c, robot, layout, out), 1e-9 * fz)
            # Pyramid corner on the friction cone: tangential norm = mu fz.
            np.testing.assert_allclose(np.hypot(M, M), MU)
            assert not _feasible(rows, _world(c, robot, layout, fz * np.array([0, 0, -1e-3] + pad)))
            if c.size == 3:
                continue
            torques = [[Y, 0, 0], [-Y, 0, 0], [0, X, 0], [0, -X, 0],
                       [0, 0, M * (X + Y)], [0, 0, -M * (X + Y)]]
            for tq in torques:
                on = fz * np.array([0, 0, 1] + tq, dtype=float)
                assert _feasible(rows, _world(c, robot, layout, on), 1e-9 * fz)
                out = on.copy()
                out[3:] *= 1.001
                assert not _feasible(rows, _world(c, robot, layout, out), 1e-9 * fz)
            local = c.local_wrench(robot, layout, _world(c, robot, layout, on))
            np.testing.assert_allclose(local, on, atol=1e-12 * fz)


def test_surface_rows_are_the_full_contact_wrench_cone() -> None:
    """Rows satisfied <=> the wrench is generated by four corner forces in the pyramid (LP)."""
    G = wrench_cone_local(ContactType.SURFACE, MU, X, Y)
    W = np.zeros((6, 12))
    for i, (x, y) in enumerate([(X, Y), (X, -Y), (-X, Y), (-X, -Y)]):
        W[:3, 3 * i : 3 * i + 3] = np.eye(3)
        W[3:, 3 * i : 3 * i + 3] = pin.skew(np.array([x, y, 0.0]))
    P = np.array([[1, 0, -M], [-1, 0, -M], [0, 1, -M], [0, -1, -M], [0, 0, -1.0]])
    A_ub = np.kron(np.eye(4), P)
    rng = np.random.default_rng(8)
    inside = 0
    for _ in range(150):
        w = rng.normal(size=6) * np.array([0.3, 0.3, 0.0, 0.04, 0.06, 0.03])
        w[2] = 1.0
        res = linprog(np.zeros(12), A_ub=A_ub, b_ub=np.zeros(20), A_eq=W, b_eq=w,
                      bounds=[(None, None)] * 12, method="highs")
        in_rows = bool(np.all(G @ w <= 1e-9))
        inside += in_rows
        assert in_rows == (res.status == 0)
    assert 25 < inside < 125  # both outcomes sampled


def test_normal_force_bounds(robot: RobotModel) -> None:
    c = Contact("foot", "rleg_effector_body", f_min=5.0, f_max=400.0)
    layout = make_layout(robot, [c])
    robot.update(robot.neutral(), np.zeros(robot.nv))
    rows = c.limit_rows(robot, layout)
    for fz, ok in ((5.0, True), (4.99, False), (400.0, True), (400.01, False)):
        assert _feasible(rows, _world(c, robot, layout, np.array([0, 0, fz, 0, 0, 0.0]))) == ok
    c.max_normal_force = 50.0  # the controller's unloading ramp
    rows = c.limit_rows(robot, layout)
    assert not _feasible(rows, _world(c, robot, layout, np.array([0, 0, 60.0, 0, 0, 0])))


def test_contact_errors(robot: RobotModel) -> None:
    with pytest.raises(InvalidFrame, match="Contact 'foot': unknown frame 'nope'.*universe"):
        Contact("foot", "nope", model=robot)
    c = Contact("foot", "nope")
    layout = Layout.build(robot.nv, [c.layout_entry()])
    with pytest.raises(InvalidFrame, match="Contact 'foot'"):
        c.rows(robot, layout, 1e-3, 0.0)
    with pytest.raises(InvalidFrame, match="Contact 'foot'"):
        c.limit_rows(robot, layout)
    for kwargs in ({"mu": -0.1}, {"half_length": -0.1}, {"half_width": -1.0}, {"f_min": -1.0},
                   {"kp": -1.0}, {"kd": float("nan")}, {"f_min": 10.0, "f_max": 5.0}):
        with pytest.raises(InvalidGain, match="Contact 'foot'"):
            Contact("foot", "rleg_effector_body", **kwargs)
    good = Contact("foot", "rleg_effector_body")
    with pytest.raises(HQPError, match="Contact 'foot'.*declared contacts"):
        good.rows(robot, Layout.build(robot.nv), 1e-3, 0.0)
    wrong_kind = Layout.build(robot.nv, [("foot", "rleg_effector_body", ContactType.POINT)])
    with pytest.raises(HQPError, match="Contact 'foot': layout slot"):
        good.rows(robot, wrong_kind, 1e-3, 0.0)
