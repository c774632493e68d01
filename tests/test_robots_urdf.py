"""Any humanoid from its URDF (`hqp.robots.from_urdf`, robot TOML files).

The bundled g1 and talos, built by `from_urdf` from their robot files, against the records
hqp built before (``tests/data/robots_reference.json``, written by the hand-made records
of g1 and talos); two humanoids of example-robot-data that hqp does not bundle (Romeo,
iCub), loaded from URDF + feet + hands only; every bad description an error before any
simulation. The closed loops (stand, reach, push, walk) are marked slow.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import hqp.robots
from hqp.errors import HQPError, InvalidFrame, UnknownName
from hqp.robots import RobotDescriptionError, from_urdf
from hqp.robots.erd import erd_robots_dir

DATA = Path(__file__).parent / "data"
REFERENCE = json.loads((DATA / "robots_reference.json").read_text())
NEW = {"romeo": DATA / "robots" / "romeo.toml", "icub": DATA / "robots" / "icub.toml"}
ROMEO_URDF = "package://example-robot-data/robots/romeo_description/urdf/romeo_small.urdf"
FRAMES = ("left_foot", "right_foot", "left_hand", "right_hand", "trunk", "pelvis", "head")


def _standing(robot):
    model = robot.pinocchio_model()
    data = model.createData()
    q = np.asarray(robot.q_standing)
    pin.framesForwardKinematics(model, data, q)
    pin.centerOfMass(model, data, q)
    return model, data, q


@pytest.mark.parametrize("name", ["g1", "talos"])
def test_bundled_robot_equals_the_hand_made_record(name: str) -> None:
    ref = REFERENCE[name]
    robot = hqp.robots.load(name)
    model, data, q = _standing(robot)
    assert list(model.names) == ref["joints"]
    np.testing.assert_allclose([i.mass for i in model.inertias], ref["masses"], rtol=1e-12)
    for key, attr in (("lower", "lowerPositionLimit"), ("upper", "upperPositionLimit"),
                      ("effort", "effortLimit"), ("velocity", "velocityLimit")):
        np.testing.assert_allclose(getattr(model, attr), ref[key], rtol=1e-12)
    for frame in FRAMES:
        f = model.frames[model.getFrameId(frame)]
        assert model.names[f.parentJoint] == ref["frames_joint"][frame]
        local = np.array(ref["frames_local"][frame])
        np.testing.assert_allclose(f.placement.translation, local[:3, 3], atol=1e-3)
        np.testing.assert_allclose(f.placement.rotation, local[:3, :3], atol=1e-6)
        # the standing configuration puts every frame within 1 cm of the record's
        standing = np.array(ref["frames_standing"][frame])
        np.testing.assert_allclose(data.oMf[model.getFrameId(frame)].translation,
                                   standing[:3, 3], atol=0.01)
    np.testing.assert_allclose(data.com[0], ref["com"], atol=0.01)
    for contact, (cname, half_length, half_width, friction) in zip(robot.contacts,
                                                                 ref["contacts"]):
        assert contact.name == cname and contact.friction == friction
        np.testing.assert_allclose([contact.half_length, contact.half_width],
                                   [half_length, half_width], atol=1e-3)
    assert [(c.name, c.frame) for c in robot.capsules] == [(c[0], c[1]) for c in
                                                           ref["capsules"]]
    np.testing.assert_allclose(robot.standing_height, ref["standing_height"], atol=0.01)


@pytest.mark.parametrize("name", sorted(NEW))
def test_new_humanoid_from_urdf_feet_and_hands(name: str) -> None:
    robot = hqp.robots.load(NEW[name])
    model, data, q = _standing(robot)
    assert robot.name == name and robot.head_frame == "head"
    for frame in FRAMES:
        assert model.existFrame(frame)
    feet = [data.oMf[model.getFrameId(f)] for f in robot.feet]
    for foot in feet:  # flat on the floor, x forward
        assert abs(foot.translation[2]) < 1e-6
        np.testing.assert_allclose(foot.rotation, np.eye(3), atol=1e-6)
    assert feet[0].translation[1] > feet[1].translation[1] + 0.05  # left foot on the left
    middle = 0.5 * (feet[0].translation + feet[1].translation)
    np.testing.assert_allclose(data.com[0][:2], middle[:2], atol=1e-5)
    lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    assert np.all(q[7:] >= lower - 1e-9) and np.all(q[7:] <= upper + 1e-9)
    dims = robot.dimensions()
    for side in ("left", "right"):  # arms hang: hands well below the shoulders
        assert dims[f"{side}_hand"][2] < dims[f"{side}_shoulder"][2] - 0.5 * dims["arm_length"]
    # knees bent: the pelvis stands lower than the straight legs reach
    assert robot.standing_height < dims["leg_length"] + 0.2
    sole = robot.contact("left_foot")
    assert 0.05 < sole.half_length < 0.15 and 0.02 < sole.half_width < 0.08
    assert sole.half_length > sole.half_width  # a foot longer than wide: x is forward
    mj = robot.mujoco_model()
    assert mj.nq == model.nq and mj.nu == model.nv - 6
    np.testing.assert_allclose(sum(mj.body_mass), sum(i.mass for i in model.inertias),
                               rtol=1e-9)


def test_sole_of_a_collada_y_up_mesh_is_read_as_ros_reads_it() -> None:
    # iCub's foot meshes are Collada files declared Y_UP, which assimp turns to Z_UP; the
    # URDF places them as ROS tools read them (no turn): the sole is 0.156 x 0.061 m, the
    # ankle near the heel (measured in the mesh's coordinates, undone turn)
    robot = hqp.robots.load(NEW["icub"])
    sole = robot.contact("left_foot")
    np.testing.assert_allclose([2 * sole.half_length, 2 * sole.half_width], [0.156, 0.061],
                               atol=0.002)


def test_from_urdf_in_a_few_lines_and_the_same_as_its_file() -> None:
    a = from_urdf(ROMEO_URDF, feet=("l_sole", "r_sole"), hands=("l_gripper", "r_gripper"),
                  name="romeo")
    b = hqp.robots.load(NEW["romeo"])
    np.testing.assert_array_equal(a.q_standing, b.q_standing)
    assert a.mjcf_path == b.mjcf_path  # the same generated files


def test_robot_file_paths_are_relative_to_the_file(tmp_path: Path) -> None:
    urdf = erd_robots_dir() / "romeo_description" / "urdf" / "romeo_small.urdf"
    (tmp_path / "sub").mkdir()
    path = tmp_path / "sub" / "mine.toml"
    path.write_text(f'urdf = "{os.path.relpath(urdf, path.parent)}"\n'
                    'feet = ["l_sole", "r_sole"]\nhands = ["l_gripper", "r_gripper"]\n'
                    'name = "my-romeo"\nknee_bend = 0.5\n')
    robot = hqp.robots.load(path)
    assert robot.name == "my-romeo"
    model, _, q = _standing(robot)
    knee = model.joints[model.getJointId("LKneePitch")].idx_q
    reference = hqp.robots.load(NEW["romeo"])
    assert q[knee] > reference.q_standing[knee] + 0.1  # the option reached the optimisation


# -- mistakes: HQPError subclasses with one-line messages, before any simulation ---------------


def _one_line(exc: pytest.ExceptionInfo) -> str:
    message = str(exc.value)
    assert "\n" not in message
    return message


def test_unknown_foot_frame_lists_the_frames() -> None:
    with pytest.raises(InvalidFrame) as exc:
        from_urdf(ROMEO_URDF, feet=("left_sole", "r_sole"), hands=("l_gripper", "r_gripper"))
    message = _one_line(exc)
    assert "'left_sole'" in message and "left foot" in message and "l_sole" in message


def test_unknown_hand_frame_lists_the_frames() -> None:
    with pytest.raises(InvalidFrame, match="right hand.*r_gripper"):
        from_urdf(ROMEO_URDF, feet=("l_sole", "r_sole"), hands=("l_gripper", "r_hand"))


def test_foot_without_collision_geometry_says_how_to_give_the_sole() -> None:
    urdf = "package://example-robot-data/robots/simple_humanoid_description/urdf/" \
           "simple_humanoid.urdf"
    with pytest.raises(RobotDescriptionError) as exc:
        from_urdf(urdf, feet=("l_ankle", "r_ankle"), hands=("l_wrist", "r_wrist"))
    message = _one_line(exc)
    assert "left foot 'l_ankle' has no collision geometry" in message
    assert "sole = {length = ..., width = ..., center = [x, y, z]}" in message


def _romeo_text() -> str:
    return (erd_robots_dir() / "romeo_description" / "urdf" / "romeo_small.urdf").read_text()


def test_joint_without_limits_is_named(tmp_path: Path) -> None:
    text = re.sub(r'(<joint name="LHipYaw".*?<limit[^>]*?)effort="[^"]*"', r'\1effort="0"',
                  _romeo_text(), count=1, flags=re.S)
    urdf = tmp_path / "romeo_no_effort.urdf"
    urdf.write_text(text)
    with pytest.raises(RobotDescriptionError) as exc:
        from_urdf(urdf, feet=("l_sole", "r_sole"), hands=("l_gripper", "r_gripper"))
    message = _one_line(exc)
    assert "gives no effort limit for joint LHipYaw" in message
    assert "torque_limits = {LHipYaw = ...}" in message
    # the option supplies it
    robot = from_urdf(urdf, feet=("l_sole", "r_sole"), hands=("l_gripper", "r_gripper"),
                      torque_limits={"LHipYaw": 9.2})
    model = robot.pinocchio_model()
    assert model.effortLimit[model.joints[model.getJointId("LHipYaw")].idx_v] == 9.2


def test_a_robot_that_cannot_stand_says_what_was_found() -> None:
    with pytest.raises(RobotDescriptionError) as exc:
        from_urdf(ROMEO_URDF, feet=("l_sole", "r_sole"), hands=("l_gripper", "r_gripper"),
                  name="romeo", standing={"LKneePitch": 1.9, "RKneePitch": 1.9},
                  position_limits={"LHipPitch": [-0.3, 0.4], "RHipPitch": [-0.3, 0.4]})
    message = _one_line(exc)
    assert message.startswith("robot 'romeo' cannot stand")
    assert "HipPitch" in message or "no solution" in message


def test_unknown_option_and_bad_values() -> None:
    feet, hands = ("l_sole", "r_sole"), ("l_gripper", "r_gripper")
    with pytest.raises(RobotDescriptionError, match="unknown option 'sole_size'; options: sole"):
        from_urdf(ROMEO_URDF, feet=feet, hands=hands, sole_size=0.2)
    with pytest.raises(RobotDescriptionError, match="sole: missing 'width'"):
        from_urdf(ROMEO_URDF, feet=feet, hands=hands, sole={"length": 0.2})
    with pytest.raises(RobotDescriptionError, match="feet: expected \\(left, right\\)"):
        from_urdf(ROMEO_URDF, feet="l_sole", hands=hands)
    with pytest.raises(RobotDescriptionError, match="standing: unknown joint 'knee'"):
        from_urdf(ROMEO_URDF, feet=feet, hands=hands, standing={"knee": 0.3})
    with pytest.raises(RobotDescriptionError, match="no such file"):
        from_urdf("/nonexistent/robot.urdf", feet=feet, hands=hands)
    with pytest.raises(InvalidFrame, match="head"):
        from_urdf(ROMEO_URDF, feet=feet, hands=hands, head="skull")


@pytest.mark.parametrize(("text", "match"), [
    ('feet = ["l_sole", "r_sole"]\nhands = ["l_gripper", "r_gripper"]\n', "missing key 'urdf'"),
    (f'urdf = "{ROMEO_URDF}"\nfeet = ["l_sole", "r_sole"]\nhands = ["l_gripper", "r_gripper"]'
     '\ncolour = "red"\n', "unknown key 'colour'"),
    ("urdf = \n", "not valid TOML"),
    (f'urdf = "{ROMEO_URDF}"\nfeet = ["l_sole", "r_sole"]\nhands = ["l_gripper", "r_gripper"]'
     '\nknee_bend = "a lot"\n', "knee_bend: expected a finite number"),
])
def test_bad_robot_file(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(RobotDescriptionError, match=match) as exc:
        hqp.robots.load(path)
    assert str(exc.value).startswith(str(path)) and "\n" not in str(exc.value)


def test_load_names_the_bundled_robots_and_files() -> None:
    assert issubclass(RobotDescriptionError, HQPError)
    with pytest.raises(UnknownName, match="g1, paper-humanoid, talos"):
        hqp.robots.load("romeo")
    with pytest.raises(RobotDescriptionError, match="no such robot file"):
        hqp.robots.load("missing/robot.toml")


@pytest.mark.parametrize("command", [
    ["run", "stand"], ["view", "stand", "--no-browser"], ["bench", "--suite", "controller"],
    ["sweep", "push-map"], ["compare", "hand-reach"],
])
def test_every_command_refuses_a_bad_robot_file_in_one_line(tmp_path, capsys, command):
    from hqp.cli import main

    path = tmp_path / "nope.toml"
    assert main([*command, "--robot", str(path)]) != 0
    err = capsys.readouterr().err.strip()
    assert "nope.toml" in err and "no such robot file" in err and "\n" not in err


def test_hqp_run_reports_a_wrong_robot_file_in_one_line(tmp_path, capsys):
    from hqp.cli import main

    path = tmp_path / "romeo.toml"
    path.write_text(f'urdf = "{ROMEO_URDF}"\nfeet = ["l_foot", "r_sole"]\n'
                    'hands = ["l_gripper", "r_gripper"]\n')
    assert main(["run", "stand", "--robot", str(path), "--json"]) != 0
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == ""  # no run
    assert any("unknown frame 'l_foot'" in line and "l_sole" in line for line in err)


# -- closed loops in MuJoCo ---------------------------------------------------------------------


def _closed_loop(behavior: str, robot: str | Path, duration: float, pushes=(),
                 overrides=None):
    from hqp.behaviors.setup import prepare
    from hqp.sim.loop import closed_loop
    from hqp.sim.simulator import Simulator

    behavior_obj, ctrl, robot_obj = prepare(behavior, robot=str(robot), overrides=overrides)
    sim = Simulator(robot_obj)
    ctrl.dt = sim.dt
    behavior_obj.start(sim.state(), 0.0)
    speeds = []
    outcome = closed_loop(sim, behavior_obj, duration, pushes, clock="steps",
                          after_step=lambda step, _: speeds.append(
                              float(np.linalg.norm(sim.state().v[:2]))))
    behavior_obj.max_base_speed = max(speeds)  # [m/s], horizontal
    model = robot_obj.model()
    state = sim.state()
    model.update(state.q, state.v)
    return outcome, behavior_obj, model


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(NEW))
def test_new_humanoid_stands_5_s(name: str) -> None:
    outcome, _, model = _closed_loop("stand", NEW[name], 5.0)
    assert outcome.fell_at is None, outcome.fall_reason
    robot = hqp.robots.load(NEW[name])
    assert abs(model.frame_placement("pelvis").translation[2] - robot.standing_height) < 0.01


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(NEW))
def test_new_humanoid_reaches_in_front_of_it(name: str) -> None:
    outcome, behavior, model = _closed_loop("reach", NEW[name], 4.0)
    assert outcome.fell_at is None, outcome.fall_reason
    assert behavior.visited == ["stand", "reach"]
    goal = behavior.inputs.value("hand_goal", 4.0)
    dims = hqp.robots.load(NEW[name]).dimensions()
    assert goal[0] > dims["right_shoulder"][0] + 0.5 * dims["arm_length"]  # in front of it
    hand = model.frame_placement("right_hand").translation
    assert np.linalg.norm(hand - goal) < 0.03  # [m]


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(NEW))
def test_new_humanoid_survives_a_50_n_push(name: str) -> None:
    from hqp.sim.loop import Push

    pushes = [Push(1.0, (50.0, 0.0, 0.0), 0.2), Push(3.0, (0.0, 50.0, 0.0), 0.2)]
    outcome, behavior, _ = _closed_loop("stand", NEW[name], 5.0, pushes)
    assert outcome.fell_at is None, outcome.fall_reason
    assert behavior.max_base_speed > 0.05  # [m/s]: the pushes moved it


@pytest.mark.slow
def test_g1_keeps_its_feet_before_an_unreachable_goal() -> None:
    # 0.8 m ahead at the seed's height (1.10 m) is out of g1's reach: the hand stops short,
    # the robot stays up (the seed's own point, 0.55 m ahead, is at the edge of it: the hand
    # stops 2.7 cm short)
    goal = np.array([0.8, -0.22, 1.10])
    outcome, behavior, model = _closed_loop("reach", "g1", 3.0,
                                            overrides={"hand_goal": list(goal)})
    assert outcome.fell_at is None, outcome.fall_reason
    hand = model.frame_placement("right_hand").translation
    assert np.linalg.norm(hand - goal) > 0.05


@pytest.mark.slow
@pytest.mark.parametrize("name", [
    "romeo",
    pytest.param("icub", marks=pytest.mark.xfail(strict=False, reason=(
        "iCub's walk is marginal: it fell after 7 footsteps at 9.1 s of a 13 s walk in one "
        "process and at 5.5 s in another (the library walk's step length and timing are not "
        "scaled to its size; docs/robots.md)"))),
])
def test_new_humanoid_walks_4_steps(name: str) -> None:
    from hqp.app.run import run_behavior

    result = run_behavior("walk", robot=str(NEW[name]), duration=8.0)
    assert not result.fell, result.fall_reason
    assert len(result.steps) >= 4


@pytest.mark.slow
def test_the_viewer_serves_a_humanoid_from_its_robot_file(tmp_path) -> None:
    import urllib.request

    from hqp.app.view import measure

    pytest.importorskip("viser")
    port = measure.free_port()
    proc = measure.start_view(port, tmp_path / "view.log", behavior="reach",
                              robot=str(NEW["romeo"]))
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=60) as reply:
            assert reply.status == 200
            assert "<html" in reply.read().decode(errors="replace").lower()
        assert "romeo" in (tmp_path / "view.log").read_text().lower()
    finally:
        assert measure.stop_view(proc) == 0
