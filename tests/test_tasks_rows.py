"""Rows of the motion primitives: zero at the goal, and the goal reached in closed loop."""

import numpy as np
import pinocchio as pin
import pytest

from hqp.model import RobotModel
from hqp.model.layout import ContactType, Layout
from hqp.tasks.base import Category
from hqp.tasks.centroidal import CentroidalMomentumTask
from hqp.tasks.com import CoMTask, support_center
from hqp.tasks.gaze import GazeTask
from hqp.tasks.orientation import OrientationTask
from hqp.tasks.pose import PoseTask
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask

HAND, HEAD = "rarm_wrist2_joint", "head2_joint"


@pytest.fixture(scope="module")
def robot() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


@pytest.fixture(scope="module")
def layout(robot: RobotModel) -> Layout:
    return Layout.build(
        robot.nv,
        [
            ("left", "lleg_effector_body", ContactType.SURFACE),
            ("right", "rleg_effector_body", ContactType.SURFACE),
        ],
    )


def start_and_goal_configurations(robot: RobotModel, seed: int):
    rng = np.random.default_rng(seed)
    q0 = robot.neutral()
    q0[robot.actuated_q] = 0.5 * (robot.q_lower + robot.q_upper) + rng.uniform(-0.2, 0.2, robot.na)
    q1 = q0.copy()
    q1[robot.actuated_q] += rng.uniform(-0.3, 0.3, robot.na)
    q1[robot.actuated_q] = np.clip(q1[robot.actuated_q], robot.q_lower, robot.q_upper)
    return q0, q1


def goal_tasks(robot: RobotModel, q1: np.ndarray):
    """Tasks whose goals are their values at q1 (so they are reachable)."""
    robot.update(q1, np.zeros(robot.nv))
    M = robot.frame_placement(HAND)
    head = robot.frame_placement(HEAD)
    out = []
    t = CoMTask(robot, kp=50.0)
    t.set_goal(robot.com)
    out.append(t)
    t = CoMTask(robot, horizontal=True, kp=50.0)
    t.set_goal(robot.com[:2])
    out.append(t)
    t = PositionTask(robot, HAND, kp=50.0)
    t.set_goal(M.translation)
    out.append(t)
    t = OrientationTask(robot, HAND, kp=50.0)
    t.set_goal(M.rotation)
    out.append(t)
    t = PoseTask(robot, HAND, kp=50.0)
    t.set_goal(M)
    out.append(t)
    t = GazeTask(robot, HEAD, kp=50.0)
    t.set_goal(head.translation + 2.0 * head.rotation @ t.axis)
    out.append(t)
    t = PostureTask(robot, kp=50.0)
    t.set_configuration(q1, robot)
    out.append(t)
    return out


def test_default_categories(robot: RobotModel) -> None:
    assert CoMTask.category is Category.BALANCE
    assert CentroidalMomentumTask.category is Category.BALANCE
    for cls in (PositionTask, OrientationTask, PoseTask, GazeTask):
        assert cls.category is Category.OPERATIONAL
    assert PostureTask.category is Category.POSTURE


def test_zero_error_and_zero_reference_at_goal(robot: RobotModel, layout: Layout) -> None:
    _, q1 = start_and_goal_configurations(robot, 0)
    for task in goal_tasks(robot, q1):
        robot.update(q1, np.zeros(robot.nv))
        rows = task.rows(robot, layout, 1e-3, 0.0)
        m = rows.A.shape[0]
        np.testing.assert_allclose(task.error(), 0.0, atol=1e-9, err_msg=task.where())
        np.testing.assert_allclose(
            task.reference_acceleration(), 0.0, atol=1e-8, err_msg=task.where()
        )
        # At rest the drift vanishes too, so the target is zero.
        np.testing.assert_allclose(rows.b, 0.0, atol=1e-8, err_msg=task.where())
        np.testing.assert_array_equal(rows.A[:, robot.nv :], np.zeros((m, layout.n - robot.nv)))
        kin = task.kinematics(robot, 0.0)
        np.testing.assert_array_equal(rows.A[:, : robot.nv], kin.jacobian)


def test_goals_reached_in_closed_loop(robot: RobotModel, layout: Layout) -> None:
    """Integrate qdd = pinv(J) b: each task alone drives its error to zero (signs are right)."""
    q0, q1 = start_and_goal_configurations(robot, 1)
    dt = 1e-2
    for task in goal_tasks(robot, q1):
        task.set_gains(kp=100.0)
        q, v = q0.copy(), np.zeros(robot.nv)
        robot.update(q, v)
        task.rows(robot, layout, dt, 0.0)
        e0 = np.linalg.norm(task.error())
        assert e0 > 1e-3, task.where()
        for k in range(150):
            rows = task.rows(robot, layout, dt, k * dt)
            qdd = np.linalg.lstsq(rows.A[:, : robot.nv], rows.b, rcond=None)[0]
            v = v + dt * qdd
            q = robot.integrate(q, dt * v)
            robot.update(q, v)
        task.rows(robot, layout, dt, 1.5)
        assert np.linalg.norm(task.error()) < 1e-3 * e0, task.where()


def test_error_sign_is_goal_minus_current(robot: RobotModel, layout: Layout) -> None:
    q0, _ = start_and_goal_configurations(robot, 2)
    robot.update(q0, np.zeros(robot.nv))
    task = PositionTask(robot, HAND)
    goal = robot.frame_placement(HAND).translation + np.array([0.1, -0.2, 0.05])
    task.set_goal(goal)
    task.rows(robot, layout, 1e-3, 0.0)
    np.testing.assert_allclose(task.error(), [0.1, -0.2, 0.05], atol=1e-12)
    np.testing.assert_allclose(task.reference_acceleration(), task.reference.kp * task.error())


def test_centroidal_rows_damp_momentum(robot: RobotModel, layout: Layout) -> None:
    rng = np.random.default_rng(3)
    q0, _ = start_and_goal_configurations(robot, 3)
    v = rng.normal(size=robot.nv)
    robot.update(q0, v)
    task = CentroidalMomentumTask(robot, "angular", gain=5.0)
    rows = task.rows(robot, layout, 1e-3, 0.0)
    k = robot.centroidal_matrix[3:] @ v
    np.testing.assert_allclose(task.error(), -k)
    np.testing.assert_allclose(rows.b, -5.0 * k - robot.centroidal_drift[3:], atol=1e-9)
    np.testing.assert_allclose(rows.A[:, : robot.nv], robot.centroidal_matrix[3:])
    sat = CentroidalMomentumTask(robot, "all", gain=5.0, max_rate=1.0)
    rows = sat.rows(robot, layout, 1e-3, 0.0)
    np.testing.assert_allclose(np.linalg.norm(rows.b + robot.centroidal_drift), 1.0)


def test_support_center(robot: RobotModel) -> None:
    robot.update(robot.neutral(), np.zeros(robot.nv))
    c = support_center(robot, ["lleg_effector_body", "rleg_effector_body"])
    expected = 0.5 * (
        robot.frame_placement("lleg_effector_body").translation
        + robot.frame_placement("rleg_effector_body").translation
    )
    np.testing.assert_allclose(c, expected)


def test_move_to_starts_at_current_value(robot: RobotModel, layout: Layout) -> None:
    q0, q1 = start_and_goal_configurations(robot, 4)
    robot.update(q0, np.zeros(robot.nv))
    for task in goal_tasks(robot, q1):
        robot.update(q0, np.zeros(robot.nv))
        goal = task.goal_at(0.0).position
        task.move_to(robot, goal, 1.0, 0.5)
        task.rows(robot, layout, 1e-3, 0.5)
        np.testing.assert_allclose(task.error(), 0.0, atol=1e-9, err_msg=task.where())
        np.testing.assert_allclose(task.goal_at(1.5).position, goal, atol=1e-12)


def test_task_feedforward_tracks_without_lag(robot: RobotModel, layout: Layout) -> None:
    """A hand following a minimum-jerk trajectory stays on it (feedforward), a plain PD lags."""
    q0, _ = start_and_goal_configurations(robot, 5)
    dt = 1e-2
    lags = {}
    for feedforward in (True, False):
        robot.update(q0, np.zeros(robot.nv))
        task = PositionTask(robot, HAND, kp=100.0)
        start = robot.frame_placement(HAND).translation.copy()
        goal = start + np.array([0.15, -0.1, 0.1])
        task.move_to(robot, goal, 1.0, 0.0)
        traj = task.trajectory
        q, v = q0.copy(), np.zeros(robot.nv)
        worst = 0.0
        for k in range(100):
            t = k * dt
            if not feedforward:
                task.set_goal(traj.sample(t).position)  # same goal, no velocity/acceleration
            rows = task.rows(robot, layout, dt, t)
            worst = max(worst, float(np.linalg.norm(task.error())))
            qdd = np.linalg.lstsq(rows.A[:, : robot.nv], rows.b, rcond=None)[0]
            v = v + dt * qdd
            q = robot.integrate(q, dt * v)
            robot.update(q, v)
        lags[feedforward] = worst
    travel = float(np.linalg.norm([0.15, -0.1, 0.1]))
    assert lags[True] < 0.01 * travel  # Euler discretisation only
    assert lags[False] > 5 * lags[True]
