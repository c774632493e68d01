from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import hqp
import hqp.robots
from hqp.model import RobotModel
from hqp.sim.convert import StateMap, rotation_from_quat_xyzw

ROBOTS = ["paper-humanoid", "g1", "talos"]


@pytest.fixture(scope="module", params=ROBOTS)
def setup(request: pytest.FixtureRequest) -> tuple[RobotModel, mujoco.MjModel, StateMap]:
    robot = hqp.robots.load(request.param)
    model = robot.model()
    mj = robot.mujoco_model()
    return model, mj, StateMap(model, mj)


def random_state(model: RobotModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return model.random_configuration(rng), rng.normal(size=model.nv)


def test_velocity_convention_of_mujoco_free_joint() -> None:
    """MuJoCo's free-joint qvel: linear = world-frame velocity of the origin, angular = body frame.

    Checked against finite differences of mj_integratePos-independent quantities: the body
    origin's world position (xpos) and orientation (xmat) after a small explicit step.
    """
    xml = """<mujoco><option gravity="0 0 0"/><worldbody><body name="b" pos="0 0 1">
      <freejoint/><inertial pos="0.1 0.2 0.3" mass="2" diaginertia="0.1 0.2 0.3"/>
      </body></worldbody></mujoco>"""
    mj = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(3)
    for _ in range(5):
        quat = rng.normal(size=4)
        data.qpos[:] = np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat)])
        data.qvel[:] = rng.normal(size=6)
        mujoco.mj_kinematics(mj, data)
        p0, R0 = data.xpos[1].copy(), data.xmat[1].reshape(3, 3).copy()
        eps = 1e-7
        qpos = data.qpos.copy()
        mujoco.mj_integratePos(mj, data.qpos, data.qvel, eps)
        mujoco.mj_kinematics(mj, data)
        p1, R1 = data.xpos[1].copy(), data.xmat[1].reshape(3, 3).copy()
        linear_world = (p1 - p0) / eps
        omega_body = pin.log3(R0.T @ R1) / eps
        np.testing.assert_allclose(linear_world, data.qvel[:3], atol=1e-6)
        np.testing.assert_allclose(omega_body, data.qvel[3:], atol=1e-6)
        # So the linear part is NOT in the body frame (unless R = I):
        assert np.linalg.norm(R0.T @ data.qvel[:3] - data.qvel[:3]) > 1e-3
        data.qpos[:] = qpos


def test_round_trips(setup: tuple[RobotModel, mujoco.MjModel, StateMap]) -> None:
    model, mj, smap = setup
    rng = np.random.default_rng(0)
    for _ in range(20):
        q, v = random_state(model, rng)
        qpos = smap.qpos_from_q(q)
        np.testing.assert_allclose(smap.q_from_qpos(qpos), q, atol=1e-15)
        qvel = smap.qvel_from_v(v, q)
        np.testing.assert_allclose(smap.v_from_qvel(qvel, q), v, atol=1e-14)
        np.testing.assert_allclose(smap.velocity_matrix(q) @ v, qvel, atol=1e-14)
        tau = rng.normal(size=model.na)
        np.testing.assert_allclose(smap.tau_from_ctrl(smap.ctrl_from_tau(tau)), tau, atol=1e-15)


def test_frames_mass_matrix_and_bias_agree(
    setup: tuple[RobotModel, mujoco.MjModel, StateMap],
) -> None:
    """At 20 random states: frame positions, M_pin = T^T M_mj T, h_pin = T^T (c + M_mj dT v)."""
    model, mj, smap = setup
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(1)
    sites = [mj.site(i).name for i in range(mj.nsite)]
    for name in ("left_foot", "right_foot", "left_hand", "right_hand", "trunk", "pelvis"):
        assert name in sites
    bodies = [mj.body(i).name for i in range(1, mj.nbody) if model.has_frame(mj.body(i).name)]
    assert len(bodies) == model.na + 1  # every MuJoCo body is a pinocchio frame
    for _ in range(20):
        q, v = random_state(model, rng)
        data.qpos[:] = smap.qpos_from_q(q)
        data.qvel[:] = smap.qvel_from_v(v, q)
        mujoco.mj_forward(mj, data)
        model.update(q, v)
        for name in sites:
            placement = model.frame_placement(name)
            np.testing.assert_allclose(data.site(name).xpos, placement.translation, atol=1e-9)
            np.testing.assert_allclose(
                data.site(name).xmat.reshape(3, 3), placement.rotation, atol=1e-9
            )
        for name in bodies:
            np.testing.assert_allclose(
                data.body(name).xpos, model.frame_placement(name).translation, atol=1e-9
            )
        scale = 1.0 + np.abs(model.M).max()
        np.testing.assert_allclose(smap.mass_matrix(data), model.M, atol=1e-9 * scale)
        scale = 1.0 + np.abs(model.h).max()
        np.testing.assert_allclose(smap.bias_force(data), model.h, atol=1e-9 * scale)


def test_bias_needs_the_dT_term(setup: tuple[RobotModel, mujoco.MjModel, StateMap]) -> None:
    """Without the T^T M_mj dT v term the bias forces differ (the test above can fail)."""
    model, mj, smap = setup
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(2)
    q, v = random_state(model, rng)
    data.qpos[:] = smap.qpos_from_q(q)
    data.qvel[:] = smap.qvel_from_v(v, q)
    mujoco.mj_forward(mj, data)
    model.update(q, v)
    naive = smap.velocity_matrix(q).T @ data.qfrc_bias
    assert np.abs(naive - model.h).max() > 1e-3


def test_accelerations_agree(setup: tuple[RobotModel, mujoco.MjModel, StateMap]) -> None:
    """Forward dynamics with the same joint torques: qacc = T vdot + dT v (no contact)."""
    model, mj, smap = setup
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(4)
    for _ in range(5):
        q, v = random_state(model, rng)
        q[2] += 10.0  # far above the floor: no contact
        tau = rng.normal(size=model.na) * 5
        data.qpos[:] = smap.qpos_from_q(q)
        data.qvel[:] = smap.qvel_from_v(v, q)
        data.ctrl[:] = smap.ctrl_from_tau(tau)
        mujoco.mj_forward(mj, data)
        model.update(q, v)
        vdot = np.linalg.solve(model.M, model.selection().T @ tau - model.h)
        dTv = np.zeros(mj.nv)
        dTv[:3] = smap.base_rotation(q) @ np.cross(v[3:6], v[:3])
        expected = smap.velocity_matrix(q) @ vdot + dTv
        np.testing.assert_allclose(data.qacc, expected, atol=1e-7 * (1 + np.abs(expected).max()))


def test_mismatched_models_raise() -> None:
    paper = hqp.robots.load("paper-humanoid")
    model = paper.model()
    xml = """<mujoco><worldbody><body><freejoint/><inertial pos="0 0 0" mass="1"
      diaginertia="1 1 1"/></body></worldbody></mujoco>"""
    with pytest.raises(hqp.HQPError, match="not in the MuJoCo model"):
        StateMap(model, mujoco.MjModel.from_xml_string(xml))
    with pytest.raises(hqp.HQPError, match="expected shape"):
        StateMap(model, paper.mujoco_model()).ctrl_from_tau(np.zeros(3))


def test_rotation_is_pinocchio_s_to_the_last_bit() -> None:
    """The one rotation of the conversion: Eigen's normalized().toRotationMatrix(), same bits."""
    rng = np.random.default_rng(5)
    out = np.empty((3, 3))
    for i in range(2000):
        quat = rng.normal(size=4)
        if i % 2:  # MuJoCo's quaternions: unit up to round-off
            quat = quat / np.linalg.norm(quat) * (1.0 + 1e-13 * rng.normal())
        x, y, z, w = quat
        expected = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
        assert np.array_equal(rotation_from_quat_xyzw(quat, out), expected)
    expected = pin.Quaternion(0.0, 0.0, 0.0, 0.0).normalized().toRotationMatrix()
    assert np.array_equal(rotation_from_quat_xyzw(np.zeros(4), out), expected)


def test_state_from_data_against_pinocchio(
    setup: tuple[RobotModel, mujoco.MjModel, StateMap],
) -> None:
    """At random states: q and v read back; MuJoCo's free-joint linear velocity is the base
    origin's world velocity (pinocchio's LOCAL_WORLD_ALIGNED joint velocity), its angular
    velocity the base-frame one; the returned arrays do not alias MuJoCo's."""
    model, mj, smap = setup
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(6)
    pdata = model.model.createData()
    for _ in range(20):
        q, v = random_state(model, rng)
        data.qpos[:] = smap.qpos_from_q(q)
        data.qvel[:] = smap.qvel_from_v(v, q)
        q_read, v_read = smap.state_from_data(data)
        np.testing.assert_allclose(q_read, q, atol=1e-15)
        np.testing.assert_allclose(v_read, v, atol=1e-14)
        np.testing.assert_array_equal(v_read, smap.v_from_qvel(data.qvel, q_read))
        pin.forwardKinematics(model.model, pdata, q_read, v_read)
        base = pin.getVelocity(model.model, pdata, 1, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(data.qvel[:3], base.linear, atol=1e-12)
        local = pin.getVelocity(model.model, pdata, 1, pin.ReferenceFrame.LOCAL)
        np.testing.assert_allclose(data.qvel[3:6], local.angular, atol=1e-12)
        q_read[:] = 0.0
        v_read[:] = 0.0
        assert np.abs(data.qpos).max() > 0.0 and np.abs(data.qvel).max() > 0.0
