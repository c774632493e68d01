"""Gaze: a ray from a head frame points at a target point (2 rows)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.model.geometry import cross3
from hqp.tasks.base import Category
from hqp.tasks.tracking import Gains, TaskKinematics, VectorGoalTask

if TYPE_CHECKING:
    from hqp.model import RobotModel


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


class GazeTask(VectorGoalTask):
    """Point a frame's local axis (the gaze ray) at a world target: 2 image coordinates.

    With ``o, R`` the head frame's origin and rotation, ``g`` the target and
    ``p = R^T (g - o)`` the target in head coordinates, ``d = p / ||p||``,
    ``a`` the gaze axis and ``u, w`` two unit axes completing it to a
    right-handed frame ``(a, u, w)``, the error is the stereographic
    projection of the target direction onto the image plane ``a = 1``:

        e = 2 [u.d, w.d] / (1 + a.d)  = 2 tan(theta / 2) [cos phi, sin phi]

    (``theta``: angle between ray and target; ``e`` ~ the two angles of the
    target in the image for small errors). It is zero only when the ray points
    at the target, and singular only when the target is exactly behind the
    head (where the seed's 2-coordinate gaze has no defined direction). The
    target may move (goal velocity and acceleration enter the drift).

    Derivatives, with ``r = g - o`` and world ``omega``:
    ``dp/dt = R^T (dg/dt - do/dt + r x omega)``, so ``J_p = R^T (-J_lin + [r]x J_ang)``.

    Args:
        robot: Robot model (the frame is checked here).
        frame: Head frame.
        axis: Gaze ray in the frame's coordinates ``(3,)`` (normalised; default ``+x``).
        name: Task name (default ``"gaze"``).
        weight: Weight within its level.
        kp: Stiffness of the PD reference [1/s^2].
        kv: Damping [1/s] (``None``: ``2 sqrt(kp)``, critical damping).
        max_velocity: Saturation of the corrective velocity [image units/s, ~ rad/s].
        max_acceleration: Saturation of the feedback acceleration [image units/s^2].

    Goal: :meth:`set_goal` with the target point ``(3,)`` [m] in the world and
    optional target velocity and acceleration; :meth:`set_trajectory` or
    :meth:`move_to` (the target moves along a minimum-jerk path).

    Raises:
        InvalidFrame: Unknown frame.
        InvalidInput: Zero or bad axis.
        InvalidGain: Bad gains.

    """

    category = Category.OPERATIONAL
    goal_size = 3

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        *,
        axis: Sequence[float] = (1.0, 0.0, 0.0),
        name: str = "gaze",
        weight: float = 1.0,
        kp: float = 100.0,
        kv: float | None = None,
        max_velocity: float = math.inf,
        max_acceleration: float = math.inf,
    ) -> None:
        super().__init__(name, weight, Gains(kp, kv, max_velocity, max_acceleration))
        robot.frame_id(frame, self.where())
        self.frame = frame
        a = check_array(axis, (3,), f"{self.where()}: axis")
        norm = float(np.linalg.norm(a))
        if norm < 1e-9:
            raise InvalidInput(f"{self.where()}: axis must be non-zero")
        a = a / norm
        helper = np.eye(3)[int(np.argmin(np.abs(a)))]
        u = helper - a * (a @ helper)
        u /= np.linalg.norm(u)
        self.axis = a
        self._P = np.vstack([u, cross3(a, u)])  # rows u, w

    def value(self, model: RobotModel) -> np.ndarray:
        """Return the point 1 m ahead on the gaze ray ``(3,)`` [m] (start of :meth:`move_to`)."""
        M = model.frame_placement(self.frame)
        return M.translation + M.rotation @ self.axis

    def kinematics(self, model: RobotModel, t: float = 0.0) -> TaskKinematics:
        """Image coordinates of the target and their derivatives ``(2,)``, ``(2, nv)``."""
        goal = self.goal_at(t)
        g, dg, ddg = goal.position, goal.velocity, goal.acceleration
        M = model.frame_placement(self.frame)
        R, o = M.rotation, M.translation
        J = model.frame_jacobian(self.frame)
        vel = model.frame_velocity(self.frame)
        acc = model.frame_drift(self.frame)
        do, w = vel[:3], vel[3:]
        r = g - o
        dr = dg - do
        Rt = R.T
        p = Rt.dot(r)
        wv = dr + cross3(r, w)  # R dp/dt
        dp = Rt.dot(wv)
        Jp = Rt.dot(_skew(r).dot(J[3:]) - J[:3])
        # R^T d/dt(wv) without qdd, minus omega x wv from d/dt R^T.
        ddp0 = Rt.dot(ddg - acc[:3] + cross3(dr, w) + cross3(r, acc[3:]) - cross3(w, wv))
        norm = float(np.linalg.norm(p))
        if norm < 1e-9:
            raise InvalidInput(f"{self.where()}: the target is at the head frame's origin")
        d = p / norm
        a, P = self.axis, self._P
        n = norm + a @ p
        if n < 1e-12 * norm:
            raise InvalidInput(f"{self.where()}: the target is exactly behind the gaze ray")
        grad_n = d + a
        Pp, Pdp = P @ p, P @ dp
        dn = grad_n @ dp
        hess = (dp @ dp - (d @ dp) ** 2) / norm  # dp^T (I - d d^T) dp / |p|
        e = 2.0 * Pp / n
        Df = 2.0 * (P / n - np.outer(Pp, grad_n) / n**2)
        rate = Df @ dp
        drift = Df @ ddp0 + 2.0 * (
            -2.0 * Pdp * dn / n**2 - Pp * hess / n**2 + 2.0 * Pp * dn**2 / n**3
        )
        return TaskKinematics(e, rate, Df @ Jp, drift)
