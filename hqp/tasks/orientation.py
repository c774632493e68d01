"""Orientation of a frame: the error ``log3(R_goal^T R)`` with the Jacobian of the log."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from hqp.model.geometry import cross3
from hqp.tasks.base import Category
from hqp.tasks.reference import MinimumJerkRotation, TrajectorySample, check_rotation
from hqp.tasks.tracking import Gains, TaskKinematics, TrackingTask

if TYPE_CHECKING:
    from hqp.model import RobotModel


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _jlog3_coefficients(th: float) -> tuple[float, float]:
    """``beta(theta)`` and ``gamma = beta'(theta) / theta`` of :func:`jlog3_rate`."""
    if th < 1e-2:
        t2 = th * th
        beta = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
        gamma = 1.0 / 360.0 + t2 / 7560.0 + t2 * t2 / 201600.0
    else:
        s, c = math.sin(th), math.cos(th)
        beta = 1.0 / th**2 - (1.0 + c) / (2.0 * th * s)
        gamma = (-2.0 / th**3 + (th + s) / (2.0 * th**2 * (1.0 - c))) / th
    return beta, gamma


def jlog3_rate_times(e: np.ndarray, de: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """``jlog3_rate(e, de) @ xi`` ``(3,)`` without forming the matrix.

    With ``[a]x [b]x = b a^T - (a . b) I``:
    ``[e]x^2 xi = e (e . xi) - |e|^2 xi`` and
    ``([de]x [e]x + [e]x [de]x) xi = e (de . xi) + de (e . xi) - 2 (e . de) xi``.
    """
    e0, e1, e2 = e.tolist()
    d0, d1, d2 = de.tolist()
    x0, x1, x2 = xi.tolist()
    ee = e0 * e0 + e1 * e1 + e2 * e2
    ed = e0 * d0 + e1 * d1 + e2 * d2
    ex = e0 * x0 + e1 * x1 + e2 * x2
    dx = d0 * x0 + d1 * x1 + d2 * x2
    beta, gamma = _jlog3_coefficients(math.sqrt(ee))
    g = gamma * ed
    ce = g * ex + beta * dx  # coefficient of e
    cx = -g * ee - 2.0 * beta * ed  # coefficient of xi
    cd = beta * ex  # coefficient of de
    return np.array([
        0.5 * (d1 * x2 - d2 * x1) + ce * e0 + cd * d0 + cx * x0,
        0.5 * (d2 * x0 - d0 * x2) + ce * e1 + cd * d1 + cx * x1,
        0.5 * (d0 * x1 - d1 * x0) + ce * e2 + cd * d2 + cx * x2,
    ])


def jlog3_rate(e: np.ndarray, de: np.ndarray) -> np.ndarray:
    """Time derivative of ``Jlog3`` ``(3, 3)`` along ``e(t) = log3(E(t))`` with rate ``de``.

    ``Jlog3(e) = I + [e]x / 2 + beta(theta) [e]x^2`` with ``theta = ||e||`` and
    ``beta = 1/theta^2 - (1 + cos theta) / (2 theta sin theta)``, so
    ``d/dt Jlog3 = [de]x / 2 + (beta'/theta) (e . de) [e]x^2 + beta ([de]x [e]x + [e]x [de]x)``.
    Series below ``theta = 1e-2`` (pinocchio's ``Hlog3`` returns NaN at the identity,
    i.e. exactly at the goal).
    """
    beta, gamma = _jlog3_coefficients(float(np.linalg.norm(e)))
    E, dE = _skew(e), _skew(de)
    return 0.5 * dE + gamma * float(e @ de) * (E @ E) + beta * (dE @ E + E @ dE)


def orientation_kinematics(
    model: RobotModel, frame: str, goal: TrajectorySample
) -> TaskKinematics:
    """Kinematics of ``e = log3(E)``, ``E = R_g^T R`` (goal frame coordinates) [rad].

    With ``omega`` the frame's and ``omega_g`` the goal's world angular
    velocity, ``E`` moves with the local velocity ``xi = R^T (omega - omega_g)``, so

        de/dt   = Jlog3(E) xi,
        d2e/dt2 = Jlog3(E) R^T J_ang qdd
                  + Jlog3(E) R^T (a_ang + omega x omega_g - alpha_g) + Hlog3(E, xi) xi,

    with ``J_ang`` and ``a_ang`` the angular rows of the ``LOCAL_WORLD_ALIGNED``
    Jacobian and drift, ``Jlog3`` the Jacobian of the log (not the frame's
    angular Jacobian) and ``Hlog3(E, xi) = d Jlog3(E exp(s xi)) / ds`` at ``s = 0``
    (:func:`jlog3_rate`, applied to ``xi`` by :func:`jlog3_rate_times`; finite at the identity).
    """
    Rg = goal.position
    wg = goal.velocity
    ag = goal.acceleration
    R = model.frame_placement(frame).rotation
    w = model.frame_velocity(frame)[3:]
    a_ang = model.frame_drift(frame)[3:]
    Rt = R.T
    E = Rg.T.dot(R)
    e = pin.log3(E)
    Jlog = pin.Jlog3(E)
    xi = Rt.dot(w - wg)
    JR = Jlog.dot(Rt)
    de = Jlog.dot(xi)
    drift = JR.dot(a_ang + cross3(w, wg) - ag) + jlog3_rate_times(e, de, xi)
    return TaskKinematics(e, de, JR.dot(model.frame_jacobian(frame)[3:]), drift)


class OrientationTask(TrackingTask):
    """Orientation of a frame: ``e = log3(R_goal^T R)`` (3 rows) [rad].

    The Jacobian of this error is ``Jlog3(E) R^T J_ang`` (Jacobian of the log
    times the frame's angular Jacobian in the frame's local axes), not the
    frame's angular Jacobian; the drift is consistent with it
    (:func:`orientation_kinematics`). The error is in the goal's axes.

    Args:
        robot: Robot model (the frame is checked here).
        frame: Frame name.
        name: Task name (default: the frame's name).
        weight: Weight within its level.
        kp: Stiffness of the PD reference [1/s^2].
        kv: Damping [1/s] (``None``: ``2 sqrt(kp)``, critical damping).
        max_velocity: Saturation of the corrective velocity [rad/s].
        max_acceleration: Saturation of the feedback acceleration [rad/s^2].

    Goal: :meth:`set_goal` with a rotation ``(3, 3)`` (``R_world_goal``) and an
    optional world angular velocity and acceleration ``(3,)``; or
    :meth:`set_trajectory` (samples: rotation, world angular velocity and
    acceleration), or :meth:`move_to` (a :class:`MinimumJerkRotation`).

    Raises:
        InvalidFrame: Unknown frame.
        InvalidGain: Bad gains.

    """

    category = Category.OPERATIONAL

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        *,
        name: str | None = None,
        weight: float = 1.0,
        kp: float = 100.0,
        kv: float | None = None,
        max_velocity: float = math.inf,
        max_acceleration: float = math.inf,
    ) -> None:
        super().__init__(name or frame, weight, Gains(kp, kv, max_velocity, max_acceleration))
        robot.frame_id(frame, self.where())
        self.frame = frame

    def _check_goal(
        self, goal: object, velocity: object | None, acceleration: object | None
    ) -> TrajectorySample:
        R = check_rotation(goal, f"{self.where()}: goal")
        return self._goal_sample(R, velocity, acceleration, 3)

    def set_goal(
        self, goal: object, velocity: object | None = None, acceleration: object | None = None
    ) -> None:
        """Set the goal rotation ``(3, 3)`` (copied), optional world angular velocity/acceleration.

        Raises:
            InvalidInput: Not a rotation, wrong shape or NaN (names the primitive).

        """
        self._store_goal(self._check_goal(goal, velocity, acceleration))

    def value(self, model: RobotModel) -> np.ndarray:
        """Return the current rotation ``R_world_frame`` ``(3, 3)``."""
        return model.frame_placement(self.frame).rotation.copy()

    def move_to(self, model: RobotModel, goal: object, duration: float, t0: float) -> None:
        """Reach ``goal`` along a :class:`MinimumJerkRotation` from the current rotation."""
        R = self._check_goal(goal, None, None).position
        self.set_trajectory(MinimumJerkRotation(self.value(model), R, duration, t0))

    def kinematics(self, model: RobotModel, t: float = 0.0) -> TaskKinematics:
        """See :func:`orientation_kinematics`."""
        return orientation_kinematics(model, self.frame, self.goal_at(t))
