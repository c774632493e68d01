"""Centre of gravity (hierarchy paper eq. 24): full 3D or horizontal (static balance)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput
from hqp.tasks.base import Category
from hqp.tasks.tracking import Gains, VectorTrackingTask

if TYPE_CHECKING:
    from hqp.model import RobotModel


def support_center(
    model: RobotModel, frames: Sequence[str], where: str = "support_center"
) -> np.ndarray:
    """Mean of the world positions of ``frames`` ``(3,)`` [m], e.g. the centre of the feet.

    Raises:
        InvalidInput: No frames.
        InvalidFrame: An unknown frame (lists the frames).

    """
    if not frames:
        raise InvalidInput(f"{where}: no frames given")
    return np.mean([model.data.oMf[model.frame_id(f, where)].translation for f in frames], axis=0)


class CoMTask(VectorTrackingTask):
    """Centre of gravity ``x_cog = sum m_i x_com(i) / M`` and ``J_cog`` (seed 003 eq. 24).

    Task function ``x = S c(q)`` with ``S`` the selection of the axes (all three,
    or ``x, y`` for the static-balance primitive: the horizontal position
    over the support, eq. 25 ``V_COG = ||x_cog - x_feet||^2``), Jacobian
    ``S J_cog`` and drift ``S dJ_cog v`` (pinocchio's centre-of-mass
    acceleration at ``qdd = 0``). Rows: ``S J_cog qdd = xdd_ref - S dJ_cog v``.

    Args:
        robot: Robot model (used for validation only).
        horizontal: Control only ``x, y`` (2 rows) instead of ``x, y, z``.
        name: Task name.
        weight: Weight within its level.
        kp: Stiffness of the PD reference [1/s^2].
        kv: Damping [1/s] (``None``: ``2 sqrt(kp)``, critical damping).
        max_velocity: Saturation of the corrective velocity [m/s].
        max_acceleration: Saturation of the feedback acceleration [m/s^2].

    Goal: :meth:`set_goal` with ``(2,)`` or ``(3,)`` [m] (e.g. from
    :func:`support_center`), optional goal velocity and acceleration, or
    :meth:`set_trajectory` / :meth:`move_to`.

    """

    category = Category.BALANCE

    def __init__(
        self,
        robot: RobotModel,
        *,
        horizontal: bool = False,
        name: str = "com",
        weight: float = 1.0,
        kp: float = 100.0,
        kv: float | None = None,
        max_velocity: float = math.inf,
        max_acceleration: float = math.inf,
    ) -> None:
        super().__init__(name, weight, Gains(kp, kv, max_velocity, max_acceleration))
        self.horizontal = bool(horizontal)
        self.goal_size = 2 if self.horizontal else 3
        self._sel = slice(0, self.goal_size)

    def measure(self, model: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(x, xd, J, dJ v)`` of the selected centre-of-gravity coordinates."""
        s = self._sel
        return model.com[s], model.com_velocity[s], model.com_jacobian[s], model.com_drift[s]
