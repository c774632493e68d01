"""Primitives over the contact wrenches: CoP, internal forces, hybrid force rows, effort."""

import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError, InvalidInput
from hqp.model import RobotModel
from hqp.model.layout import ContactType, Layout
from hqp.tasks.base import Category
from hqp.tasks.cop import CoPTask
from hqp.tasks.effort import EffortTask
from hqp.tasks.hybrid import HybridTask
from hqp.tasks.internal_forces import COMPONENTS, InternalForcesTask, internal_basis

LEFT, RIGHT = "lleg_effector_body", "rleg_effector_body"


@pytest.fixture(scope="module")
def robot() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


@pytest.fixture(scope="module")
def layout(robot: RobotModel) -> Layout:
    return Layout.build(
        robot.nv,
        [("left", LEFT, ContactType.SURFACE), ("right", RIGHT, ContactType.SURFACE)],
    )


def random_state(robot: RobotModel, rng: np.random.Generator) -> None:
    robot.update(robot.random_configuration(rng, margin=0.05), rng.normal(size=robot.nv))


def test_categories() -> None:
    assert CoPTask.category is Category.BALANCE
    assert InternalForcesTask.category is Category.OPERATIONAL
    assert HybridTask.category is Category.OPERATIONAL
    assert EffortTask.category is Category.POSTURE


def independent_cop(robot: RobotModel, layout: Layout, x: np.ndarray, h: float) -> np.ndarray:
    """Total wrench about the world origin with pinocchio forces, CoP by least squares."""
    total = pin.Force.Zero()
    for slot in layout.contacts:
        w = x[slot.slice]
        f = pin.Force(w[:3], w[3:])
        p = robot.frame_placement(slot.frame).translation
        total += pin.SE3(np.eye(3), p).act(f)  # moment about the origin
    F, tau = total.linear, total.angular
    # moment about c = (cx, cy, h): tau - c x F; its x, y parts vanish -> 2 linear equations.
    # (c x F)_x = cy Fz - h Fy, (c x F)_y = h Fx - cx Fz
    A = np.array([[0.0, F[2]], [-F[2], 0.0]])
    rhs = np.array([tau[0] + h * F[1], tau[1] - h * F[0]])
    return np.linalg.solve(A, rhs)


def test_cop_rows_match_an_independent_cop(robot: RobotModel, layout: Layout) -> None:
    rng = np.random.default_rng(0)
    task = CoPTask(robot)
    weight = robot.mass * np.linalg.norm(robot.gravity_vector)
    for _ in range(10):
        random_state(robot, rng)
        x = np.zeros(layout.n)
        x[: robot.nv] = rng.normal(size=robot.nv)
        for slot in layout.contacts:
            w = rng.normal(size=6) * [20, 20, 0, 5, 5, 5]
            w[2] = 300 * rng.uniform(0.2, 1.0)
            x[slot.slice] = w
        h = task.plane_height(robot, layout)
        c = independent_cop(robot, layout, x, h)
        np.testing.assert_allclose(task.measure(robot, layout, x), c, rtol=1e-10, atol=1e-12)
        goal = rng.normal(size=2)
        task.set_goal(goal)
        rows = task.rows(robot, layout, 1e-3, 0.0)
        Fz = sum(x[s.start + 2] for s in layout.contacts)
        # residual = F_z (goal - c) / (m g); zero on the qdd columns
        np.testing.assert_allclose(
            rows.A @ x - rows.b, Fz * (goal - c) / weight, rtol=1e-9, atol=1e-12
        )
        np.testing.assert_array_equal(rows.A[:, : robot.nv], 0.0)
        task.set_goal(c)
        rows = task.rows(robot, layout, 1e-3, 0.0)
        np.testing.assert_allclose(rows.A @ x - rows.b, 0.0, atol=1e-9)
        np.testing.assert_allclose(task.error(), 0.0, atol=1e-12)


def test_cop_of_a_single_point_contact_is_under_it(robot: RobotModel) -> None:
    lay = Layout.build(robot.nv, [("p", LEFT, ContactType.POINT)])
    robot.update(robot.neutral(), np.zeros(robot.nv))
    task = CoPTask(robot, ["p"], height=-2.0)
    x = np.zeros(lay.n)
    x[lay.contact("p").slice] = [10.0, -5.0, 100.0]
    p = robot.frame_placement(LEFT).translation
    # the force line through p meets z = -2 at p + (F/Fz)(-2 - p_z)
    expected = p[:2] + np.array([10.0, -5.0]) / 100.0 * (-2.0 - p[2])
    np.testing.assert_allclose(task.measure(robot, lay, x), expected, atol=1e-12)


def test_internal_basis_spans_the_null_space_of_the_grasp_map() -> None:
    rng = np.random.default_rng(1)
    for _ in range(10):
        p1, p2 = rng.normal(size=(2, 3))
        G = np.zeros((6, 12))
        for k, p in enumerate((p1, p2)):
            G[:3, 6 * k : 6 * k + 3] = np.eye(3)
            G[3:, 6 * k : 6 * k + 3] = pin.skew(p)
            G[3:, 6 * k + 3 : 6 * k + 6] = np.eye(3)
        B = internal_basis(p1, p2, True, "test")
        np.testing.assert_allclose(G @ B, 0.0, atol=1e-12)
        assert np.linalg.matrix_rank(B) == 6
        gram = B.T @ B
        np.testing.assert_allclose(gram - np.diag(np.diag(gram)), 0.0, atol=1e-12)  # orthogonal
        Bp = internal_basis(p1, p2, False, "test")
        np.testing.assert_allclose(G[:, [0, 1, 2, 6, 7, 8]] @ Bp, 0.0, atol=1e-12)


def test_internal_force_coordinates(robot: RobotModel, layout: Layout) -> None:
    rng = np.random.default_rng(2)
    random_state(robot, rng)
    full = InternalForcesTask(robot, ["left", "right"], COMPONENTS)
    K = full.coordinates(robot, layout)
    p1 = robot.frame_placement(LEFT).translation
    p2 = robot.frame_placement(RIGHT).translation
    B = internal_basis(p1, p2, True, "test")
    c = rng.normal(size=6)
    x = np.zeros(layout.n)
    x[layout.nv :] = B @ c
    np.testing.assert_allclose(K @ x, c, atol=1e-10)  # internal pair -> its coordinates
    # A pair that only carries a net wrench (in the range of G^T) has no internal part.
    G = np.zeros((6, 12))
    for k, p in enumerate((p1, p2)):
        G[:3, 6 * k : 6 * k + 3] = np.eye(3)
        G[3:, 6 * k : 6 * k + 3] = pin.skew(p)
        G[3:, 6 * k + 3 : 6 * k + 6] = np.eye(3)
    x[layout.nv :] = G.T @ rng.normal(size=6)
    np.testing.assert_allclose(K @ x, 0.0, atol=1e-10)
    # Default selection leaves out shear_vertical; goal zero by default.
    task = InternalForcesTask(robot, ["left", "right"])
    rows = task.rows(robot, layout, 1e-3, 0.0)
    assert rows.A.shape == (5, layout.n)
    assert task.components(layout) == tuple(c for c in COMPONENTS if c != "shear_vertical")
    np.testing.assert_array_equal(rows.b, np.zeros(5))
    np.testing.assert_array_equal(rows.A[:, : robot.nv], 0.0)
    task.set_goal([10.0, 0, 0, 0, 0])
    assert task.rows(robot, layout, 1e-3, 0.0).b[0] == 10.0
    # Tension: the contact forces push the feet apart along the line.
    x = np.zeros(layout.n)
    d = (p2 - p1) / np.linalg.norm(p2 - p1)
    x[layout.contact("left").start : layout.contact("left").start + 3] = -7.0 * d
    x[layout.contact("right").start : layout.contact("right").start + 3] = 7.0 * d
    np.testing.assert_allclose(task.measure(robot, layout, x), [7.0, 0, 0, 0, 0], atol=1e-10)


def test_hybrid_force_rows(robot: RobotModel, layout: Layout) -> None:
    rng = np.random.default_rng(3)
    random_state(robot, rng)
    task = HybridTask(robot, RIGHT, "right", force_axes=("fz", "tx", "ty"))
    task.set_goal(robot.frame_placement(RIGHT))
    task.set_force([200.0, 1.0, -2.0])
    rows = task.rows(robot, layout, 1e-3, 0.0)
    # motion: x, y translation and z rotation; then 3 force rows
    assert rows.A.shape == (6, layout.n)
    slot = layout.contact("right")
    F = rows.A[3:]
    np.testing.assert_array_equal(F[:, : slot.start], 0.0)
    np.testing.assert_array_equal(F[:, slot.slice], np.eye(6)[[2, 3, 4]])
    np.testing.assert_array_equal(rows.b[3:], [200.0, 1.0, -2.0])
    np.testing.assert_array_equal(rows.A[:3, robot.nv :], 0.0)
    kin = task.kinematics(robot, 0.0)
    J = robot.frame_jacobian(RIGHT)
    np.testing.assert_allclose(kin.jacobian[:2], J[:2])
    # At the goal the world rotation rows are the frame's angular velocity rows.
    np.testing.assert_allclose(kin.jacobian[2], J[5], atol=1e-12)
    # Point contact: no torque axes, no rotation rows.
    lay = Layout.build(robot.nv, [("right", RIGHT, ContactType.POINT)])
    point = HybridTask(robot, RIGHT, "right", force_axes=("fz",))
    point.set_goal(robot.frame_placement(RIGHT))
    assert point.rows(robot, lay, 1e-3, 0.0).A.shape == (3, lay.n)
    with pytest.raises(InvalidInput, match="point contact"):
        task.rows(robot, lay, 1e-3, 0.0)
    with pytest.raises(InvalidInput, match="is on frame"):
        HybridTask(robot, LEFT, "right").rows(robot, layout, 1e-3, 0.0)


def test_effort_rows_are_the_torques(robot: RobotModel, layout: Layout) -> None:
    """W (T x + t0) equals W tau with tau = rnea(q, v, qdd) - J_c^T f, computed independently."""
    rng = np.random.default_rng(4)
    for normalize in (False, True):
        task = EffortTask(robot, normalize=normalize)
        for _ in range(5):
            q = robot.random_configuration(rng, margin=0.05)
            v = rng.normal(size=robot.nv)
            robot.update(q, v)
            x = rng.normal(size=layout.n)
            rows = task.rows(robot, layout, 1e-3, 0.0)
            data = robot.model.createData()
            tau = pin.rnea(robot.model, data, q, v, x[: robot.nv]).copy()
            pin.computeJointJacobians(robot.model, data, q)
            pin.updateFramePlacements(robot.model, data)
            for slot in layout.contacts:
                fid = robot.model.getFrameId(slot.frame)
                Jc = pin.getFrameJacobian(robot.model, data, fid, pin.LOCAL_WORLD_ALIGNED)
                tau -= Jc.T @ x[slot.slice]
            lim = robot.tau_max
            ok = np.isfinite(lim) & (lim > 0)
            W = np.where(ok, 1.0 / np.where(ok, lim, 1.0), 1.0) if normalize else np.ones(robot.na)
            np.testing.assert_allclose(
                rows.A @ x - rows.b, W * tau[robot.actuated], rtol=1e-9, atol=1e-8
            )


def test_force_primitives_bad_input(robot: RobotModel, layout: Layout) -> None:
    robot.update(robot.neutral(), np.zeros(robot.nv))
    with pytest.raises(InvalidInput, match="CoPTask 'cop': goal not set"):
        CoPTask(robot).rows(robot, layout, 1e-3, 0.0)
    with pytest.raises(InvalidInput, match="CoPTask 'cop'.*unknown contact 'nope'"):
        t = CoPTask(robot, ["nope"])
        t.set_goal([0.0, 0.0])
        t.rows(robot, layout, 1e-3, 0.0)
    with pytest.raises(InvalidInput, match="CoPTask 'cop': goal.*NaN"):
        CoPTask(robot).set_goal([np.nan, 0.0])
    with pytest.raises(InvalidInput, match="two distinct"):
        InternalForcesTask(robot, ["left"])
    with pytest.raises(InvalidInput, match="components"):
        InternalForcesTask(robot, ["left", "right"], ["squeeze"])
    mixed = Layout.build(
        robot.nv, [("left", LEFT, ContactType.SURFACE), ("right", RIGHT, ContactType.POINT)]
    )
    with pytest.raises(InvalidInput, match="same kind"):
        InternalForcesTask(robot, ["left", "right"]).rows(robot, mixed, 1e-3, 0.0)
    with pytest.raises(InvalidInput, match="goal has 2 entries"):
        t = InternalForcesTask(robot, ["left", "right"])
        t.set_goal([0.0, 1.0])
        t.rows(robot, layout, 1e-3, 0.0)
    with pytest.raises(InvalidInput, match="HybridTask 'hybrid_.*force_axes"):
        HybridTask(robot, RIGHT, "right", force_axes=("fw",))
    with pytest.raises(HQPError, match="HybridTask 'hybrid_.*force"):
        HybridTask(robot, RIGHT, "right").set_force([1.0, 2.0])


def test_force_regularization_rows_are_the_wrenches_over_the_weight(
    robot: RobotModel, layout: Layout
) -> None:
    from hqp.tasks.effort import ForceRegularization

    task = ForceRegularization(robot, weight=50.0)
    assert task.category is Category.POSTURE and task.weight == 50.0
    rows = task.rows(robot, layout, 1e-3, 0.0)
    rng = np.random.default_rng(3)
    x = rng.normal(size=layout.n)
    mg = robot.mass * 9.81
    f = np.concatenate([x[layout.contact(c).start:layout.contact(c).start + 6]
                        for c in ("left", "right")])
    np.testing.assert_allclose(rows.A @ x - rows.b, f / mg, rtol=1e-3, atol=1e-15)
    assert not rows.A[:, : robot.nv].any()
    # the lexicographic optimum with it below a net-force row shares the load evenly
    from hqp.solver import Level, solve

    G = np.zeros((6, layout.n))
    for c in ("left", "right"):
        G[:, layout.contact(c).start:layout.contact(c).start + 6] = np.eye(6)
    w = np.array([0.0, 0.0, mg, 0.0, 0.0, 0.0])
    sol = solve([Level(A=G, b=w), Level(A=rows.A, b=rows.b)], backend="quadprog")
    left = sol.x[layout.contact("left").start:layout.contact("left").start + 6]
    np.testing.assert_allclose(left, 0.5 * w, atol=1e-6)
