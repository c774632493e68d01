"""Actuation limits: joint torques within their bounds.

The torques are an affine map of ``x = [qdd | f_1 | ... | f_k]``
(:func:`hqp.tasks.dynamics.torque_map`):

    tau = S (M qdd + h - sum_c J_c^T f_c) = T x + t0,

so the bounds ``-tau_max <= tau <= tau_max`` are the inequality rows

    -tau_max - t0 <= T x <= tau_max - t0        (na rows)

over every contact slot of the layout (inactive slots are zero).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidGain, check_array
from hqp.tasks.base import Category, Rows, Task
from hqp.tasks.dynamics import torque_map

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout


class TorqueLimits(Task):
    """``-tau_max <= S (M qdd + h - J_c^T f) <= tau_max`` (CONTACT_LIMITS).

    Args:
        name: Task name.
        tau_max: Torque bounds over the actuated joints ``(na,)`` or a scalar
            [N m] (``inf`` entries: unbounded); default: the model's ``tau_max``.
        scale: Fraction of the bounds used (``0 < scale <= 1``), a margin for
            model errors.
        weight: Weight within its level.

    Raises:
        InvalidGain: Negative or NaN bounds, or ``scale`` outside ``(0, 1]``.

    """

    category = Category.CONTACT_LIMITS

    def __init__(
        self,
        name: str = "torque_limits",
        tau_max: np.ndarray | float | None = None,
        *,
        scale: float = 1.0,
        weight: float = 1.0,
    ) -> None:
        super().__init__(name, weight)
        if not (0.0 < float(scale) <= 1.0):
            raise InvalidGain(f"{self.where()}: scale must be in (0, 1], got {scale}")
        self.scale = float(scale)
        self.tau_max: np.ndarray | None = None
        if tau_max is not None:
            where = f"{self.where()}: tau_max"
            arr = check_array(np.atleast_1d(tau_max), (None,), where, allow_inf=True)
            if np.any(arr < 0):
                raise InvalidGain(f"{self.where()}: tau_max must be >= 0, got {arr}")
            self.tau_max = arr

    def bounds(self, model: RobotModel) -> np.ndarray:
        """Torque bounds ``(na,)`` [N m] used at ``model`` (after ``scale``).

        Raises:
            InvalidGain: ``tau_max`` of a size other than 1 or ``na``.

        """
        if self.tau_max is None:
            tau = model.tau_max
        elif self.tau_max.size in (1, model.na):
            tau = np.broadcast_to(self.tau_max, (model.na,))
        else:
            raise InvalidGain(
                f"{self.where()}: tau_max has {self.tau_max.size} entries, "
                f"robot has {model.na} joints"
            )
        return self.scale * np.asarray(tau, dtype=float)

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Inequality rows ``(na, n)``.

        Raises:
            InvalidFrame: A contact frame of the layout is not in the model.

        """
        T, t0 = torque_map(model, layout, self.where())
        tau = self.bounds(model)
        return Rows(C=T, lower=-tau - t0, upper=tau - t0)
