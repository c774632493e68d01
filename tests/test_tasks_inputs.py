"""Bad input to the balance, operational and posture primitives raises HQPError naming the task."""

import json

import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError, InvalidFrame, InvalidGain, InvalidInput
from hqp.model import RobotModel
from hqp.model.layout import Layout
from hqp.tasks.centroidal import CentroidalMomentumTask
from hqp.tasks.com import CoMTask
from hqp.tasks.gaze import GazeTask
from hqp.tasks.hybrid import HybridTask
from hqp.tasks.orientation import OrientationTask
from hqp.tasks.pose import PoseTask
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask, load_poses

HAND = "rarm_wrist2_joint"


@pytest.fixture(scope="module")
def robot() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


FRAME_TASKS = [
    (PositionTask, {}, "PositionTask 'no_such_frame'"),
    (OrientationTask, {}, "OrientationTask 'no_such_frame'"),
    (PoseTask, {}, "PoseTask 'no_such_frame'"),
    (GazeTask, {}, "GazeTask 'gaze'"),
    (HybridTask, {"contact": "c"}, "HybridTask 'hybrid_no_such_frame'"),
]


@pytest.mark.parametrize("cls, kwargs, where", FRAME_TASKS)
def test_unknown_frame_lists_frames(robot, cls, kwargs, where) -> None:
    with pytest.raises(InvalidFrame, match="frames in the model: .*rarm_wrist2_joint") as info:
        cls(robot, "no_such_frame", **kwargs)
    assert where in str(info.value)


def vector_tasks(robot):
    return [
        (CoMTask(robot), 3),
        (CoMTask(robot, horizontal=True), 2),
        (PositionTask(robot, HAND, axes="yz"), 2),
        (GazeTask(robot, "head2_joint"), 3),
        (PostureTask(robot, ["head1_joint", "head2_joint"]), 2),
    ]


def test_nan_and_wrong_shape_goals(robot) -> None:
    for task, m in vector_tasks(robot):
        with pytest.raises(InvalidInput, match=f"{task.where()}: goal: expected shape"):
            task.set_goal(np.zeros(m + 1))
        bad = np.zeros(m)
        bad[-1] = np.nan
        with pytest.raises(InvalidInput, match=f"{task.where()}: goal: contains NaN"):
            task.set_goal(bad)
        with pytest.raises(InvalidInput, match=f"{task.where()}: goal velocity"):
            task.set_goal(np.zeros(m), velocity=np.zeros(m + 2))
    ori = OrientationTask(robot, HAND)
    with pytest.raises(InvalidInput, match="OrientationTask .*not a rotation"):
        ori.set_goal(2.0 * np.eye(3))
    with pytest.raises(InvalidInput, match="OrientationTask .*expected shape"):
        ori.set_goal(np.zeros(3))
    pose = PoseTask(robot, HAND)
    H = np.eye(4)
    H[0, 3] = np.nan
    with pytest.raises(InvalidInput, match="PoseTask .*NaN"):
        pose.set_goal(H)
    with pytest.raises(InvalidInput, match="PoseTask .*goal velocity"):
        pose.set_goal(np.eye(4), velocity=np.zeros(3))
    cm = CentroidalMomentumTask(robot, "angular")
    with pytest.raises(InvalidInput, match="CentroidalMomentumTask 'centroidal': goal"):
        cm.set_goal(np.zeros(6))


def test_goals_are_copied(robot) -> None:
    task = PositionTask(robot, HAND)
    goal = np.array([0.1, 0.2, 0.3])
    task.set_goal(goal)
    goal[0] = 5.0
    np.testing.assert_array_equal(task.goal_at(0.0).position, [0.1, 0.2, 0.3])


def test_goal_not_set(robot) -> None:
    layout = Layout.build(robot.nv)
    robot.update(robot.neutral(), np.zeros(robot.nv))
    with pytest.raises(InvalidInput, match="PositionTask 'hand': goal not set"):
        PositionTask(robot, HAND, name="hand").rows(robot, layout, 1e-3, 0.0)


@pytest.mark.parametrize(
    "make",
    [
        lambda r: CoMTask(r, kp=-1.0),
        lambda r: PositionTask(r, HAND, kv=np.nan),
        lambda r: OrientationTask(r, HAND, max_velocity=-1.0),
        lambda r: PoseTask(r, HAND, max_angular_acceleration=-2.0),
        lambda r: GazeTask(r, "head2_joint", kp=np.inf),
        lambda r: PostureTask(r, kp=10.0, kv=0.0),
        lambda r: HybridTask(r, HAND, "c", max_acceleration=np.nan),
        lambda r: CentroidalMomentumTask(r, gain=-1.0),
    ],
)
def test_bad_gains_name_the_primitive(robot, make) -> None:
    with pytest.raises(InvalidGain, match=r"^\w+Task '[\w_]+'"):
        make(robot)


@pytest.mark.parametrize(
    "make",
    [
        lambda r, **gains: CoMTask(r, **gains),
        lambda r, **gains: PositionTask(r, HAND, **gains),
        lambda r, **gains: OrientationTask(r, HAND, **gains),
        lambda r, **gains: PoseTask(r, HAND, **gains),
        lambda r, **gains: GazeTask(r, "head2_joint", **gains),
        lambda r, **gains: PostureTask(r, **gains),
        lambda r, **gains: HybridTask(r, HAND, "c", **gains),
    ],
)
def test_gain_keywords_reach_the_reference(robot, make) -> None:
    ref = make(robot, kp=4.0, kv=3.0, max_velocity=0.5, max_acceleration=2.0).reference
    assert (ref.kp, ref.kv, ref.max_velocity, ref.max_acceleration) == (4.0, 3.0, 0.5, 2.0)


def test_set_gains_validates_and_keeps_old_reference(robot) -> None:
    task = PositionTask(robot, HAND, kp=100.0, max_velocity=0.5)
    with pytest.raises(InvalidGain, match="PositionTask"):
        task.set_gains(kp=-3.0)
    assert task.reference.kp == 100.0
    task.set_gains(kp=25.0)
    assert task.reference.kv == pytest.approx(10.0)  # critical damping for the new kp
    assert task.reference.max_velocity == 0.5


def test_bad_selections(robot) -> None:
    with pytest.raises(InvalidInput, match="axes"):
        PositionTask(robot, HAND, axes="xw")
    with pytest.raises(InvalidInput, match="axes"):
        PositionTask(robot, HAND, axes=[0, 0])
    with pytest.raises(InvalidInput, match="unknown joint 'elbow'"):
        PostureTask(robot, ["elbow"])
    with pytest.raises(InvalidInput, match="components"):
        CentroidalMomentumTask(robot, "torque")
    with pytest.raises(InvalidInput, match="GazeTask 'gaze': axis must be non-zero"):
        GazeTask(robot, "head2_joint", axis=(0.0, 0.0, 0.0))
    assert issubclass(InvalidInput, HQPError)


def test_posture_from_files(robot, tmp_path) -> None:
    joints = list(robot.joint_names)
    rng = np.random.default_rng(0)
    stand = rng.uniform(robot.q_lower, robot.q_upper)
    np.savez(tmp_path / "poses.npz", stand=stand)
    named = {"wave": {"rarm_shoulder1_joint": 0.3, "rarm_elbow_joint": -0.5}}
    (tmp_path / "poses.json").write_text(json.dumps(named))
    task = PostureTask.from_file(robot, tmp_path / "poses.npz", "stand")
    np.testing.assert_allclose(task.goal_at(0.0).position, stand)
    arm = PostureTask.from_file(
        robot, tmp_path / "poses.json", "wave", joints=["rarm_elbow_joint", "rarm_shoulder1_joint"]
    )
    np.testing.assert_allclose(arm.goal_at(0.0).position, [-0.5, 0.3])
    assert set(load_poses(tmp_path / "poses.json")) == {"wave"}
    with pytest.raises(InvalidInput, match="no pose 'sit'.*poses: stand"):
        PostureTask.from_file(robot, tmp_path / "poses.npz", "sit")
    with pytest.raises(InvalidInput, match="goal misses joints"):
        PostureTask.from_file(robot, tmp_path / "poses.json", "wave", joints=joints[:3])
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(InvalidInput, match="invalid JSON"):
        load_poses(tmp_path / "bad.json")
    (tmp_path / "poses.txt").write_text("stand: 0")
    with pytest.raises(InvalidInput, match="unknown extension"):
        load_poses(tmp_path / "poses.txt")
    with pytest.raises(InvalidInput, match="no such file"):
        load_poses(tmp_path / "missing.npz")


def test_symmetry_posture_eq26(robot) -> None:
    task = PostureTask.symmetry(robot)
    mid = 0.5 * (robot.q_lower + robot.q_upper)
    np.testing.assert_allclose(task.goal_at(0.0).position, mid)
    np.testing.assert_allclose(task.scale, 1.0 / (robot.q_upper - robot.q_lower))
    q = robot.neutral()
    q[robot.actuated_q] = robot.q_upper
    robot.update(q, np.zeros(robot.nv))
    kin = task.kinematics(robot, 0.0)
    np.testing.assert_allclose(kin.error, 0.5)  # half a range above mid-range, normalised
