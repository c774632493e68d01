"""Finite-difference checks of task kinematics (shared by the task tests)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hqp.model import RobotModel


def check_kinematics(
    robot: RobotModel,
    kinematics: Callable[[RobotModel, float], object],
    rng: np.random.Generator,
    *,
    n: int = 10,
    eps: float = 1e-6,
    rtol: float = 1e-5,
    t: float = 0.3,
    margin: float = 0.05,
) -> None:
    """Check ``de/dt`` and ``d2e/dt2 = J qdd + drift`` against central differences.

    Along the path ``q(s) = q (+) (s v + s^2/2 qdd)``, ``v(s) = v + s qdd``,
    time ``t + s`` (so a moving goal moves too): the finite difference of the
    error must match the reported rate, and that of the rate must match
    ``J qdd + drift``; and the rate must be affine in ``v`` with slope ``J``.
    """
    other = RobotModel(robot.model, name="fd", floating_base=robot.floating_base)
    for _ in range(n):
        q = robot.random_configuration(rng, margin=margin)
        v = rng.normal(size=robot.nv)
        qdd = rng.normal(size=robot.nv)
        robot.update(q, v)
        kin = kinematics(robot, t)
        e0, r0 = np.array(kin.error), np.array(kin.rate)
        J, drift = np.array(kin.jacobian), np.array(kin.drift)

        def at(s: float, kin_fn=kinematics, q=q, v=v, qdd=qdd):
            other.update(other.integrate(q, s * v + 0.5 * s * s * qdd), v + s * qdd)
            return kin_fn(other, t + s)

        kp, km = at(eps), at(-eps)
        fd_rate = (kp.error - km.error) / (2 * eps)
        fd_acc = (kp.rate - km.rate) / (2 * eps)
        scale_r = 1.0 + np.abs(r0).max()
        scale_a = 1.0 + np.abs(J @ qdd + drift).max()
        np.testing.assert_allclose(fd_rate, r0, atol=rtol * scale_r, err_msg="rate vs FD of error")
        np.testing.assert_allclose(
            fd_acc, J @ qdd + drift, atol=rtol * scale_a, err_msg="J qdd + drift vs FD of rate"
        )
        # Rate affine in v with slope J.
        dv = rng.normal(size=robot.nv)
        other.update(q, v + dv)
        r1 = kinematics(other, t).rate
        np.testing.assert_allclose(r1 - r0, J @ dv, atol=1e-9 * (1 + np.abs(J).max()) * 10)
        np.testing.assert_allclose(e0, kinematics(other, t).error, atol=1e-12)
