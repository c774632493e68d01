"""The native robot model (``hqp._core._ext.RobotCore``) against :class:`hqp.model.RobotModel`.

Both run pinocchio (the C++ API against the Python bindings of the same wheel), so every
quantity of a step agrees to rounding: 1e-10 relative at 10 random states of each robot.
"""

from __future__ import annotations

import numpy as np
import pytest

from hqp import robots
from hqp.robots.robot import ROOT_JOINT

core = pytest.importorskip("hqp._core._ext")


def native_model(robot):
    frames = [(name, parent, placement.homogeneous)
              for name, (parent, placement) in robot.extra_frames.items()]
    return core.RobotCore(str(robot.urdf_path), ROOT_JOINT, frames)


def _close(a, b, what):
    scale = max(1.0, float(np.abs(b).max()))
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * scale, err_msg=what)


@pytest.mark.parametrize("name", robots.NAMES)
def test_native_model_matches_the_python_model(name):
    robot = robots.load(name)
    py = robot.model()
    nat = native_model(robot)
    assert (nat.nq, nat.nv) == (py.nq, py.nv)
    assert nat.mass == pytest.approx(py.mass, rel=1e-12)
    frames = [robot.base_frame, *robot.feet, *robot.hands]
    rng = np.random.default_rng(11)
    for _ in range(10):
        q = py.random_configuration(rng)
        v = rng.normal(size=py.nv)
        py.update(q, v)
        nat.update(q, v)
        for what in ("M", "h", "com", "com_velocity", "com_drift", "com_jacobian",
                     "centroidal_matrix", "centroidal_drift"):
            _close(getattr(nat, what), getattr(py, what), what)
        _close(nat.gravity, py.gravity, "gravity")
        np.testing.assert_array_equal(nat.M, nat.M.T)
        for frame in frames:
            fid = nat.frame_id(frame)
            assert fid == py.frame_id(frame)
            _close(nat.frame_jacobian(fid), py.frame_jacobian(frame), frame + " J")
            _close(nat.frame_velocity(fid), py.frame_velocity(frame), frame + " velocity")
            _close(nat.frame_drift(fid), py.frame_drift(frame), frame + " drift")
            _close(nat.frame_placement(fid), py.frame_placement(frame).homogeneous,
                   frame + " placement")


def test_native_drift_is_the_derivative_of_the_frame_velocity():
    """Finite differences: the classical acceleration at qdd = 0 (the drift) is the time
    derivative of the frame's LOCAL_WORLD_ALIGNED velocity along q(t) = q + v t, v fixed."""
    robot = robots.load("g1")
    nat = native_model(robot)
    py = robot.model()
    rng = np.random.default_rng(5)
    q = py.random_configuration(rng, margin=0.2)
    v = rng.normal(size=py.nv) * 0.3
    dt = 1e-6
    for frame in (robot.hands[0], robot.feet[1]):
        fid = nat.frame_id(frame)
        nat.update(q, v)
        drift, vel0 = nat.frame_drift(fid), nat.frame_velocity(fid)
        nat.update(py.integrate(q, v * dt), v)
        rate = (nat.frame_velocity(fid) - vel0) / dt
        np.testing.assert_allclose(rate, drift, rtol=0, atol=1e-5 * max(1.0, np.abs(drift).max()))


def test_native_model_rejects_bad_input():
    robot = robots.load("paper-humanoid")
    with pytest.raises(ValueError, match="expected"):
        native_model(robot).update(np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match="missing"):
        core.RobotCore(str(robot.urdf_path), ROOT_JOINT,
                       [("tool", "no_such_frame", np.eye(4))])
    with pytest.raises(ValueError, match="nope.urdf"):
        core.RobotCore("/nonexistent/nope.urdf", ROOT_JOINT, [])
