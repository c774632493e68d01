import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError, InvalidFrame
from hqp.model import RobotModel
from hqp.model.layout import ContactType, Layout


@pytest.fixture(scope="module")
def sample() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


def test_unknown_frame_lists_frames(sample: RobotModel) -> None:
    with pytest.raises(InvalidFrame, match="frames in the model: .*universe"):
        sample.frame_id("no_such_frame")


def test_bad_state_shape_raises(sample: RobotModel) -> None:
    with pytest.raises(HQPError, match="expected"):
        sample.update(np.zeros(3), np.zeros(sample.nv))
    q = sample.neutral()
    q[0] = np.nan
    with pytest.raises(HQPError, match="NaN"):
        sample.update(q, np.zeros(sample.nv))


def test_drift_terms_match_finite_differences(sample: RobotModel) -> None:
    rng = np.random.default_rng(1)
    other = RobotModel(sample.model, name="other")
    frames = [f for f in sample.frame_names if "wrist" in f][:2]
    eps = 1e-7
    for _ in range(10):
        q = sample.random_configuration(rng)
        v = rng.normal(size=sample.nv)
        sample.update(q, v)
        other.update(sample.integrate(q, v * eps), v)  # qdd = 0 along the step
        for name in frames:
            fd = (other.frame_velocity(name) - sample.frame_velocity(name)) / eps
            np.testing.assert_allclose(
                fd, sample.frame_drift(name), atol=1e-4 * (1 + np.abs(fd).max())
            )
        fd_com = (other.com_velocity - sample.com_velocity) / eps
        np.testing.assert_allclose(fd_com, sample.com_drift, atol=1e-4 * (1 + np.abs(fd_com).max()))
        np.testing.assert_allclose(sample.com_jacobian @ v, sample.com_velocity, atol=1e-10)
        np.testing.assert_allclose(sample.M, sample.M.T)


def test_layout_slots() -> None:
    layout = Layout.build(
        10, [("left", "lf", ContactType.SURFACE), ("hand", "rh", ContactType.POINT)]
    )
    assert layout.n == 19
    assert layout.contact("left").slice == slice(10, 16)
    assert layout.contact("hand").slice == slice(16, 19)
    with pytest.raises(HQPError, match="declared contacts: left, hand"):
        layout.contact("right")


def _reference_terms(model: pin.Model, q: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
    """Every quantity of an update by the individual pinocchio algorithms (separate data)."""
    data = model.createData()
    nv = model.nv
    pin.crba(model, data, q)
    M = np.triu(data.M) + np.triu(data.M, 1).T
    h = pin.nonLinearEffects(model, data, q, v).copy()
    g = pin.computeGeneralizedGravity(model, data, q).copy()
    data.vcom[0] = np.zeros(3)  # computeCentroidalMapTimeVariation reads it (pinocchio 3.8)
    pin.computeCentroidalMapTimeVariation(model, data, q, v)
    Ag, dAgv = data.Ag.copy(), data.dAg @ v
    Jcom = pin.jacobianCenterOfMass(model, data, q, False).copy()
    pin.centerOfMass(model, data, q, v, np.zeros(nv))
    return {"M": M, "h": h, "gravity": g, "centroidal_matrix": Ag, "centroidal_drift": dAgv,
            "com_jacobian": Jcom, "com": data.com[0].copy(), "com_velocity": data.vcom[0].copy(),
            "com_drift": data.acom[0].copy()}


@pytest.mark.parametrize("robot_name", ["sample", "g1", "talos"])
def test_single_pass_matches_separate_algorithms(sample: RobotModel, robot_name: str) -> None:
    """One computeAllTerms pass per update gives the separate algorithms' results (1e-12)."""
    if robot_name == "sample":
        robot = sample
    else:
        from hqp.robots import load

        robot = load(robot_name).model()
    rng = np.random.default_rng(7)
    frames = [f for f in robot.frame_names if "foot" in f or "wrist" in f or "hand" in f][:4]
    for _ in range(5):
        q = robot.random_configuration(rng)
        v = rng.normal(size=robot.nv)
        robot.update(q, v)
        for name, ref in _reference_terms(robot.model, q, v).items():
            got = getattr(robot, name)
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * max(1.0, np.abs(ref).max()),
                                       err_msg=name)
        data = robot.model.createData()
        pin.forwardKinematics(robot.model, data, q, v, np.zeros(robot.nv))
        pin.computeJointJacobians(robot.model, data, q)
        pin.updateFramePlacements(robot.model, data)
        for frame in frames:
            fid = robot.frame_id(frame)
            for ref_frame in (pin.LOCAL_WORLD_ALIGNED, pin.LOCAL, pin.WORLD):
                np.testing.assert_allclose(
                    robot.frame_jacobian(frame, ref_frame),
                    pin.getFrameJacobian(robot.model, data, fid, ref_frame), rtol=0, atol=1e-12)
                np.testing.assert_allclose(
                    robot.frame_velocity(frame, ref_frame),
                    pin.getFrameVelocity(robot.model, data, fid, ref_frame).vector,
                    rtol=0, atol=1e-12)
                np.testing.assert_allclose(
                    robot.frame_drift(frame, ref_frame),
                    pin.getFrameClassicalAcceleration(robot.model, data, fid, ref_frame).vector,
                    rtol=0, atol=1e-11)
            np.testing.assert_allclose(robot.frame_placement(frame).homogeneous,
                                       data.oMf[fid].homogeneous, rtol=0, atol=1e-12)


def test_update_gives_fresh_arrays(sample: RobotModel) -> None:
    """Arrays read after one update are not overwritten by the next (callers may keep them)."""
    rng = np.random.default_rng(2)
    sample.update(sample.random_configuration(rng), rng.normal(size=sample.nv))
    kept = {k: np.array(getattr(sample, k)) for k in ("M", "h", "com", "com_jacobian")}
    refs = {k: getattr(sample, k) for k in kept}
    sample.update(sample.random_configuration(rng), rng.normal(size=sample.nv))
    for k, value in kept.items():
        np.testing.assert_array_equal(refs[k], value)
        assert not np.array_equal(getattr(sample, k), value)
