from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import hqp
import hqp.robots
from hqp.model.layout import ContactType
from hqp.robots import paper_humanoid as ph
from hqp.robots.robot import Robot

ROBOTS = ["paper-humanoid", "g1", "talos"]


@pytest.fixture(scope="module")
def paper() -> Robot:
    return hqp.robots.load("paper-humanoid")


def erd_file(relative: str) -> Path:
    from hqp.robots.erd import erd_robots_dir

    return erd_robots_dir() / relative


# -- registry -------------------------------------------------------------------------------------


def test_unknown_robot_lists_valid_names() -> None:
    with pytest.raises(hqp.UnknownName, match="valid robots: g1, paper-humanoid, talos"):
        hqp.robots.load("asimo")


# -- paper humanoid: figures ----------------------------------------------------------------------


def test_paper_humanoid_figures(paper: Robot) -> None:
    model = paper.model()
    np.testing.assert_allclose(model.mass, 71.0, rtol=1e-12)
    assert model.na == 24
    expected = [
        f"{side}_{j}"
        for side in ("left", "right")
        for j in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
    ]
    expected += ["torso_yaw", "torso_pitch", "head_yaw", "head_pitch"]
    expected += [
        f"{side}_{j}"
        for side in ("left", "right")
        for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow")
    ]
    assert sorted(model.joint_names) == sorted(expected)
    # Height: sole to vertex with straight legs (neutral configuration).
    model.update(model.neutral(), np.zeros(model.nv))
    height = model.frame_placement("head_top").translation[2] - model.frame_placement(
        "left_foot"
    ).translation[2]
    np.testing.assert_allclose(height, 1.65, atol=1e-9)


def test_paper_humanoid_sign_conventions(paper: Robot) -> None:
    """Knee and elbow flexion are negative (paper Figs. 4-5); limits as documented."""
    model = paper.model()
    knee = model.joint_index("right_knee")
    elbow = model.joint_index("right_elbow")
    np.testing.assert_allclose(model.q_lower[knee], -ph.KNEE_FLEXION_LIMIT)
    np.testing.assert_allclose(model.q_upper[knee], 0.0)
    np.testing.assert_allclose(model.q_lower[elbow], -ph.ELBOW_FLEXION_LIMIT)
    np.testing.assert_allclose(model.q_upper[elbow], 0.0)
    # Flexing the knee (negative angle) moves the foot backwards; flexing the elbow moves
    # the hand forwards and up.
    q = model.neutral()
    model.update(q, np.zeros(model.nv))
    foot0 = model.frame_placement("right_foot").translation.copy()
    hand0 = model.frame_placement("right_hand").translation.copy()
    q[7 + knee] = -0.5
    q[7 + elbow] = -0.5
    model.update(q, np.zeros(model.nv))
    assert model.frame_placement("right_foot").translation[0] < foot0[0] - 0.1
    assert model.frame_placement("right_hand").translation[0] > hand0[0] + 0.05
    assert model.frame_placement("right_hand").translation[2] > hand0[2]


def test_paper_humanoid_limits_match_talos_urdf(paper: Robot) -> None:
    """Torque and velocity limits are TALOS's (example-robot-data talos_reduced.urdf)."""
    root = ET.parse(erd_file("talos_data/robots/talos_reduced.urdf")).getroot()
    talos = {
        j.get("name"): j.find("limit")
        for j in root.iter("joint")
        if j.find("limit") is not None
    }
    model = paper.model()
    for name in model.joint_names:
        key = name.removeprefix("left_").removeprefix("right_")
        effort, velocity, talos_joint = ph.TALOS_LIMITS[key]
        limit = talos[talos_joint]
        assert float(limit.get("effort")) == pytest.approx(effort)
        assert float(limit.get("velocity")) == pytest.approx(velocity)
        i = model.joint_index(name)
        assert model.tau_max[i] == pytest.approx(effort)
        assert model.v_max[i] == pytest.approx(velocity)


def test_paper_humanoid_files_equal_generator_output() -> None:
    urdf, mjcf = ph.generate()
    assert ph.URDF_PATH.read_text() == urdf, "run: python -m hqp.robots.paper_humanoid"
    assert ph.MJCF_PATH.read_text() == mjcf, "run: python -m hqp.robots.paper_humanoid"


# -- paper humanoid: MJCF and URDF agree ----------------------------------------------------------


def test_paper_humanoid_mjcf_and_urdf_agree(paper: Robot) -> None:
    """Masses, inertias and frame placements of both files, through pinocchio's parsers."""
    m_urdf = pin.buildModelFromUrdf(str(paper.urdf_path), pin.JointModelFreeFlyer())
    m_mjcf = pin.buildModelFromMJCF(str(paper.mjcf_path))
    # pinocchio 3's MJCF parser kept the root body's initial position as the free flyer's
    # placement (MuJoCo's free-joint qpos is absolute), pinocchio 4's drops it: compare
    # with it removed.
    root = m_mjcf.jointPlacements[1].translation
    assert np.allclose(root, [0, 0, paper.standing_height]) or np.allclose(root, 0.0), root
    m_mjcf.jointPlacements[1] = pin.SE3.Identity()
    assert m_urdf.nq == m_mjcf.nq == 31
    assert list(m_urdf.names)[2:] == list(m_mjcf.names)[2:]
    for j in range(1, m_urdf.njoints):
        iu, im = m_urdf.inertias[j], m_mjcf.inertias[j]
        np.testing.assert_allclose(iu.mass, im.mass, rtol=1e-9)
        np.testing.assert_allclose(iu.lever, im.lever, atol=1e-9)
        np.testing.assert_allclose(iu.inertia, im.inertia, atol=1e-9)
        if j > 1:
            np.testing.assert_allclose(
                m_urdf.jointPlacements[j].homogeneous, m_mjcf.jointPlacements[j].homogeneous,
                atol=1e-9,
            )
    np.testing.assert_allclose(sum(i.mass for i in m_mjcf.inertias), 71.0, rtol=1e-9)
    # (MJCF-model frame index, URDF-model frame index) of frames with the same name; the
    # MJCF model has both a BODY and an OP_FRAME (site) "pelvis" and "trunk".
    common = [
        (i, m_urdf.getFrameId(f.name)) for i, f in enumerate(m_mjcf.frames)
        if f.name != "universe" and m_urdf.existFrame(f.name)
        and f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)
    ]
    common_names = {m_mjcf.frames[i].name for i, _ in common}
    for name in ("left_foot", "right_foot", "left_hand", "right_hand", "trunk", "pelvis", "head"):
        assert name in common_names
    d_urdf, d_mjcf = m_urdf.createData(), m_mjcf.createData()
    rng = np.random.default_rng(0)
    for _ in range(10):
        q = np.concatenate([rng.uniform(-1, 1, 3), pin.Quaternion(*rng.normal(size=4))
                            .normalized().coeffs(), rng.uniform(-2.5, 2.5, m_urdf.nq - 7)])
        pin.framesForwardKinematics(m_urdf, d_urdf, q)
        pin.framesForwardKinematics(m_mjcf, d_mjcf, q)
        for i_mjcf, i_urdf in common:
            np.testing.assert_allclose(
                d_urdf.oMf[i_urdf].homogeneous, d_mjcf.oMf[i_mjcf].homogeneous,
                atol=1e-9, err_msg=m_mjcf.frames[i_mjcf].name,
            )
        pin.crba(m_urdf, d_urdf, q)
        pin.crba(m_mjcf, d_mjcf, q)
        np.testing.assert_allclose(np.triu(d_urdf.M), np.triu(d_mjcf.M), atol=1e-9)


def test_paper_humanoid_mujoco_model(paper: Robot) -> None:
    mj = paper.mujoco_model()
    model = paper.model()
    assert mj.nu == 24
    assert mj.opt.timestep == 0.001
    assert mj.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    np.testing.assert_allclose(mj.dof_damping, 0.0)
    np.testing.assert_allclose(mj.dof_armature, 0.0)
    np.testing.assert_allclose(mj.dof_frictionloss, 0.0)
    assert not mj.actuator_ctrllimited.any()
    assert not mj.actuator_forcelimited.any()
    assert not mj.jnt_actfrclimited.any()
    np.testing.assert_allclose(mj.body_mass.sum(), 71.0, rtol=1e-9)
    for name in model.joint_names:
        i = model.joint_index(name)
        jnt = mj.joint(name)
        assert jnt.limited[0]
        np.testing.assert_allclose(jnt.range, [model.q_lower[i] - 0.2, model.q_upper[i] + 0.2])
    soles = [mj.geom(f"{side}_sole") for side in ("left", "right")]
    for sole in soles:
        assert sole.type[0] == mujoco.mjtGeom.mjGEOM_BOX
        assert sole.condim[0] == 3


# -- standing configuration -----------------------------------------------------------------------


def _check_standing(robot: Robot) -> None:
    model = robot.model()
    q = robot.q_standing
    assert q.shape == (model.nq,)
    model.update(q, np.zeros(model.nv))
    inside = []
    for name in robot.feet:
        placement = model.frame_placement(name)
        np.testing.assert_allclose(placement.translation[2], 0.0, atol=1e-9)
        np.testing.assert_allclose(placement.rotation, np.eye(3), atol=1e-9)
        contact = robot.contact(name)
        assert contact.kind is ContactType.SURFACE
        inside.append((placement.rotation @ contact.corners().T).T + placement.translation)
    corners = np.vstack(inside)[:, :2]
    com = model.com[:2]
    # CoM strictly inside the convex hull of the sole corners (both soles are boxes
    # aligned with the world axes, so the hull's bounding box test is exact along x and the
    # hull contains the segment between the sole centres).
    assert corners[:, 0].min() + 0.02 < com[0] < corners[:, 0].max() - 0.02
    assert corners[:, 1].min() + 0.02 < com[1] < corners[:, 1].max() - 0.02
    np.testing.assert_allclose(
        robot.standing_height, model.frame_placement(robot.base_frame).translation[2]
    )
    assert np.all(q[model.actuated_q] >= model.q_lower - 1e-12)
    assert np.all(q[model.actuated_q] <= model.q_upper + 1e-12)


def test_paper_humanoid_standing(paper: Robot) -> None:
    _check_standing(paper)
    model = paper.model()
    for side in ("left", "right"):
        assert paper.q_standing[7 + model.joint_index(f"{side}_knee")] < -0.1  # bent knees


def sink_depth(
    robot: Robot,
    seconds: float = 1.0,
    solref: tuple[float, ...] | None = None,
    solimp: tuple[float, ...] | None = None,
) -> float:
    """Largest sole penetration [m] over the last 0.1 s of a robot held in q_standing.

    The joints are held by stiff joint-equality constraints in a copy of the MJCF (the
    shipped model is untouched), the free base is free: only the contacts carry the robot.
    ``solref``/``solimp`` replace the geoms' contact parameters when given.
    """
    spec = mujoco.MjSpec.from_file(str(robot.mjcf_path))
    for geom in spec.geoms:
        if solref is not None:
            geom.solref = list(solref)
        if solimp is not None:
            geom.solimp = list(solimp)
    base = spec.compile()
    q = robot.q_standing
    from hqp.sim.convert import StateMap

    smap = StateMap(robot.model(), base)
    qpos = smap.qpos_from_q(q)
    for j in range(base.njnt):
        if base.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            continue
        eq = spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1=base.joint(j).name)
        eq.data[:5] = [qpos[base.jnt_qposadr[j]], 0.0, 0.0, 0.0, 0.0]
        eq.solref = [0.002, 1.0]
    mj = spec.compile()
    data = mujoco.MjData(mj)
    data.qpos[:] = qpos
    steps = int(round(seconds / mj.opt.timestep))
    depth = 0.0
    for k in range(steps):
        mujoco.mj_step(mj, data)
        if k >= steps - 100:
            assert data.ncon >= 6  # both soles (box-plane: up to 4 contacts each)
            depth = max(depth, -float(data.contact.dist[: data.ncon].min()))
    return depth


def test_paper_humanoid_sinks_less_than_a_millimetre(paper: Robot) -> None:
    assert sink_depth(paper) < 1e-3


# -- every robot ----------------------------------------------------------------------------------


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request: pytest.FixtureRequest) -> Robot:
    return hqp.robots.load(request.param)


def test_uniform_frames(robot: Robot) -> None:
    model = robot.model()
    mj = robot.mujoco_model()
    names = ["left_foot", "right_foot", "left_hand", "right_hand", "trunk", "pelvis", "head"]
    assert robot.feet == ("left_foot", "right_foot")
    assert robot.hands == ("left_hand", "right_hand")
    assert robot.base_frame == "pelvis"
    assert robot.head_frame == "head"
    for name in names:
        assert model.has_frame(name), name
        assert mj.site(name).name == name
    # The base frame is the free flyer's frame.
    base = model.model.frames[model.frame_id("pelvis")]
    assert base.parentJoint == 1
    np.testing.assert_allclose(base.placement.homogeneous, np.eye(4), atol=1e-12)
    assert [c.name for c in robot.contacts] == ["left_foot", "right_foot"]
    for c in robot.contacts:
        assert c.kind is ContactType.SURFACE
        assert c.half_length > 0.05 and c.half_width > 0.02 and c.friction > 0


def test_standing(robot: Robot) -> None:
    _check_standing(robot)


def test_mujoco_model_matches_controller_model(robot: Robot) -> None:
    model = robot.model()
    mj = robot.mujoco_model()
    assert mj.nu == model.na
    assert mj.opt.timestep == 0.001
    assert mj.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    np.testing.assert_allclose(mj.dof_damping, 0.0)
    np.testing.assert_allclose(mj.dof_armature, 0.0)
    np.testing.assert_allclose(mj.dof_frictionloss, 0.0)
    np.testing.assert_allclose(mj.jnt_stiffness, 0.0)
    assert not mj.actuator_ctrllimited.any()
    assert not mj.actuator_forcelimited.any()
    np.testing.assert_allclose(mj.body_mass.sum(), model.mass, rtol=1e-10)
    for name in model.joint_names:
        i = model.joint_index(name)
        jnt = mj.joint(name)
        assert jnt.limited[0]
        np.testing.assert_allclose(
            jnt.range, [model.q_lower[i] - 0.2, model.q_upper[i] + 0.2], atol=1e-10
        )
    # Only the sole boxes collide, with condim 3.
    colliding = [g for g in range(mj.ngeom) if mj.geom_contype[g] or mj.geom_conaffinity[g]]
    names = sorted(mj.geom(g).name for g in colliding)
    assert names == ["floor", "left_sole", "right_sole"]
    for g in colliding:
        assert mj.geom_condim[g] == 3
    # The sole boxes are the contact surfaces: same half-lengths, bottom face centred on the
    # sole frame (site), same friction.
    data = mujoco.MjData(mj)
    mujoco.mj_resetDataKeyframe(mj, data, mj.key("standing").id)
    mujoco.mj_forward(mj, data)
    for side in ("left", "right"):
        contact = robot.contact(f"{side}_foot")
        geom = mj.geom(f"{side}_sole")
        np.testing.assert_allclose(geom.size[:2], [contact.half_length, contact.half_width])
        np.testing.assert_allclose(geom.friction[0], contact.friction)
        rot = data.geom(f"{side}_sole").xmat.reshape(3, 3)
        bottom = data.geom(f"{side}_sole").xpos - rot[:, 2] * geom.size[2]
        np.testing.assert_allclose(bottom, data.site(f"{side}_foot").xpos, atol=1e-9)
        np.testing.assert_allclose(bottom[2], 0.0, atol=1e-9)


@pytest.mark.parametrize("name", ["g1", "talos"])
def test_erd_robot_figures(name: str) -> None:
    robot = hqp.robots.load(name)
    model = robot.model()
    urdf = ET.parse(robot.urdf_path).getroot()
    urdf_mass = sum(float(link.find("inertial/mass").get("value"))
                    for link in urdf.iter("link") if link.find("inertial/mass") is not None)
    np.testing.assert_allclose(model.mass, urdf_mass, rtol=1e-12)
    assert model.na == {"g1": 29, "talos": 32}[name]
    limits = {
        j.get("name"): j.find("limit") for j in urdf.iter("joint") if j.get("type") == "revolute"
    }
    for joint in model.joint_names:
        i = model.joint_index(joint)
        assert model.tau_max[i] == pytest.approx(float(limits[joint].get("effort")))
        assert model.q_lower[i] == pytest.approx(float(limits[joint].get("lower")))
        assert model.q_upper[i] == pytest.approx(float(limits[joint].get("upper")))


@pytest.mark.parametrize("name", ROBOTS)
def test_robots_sink_less_than_a_millimetre(name: str) -> None:
    depth = sink_depth(hqp.robots.load(name))
    assert 0.0 < depth < 1e-3


def test_default_contact_parameters_would_sink_more() -> None:
    """MuJoCo's default solref/solimp sink the paper humanoid by more than 1 mm: tuning matters."""
    robot = hqp.robots.load("paper-humanoid")
    assert sink_depth(robot, solref=(0.02, 1.0), solimp=(0.9, 0.95, 0.001, 0.5, 2.0)) > 1e-3


def test_capsules_are_on_existing_frames(robot: Robot) -> None:
    model = robot.model()
    assert len(robot.capsules) >= 15
    for capsule in robot.capsules:
        assert model.has_frame(capsule.frame)
        assert capsule.radius > 0
    # Standing: left and right limbs are apart.
    model.update(robot.q_standing, np.zeros(model.nv))
    by_name = {c.name: c for c in robot.capsules}

    def points(name: str) -> np.ndarray:
        c = by_name[name]
        placement = model.frame_placement(c.frame)
        s = np.linspace(0.0, 1.0, 50)[:, None]
        local = (1 - s) * np.array(c.a) + s * np.array(c.b)
        return local @ placement.rotation.T + placement.translation

    def distance(n1: str, n2: str) -> float:
        p1, p2 = points(n1), points(n2)
        gap = np.linalg.norm(p1[:, None] - p2[None], axis=2).min()
        return float(gap - by_name[n1].radius - by_name[n2].radius)

    left = [c.name for c in robot.capsules if c.name.startswith(("left", "leg_left", "arm_left"))]
    right = [c.name for c in robot.capsules
             if c.name.startswith(("right", "leg_right", "arm_right"))]
    assert len(left) == len(right) >= 6
    for n1 in left:
        for n2 in right:
            assert distance(n1, n2) > 0.0, (n1, n2)
    if robot.name == "paper-humanoid":
        assert distance("left_hand", "trunk") > 0.0
        assert distance("right_hand", "trunk") > 0.0


@pytest.mark.parametrize("name", ["g1", "talos"])
def test_erd_generated_urdf_equals_source(name: str) -> None:
    """The mesh-free URDF (uniform frames as links) has the source URDF's dynamics."""
    from hqp.robots.robot import build_pinocchio_model

    robot = hqp.robots.load(name)
    assert robot.source_urdf_path is not None
    source = build_pinocchio_model(robot.source_urdf_path)
    generated = robot.pinocchio_model()
    assert list(source.names) == list(generated.names)
    for j in range(1, source.njoints):
        np.testing.assert_allclose(source.inertias[j].mass, generated.inertias[j].mass, rtol=1e-11)
        np.testing.assert_allclose(source.inertias[j].lever, generated.inertias[j].lever,
                                   atol=1e-11)
        np.testing.assert_allclose(source.inertias[j].inertia, generated.inertias[j].inertia,
                                   atol=1e-11)
        np.testing.assert_allclose(source.jointPlacements[j].homogeneous,
                                   generated.jointPlacements[j].homogeneous, atol=1e-11)
    for limits in ("lowerPositionLimit", "upperPositionLimit", "effortLimit", "velocityLimit"):
        np.testing.assert_allclose(getattr(source, limits), getattr(generated, limits),
                                   rtol=1e-11)
    # the uniform frames stay on the joints of the source's links they were found on
    names = ["left_foot", "right_foot", "left_hand", "right_hand", "trunk", "pelvis", "head"]
    for frame in names:
        joint = generated.frames[generated.getFrameId(frame)].parentJoint
        assert generated.names[joint] in source.names


def test_generated_files_follow_the_installation(tmp_path, monkeypatch):
    # Two environments with the same example-robot-data share the generated-files directory;
    # the MJCF names the meshes by absolute path, so each installation gets its own files
    # (otherwise a second venv reads the first one's meshes, and fails once it is gone).
    from hqp.robots import DATA_DIR
    from hqp.robots.erd import erd_robots_dir
    from hqp.robots.urdf import load_file

    theirs = hqp.robots.load("g1").mjcf_path
    real = erd_robots_dir()
    robots_dir = tmp_path / "example-robot-data" / "robots"
    copy = robots_dir / "g1_description"
    (copy / "urdf").mkdir(parents=True)
    urdf = "g1_description/urdf/g1_29dof_rev_1_0.urdf"
    (robots_dir / urdf).write_bytes((real / urdf).read_bytes())
    (copy / "meshes").symlink_to(real / "g1_description" / "meshes")
    monkeypatch.setenv("EXAMPLE_ROBOT_DATA_SHARE", str(tmp_path))
    mine = load_file(DATA_DIR / "g1.toml").mjcf_path  # the same URDF, another installation
    assert mine != theirs and mine.exists() and theirs.exists()
