import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError, InvalidFrame
from hqp.layout import ContactType, Layout
from hqp.model import RobotModel


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
