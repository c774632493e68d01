"""Jacobians and drift terms of the motion primitives against finite differences (pin.integrate).

Every task is checked at 10 random configurations and velocities with a
moving goal (so the feedforward terms in the drift are checked too): the
error's time derivative along ``q(s) = q (+) (s v + s^2/2 qdd)`` must match
the reported rate, the rate's must match ``J qdd + drift``.
"""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from task_fd import check_kinematics

from hqp.model import RobotModel
from hqp.tasks.centroidal import CentroidalMomentumTask
from hqp.tasks.com import CoMTask
from hqp.tasks.gaze import GazeTask
from hqp.tasks.hybrid import HybridTask
from hqp.tasks.orientation import OrientationTask
from hqp.tasks.pose import PoseTask
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask
from hqp.tasks.reference import MinimumJerk, MinimumJerkPose, MinimumJerkRotation
from hqp.tasks.tracking import TaskKinematics

ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
G1 = ERD / "g1_description" / "urdf" / "g1_29dof_rev_1_0.urdf"

# robot name -> (hand frame, head frame, foot frame)
FRAMES = {
    "sample": ("rarm_wrist2_joint", "head2_joint", "rleg_effector_body"),
    "g1": ("right_wrist_yaw_link", "torso_link", "left_ankle_roll_link"),
    # the bundled robots share frame names
    "paper-humanoid": ("right_hand", "head", "left_foot"),
    "talos": ("right_hand", "head", "left_foot"),
}


@pytest.fixture(scope="module", params=["sample", "g1", "paper-humanoid", "talos"])
def robot(request) -> RobotModel:
    if request.param == "sample":
        return RobotModel(pin.buildSampleModelHumanoid(), name="sample")
    if request.param in ("paper-humanoid", "talos"):
        from hqp.robots import load

        return load(request.param).model()
    if not G1.is_file():
        pytest.skip("example-robot-data G1 URDF not found")
    return RobotModel.from_urdf(G1, name="g1")


def moving_pose(rng) -> MinimumJerkPose:
    return MinimumJerkPose(pin.SE3.Random(), pin.SE3.Random(), 1.0, 0.0)


def tasks(robot: RobotModel, rng: np.random.Generator):
    hand, head, foot = FRAMES[robot.name]
    com = CoMTask(robot)
    com.set_trajectory(MinimumJerk(np.zeros(3), rng.normal(size=3), 1.0))
    static = CoMTask(robot, horizontal=True)
    static.set_goal(rng.normal(size=2))  # a goal snapshot: its derivatives are not checked here
    pos = PositionTask(robot, hand, axes="xz")
    pos.set_trajectory(MinimumJerk(np.zeros(2), rng.normal(size=2), 1.0))
    ori = OrientationTask(robot, hand)
    R0, R1 = pin.exp3(rng.normal(size=3)), pin.exp3(rng.normal(size=3))
    ori.set_trajectory(MinimumJerkRotation(R0, R1, 1.0))
    pose = PoseTask(robot, hand)
    pose.set_trajectory(moving_pose(rng))
    gaze = GazeTask(robot, head, axis=(1.0, 0.2, 0.1))
    gaze.set_trajectory(MinimumJerk(np.array([2.0, 0.5, 1.0]), np.array([1.0, -1.0, 2.0]), 1.0))
    posture = PostureTask.symmetry(robot, robot.joint_names[:5])
    posture.set_trajectory(MinimumJerk(np.zeros(5), rng.normal(size=5), 1.0))
    hybrid = HybridTask(robot, foot, "foot", force_axes=("fz", "ty"))
    hybrid.set_trajectory(moving_pose(rng))
    return [com, static, pos, ori, pose, gaze, posture, hybrid]


def test_task_jacobians_and_drifts(robot: RobotModel) -> None:
    rng = np.random.default_rng(7)
    for task in tasks(robot, rng):
        try:
            check_kinematics(robot, task.kinematics, rng, n=10)
        except AssertionError as exc:
            raise AssertionError(f"{task.where()}: {exc}") from None


def test_frame_angular_jacobian_is_not_the_orientation_jacobian(robot: RobotModel) -> None:
    """The check fails if the orientation error used the frame's angular Jacobian."""
    hand = FRAMES[robot.name][0]
    ori = OrientationTask(robot, hand)
    ori.set_goal(np.eye(3))

    def naive(state: RobotModel, t: float) -> TaskKinematics:
        k = ori.kinematics(state, t)
        J = state.frame_jacobian(hand)[3:]
        return TaskKinematics(k.error, J @ state.v, J, state.frame_drift(hand)[3:])

    with pytest.raises(AssertionError):
        check_kinematics(robot, naive, np.random.default_rng(0), n=3)


def test_centroidal_momentum_rate(robot: RobotModel) -> None:
    """d/dt (S A_g v - h_goal(t)) = S A_g qdd + S dA_g v - hdot_goal, by finite differences."""
    rng = np.random.default_rng(8)
    task = CentroidalMomentumTask(robot, "all")
    task.set_trajectory(MinimumJerk(np.zeros(6), rng.normal(size=6), 1.0))
    other = RobotModel(robot.model, name="fd")
    eps, t = 1e-6, 0.4
    for _ in range(10):
        q = robot.random_configuration(rng, margin=0.05)
        v, qdd = rng.normal(size=(2, robot.nv))
        robot.update(q, v)
        e, J, drift = task.kinematics(robot, t)
        es = []
        for s in (eps, -eps):
            other.update(other.integrate(q, s * v + 0.5 * s * s * qdd), v + s * qdd)
            es.append(task.kinematics(other, t + s)[0])
        fd = (es[0] - es[1]) / (2 * eps)
        expected = J @ qdd + drift
        np.testing.assert_allclose(fd, expected, atol=1e-5 * (1 + np.abs(expected).max()))
        h_goal = task.trajectory.sample(t).position
        np.testing.assert_allclose(e + h_goal, robot.centroidal_matrix @ v, atol=1e-12)


@pytest.mark.parametrize("angle", [0.0, 1e-7, 1e-3, 0.009, 0.011, 0.5, 2.5])
def test_jlog3_rate_matches_finite_differences(angle: float) -> None:
    from hqp.tasks.orientation import jlog3_rate

    rng = np.random.default_rng(9)
    axis = rng.normal(size=3)
    e = angle * axis / np.linalg.norm(axis)
    R = pin.exp3(e)
    xi = rng.normal(size=3)
    de = pin.Jlog3(R) @ xi
    h = 1e-3  # pinocchio's Jlog3 loses ~1e-10 near the identity: keep the step large
    fd = (pin.Jlog3(R @ pin.exp3(h * xi)) - pin.Jlog3(R @ pin.exp3(-h * xi))) / (2 * h)
    got = jlog3_rate(e, de)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, fd, atol=1e-6)
