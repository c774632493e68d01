"""Position of a frame's origin in the world (all or selected axes)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hqp.tasks.base import Category
from hqp.tasks.tracking import Gains, VectorTrackingTask, parse_axes

if TYPE_CHECKING:
    from hqp.model import RobotModel


def frame_position_kinematics(
    model: RobotModel, frame: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """World position of a frame's origin and its derivatives at the updated state.

    Returns:
        ``(p, pd, J_lin, a_lin)``: position ``(3,)`` [m], velocity ``(3,)`` [m/s],
        linear rows ``(3, nv)`` of the ``LOCAL_WORLD_ALIGNED`` frame Jacobian and
        the origin's classical acceleration at ``qdd = 0`` ``(3,)`` [m/s^2].

    """
    p = model.frame_placement(frame).translation
    J = model.frame_jacobian(frame)
    v = model.frame_velocity(frame)
    a = model.frame_drift(frame)
    return p, v[:3], J[:3], a[:3]


class PositionTask(VectorTrackingTask):
    """World position ``p(q)`` of a frame's origin (seed 001 ``PositionPrimitive``).

    Task function ``x = S p``, Jacobian ``S J_lin`` (linear rows of the
    ``LOCAL_WORLD_ALIGNED`` frame Jacobian), drift ``S a_lin`` (the origin's
    classical acceleration at ``qdd = 0``). Rows: ``S J_lin qdd = xdd_ref - S a_lin``.

    Args:
        robot: Robot model (the frame is checked here).
        frame: Frame name.
        axes: Selected world axes (``"xz"``, indices, or ``None`` for all).
        name: Task name (default: the frame's name).
        weight: Weight within its level.
        kp: Stiffness of the PD reference [1/s^2].
        kv: Damping [1/s] (``None``: ``2 sqrt(kp)``, critical damping).
        max_velocity: Saturation of the corrective velocity [m/s].
        max_acceleration: Saturation of the feedback acceleration [m/s^2].

    Goal: :meth:`set_goal` with the selected coordinates ``(k,)`` [m].

    Raises:
        InvalidFrame: Unknown frame (lists the frames).
        InvalidInput: Bad axes.
        InvalidGain: Bad gains.

    """

    category = Category.OPERATIONAL

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        *,
        axes: str | Sequence[int] | None = None,
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
        self.axes = parse_axes(axes, 3, self.where())
        self.goal_size = len(self.axes)

    def measure(self, model: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(S p, S pd, S J_lin, S a_lin)``."""
        ax = self.axes
        p, v, J, a = frame_position_kinematics(model, self.frame)
        return p[ax], v[ax], J[ax], a[ax]
