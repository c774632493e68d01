"""Minimise effort: the joint torques as least-squares rows over ``x = [qdd | f]``."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput
from hqp.tasks.base import Category, Rows, Task
from hqp.tasks.dynamics import torque_map

if TYPE_CHECKING:
    from hqp.layout import Layout
    from hqp.model import RobotModel


class EffortTask(Task):
    """Minimise the actuated torques ``tau = S (M qdd + h - sum_c J_c^T f_c)``.

    Rows ``W T x = -W t0`` with ``tau = T x + t0`` from
    :func:`hqp.tasks.dynamics.torque_map` (every contact slot of the layout
    enters) and ``W = diag(1 / tau_max)`` when ``normalize`` (each torque as
    a fraction of its limit; joints without a finite positive limit keep
    weight 1), else the identity. In the least-squares sense of a level this
    minimises ``||W tau||^2``.

    Args:
        robot: Robot model (torque limits for the normalisation).
        normalize: Divide each torque by its limit.
        name: Task name.
        weight: Weight within its level.

    """

    category = Category.POSTURE

    def __init__(
        self,
        robot: RobotModel,
        *,
        normalize: bool = True,
        name: str = "effort",
        weight: float = 1.0,
    ) -> None:
        super().__init__(name, weight)
        self.normalize = bool(normalize)
        lim = np.asarray(robot.tau_max, dtype=float)
        ok = np.isfinite(lim) & (lim > 0.0)
        inv = np.where(ok, 1.0 / np.where(ok, lim, 1.0), 1.0)
        self._w = inv if normalize else np.ones(robot.na)

    def rows(self, state: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Equality rows ``W T x = -W t0`` ``(na, n)`` (target: zero torque).

        Raises:
            InvalidInput: A layout that does not match the robot.
            InvalidFrame: A contact frame not in the model.

        """
        if layout.nv != state.nv or self._w.shape[0] != state.na:
            raise InvalidInput(f"{self.where()}: layout or robot does not match the task's robot")
        T, t0 = torque_map(state, layout, self.where())
        return Rows(A=self._w[:, None] * T, b=-self._w * t0)

    def error(self) -> np.ndarray:
        """Empty: the task has no goal other than zero torque."""
        return np.zeros(0)
