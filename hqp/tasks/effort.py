"""Minimise effort: the joint torques as least-squares rows over ``x = [qdd | f]``."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput
from hqp.tasks.base import Category, Rows, Task
from hqp.tasks.dynamics import torque_map

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout


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

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Equality rows ``W T x = -W t0`` ``(na, n)`` (target: zero torque).

        Raises:
            InvalidInput: A layout that does not match the robot.
            InvalidFrame: A contact frame not in the model.

        """
        if layout.nv != model.nv or self._w.shape[0] != model.na:
            raise InvalidInput(f"{self.where()}: layout or robot does not match the task's robot")
        T, t0 = torque_map(model, layout, self.where())
        return Rows(A=self._w[:, None] * T, b=-self._w * t0)

    def error(self) -> np.ndarray:
        """Empty: the task has no goal other than zero torque."""
        return np.zeros(0)


class ForceRegularization(Task):
    """Minimise the contact wrenches ``||f||^2 / (m g)^2`` over every contact slot.

    Rows ``[0 | I / (m g)] x = 0`` over ``x = [qdd | f_1 | ... | f_k]`` (``m g`` the robot's
    weight, so a row is a fraction of it). The net contact wrench is fixed by the dynamics
    once the accelerations are; what this task chooses is how it is shared between the
    contacts (the internal forces of Sentis, Park and Khatib, T-RO 2010), which no motion task
    sees. Placed, weighted, in the lowest level it keeps that level from buying a tiny
    decrease of its cost with contact forces at the corners of the friction pyramids, which
    otherwise jump from one step to the next (measured on ``walk``: the largest per-step
    torque change fell from 154 N m to 52 N m).

    Args:
        robot: Robot model (its mass).
        name: Task name.
        weight: Weight within its level.

    """

    category = Category.POSTURE

    def __init__(self, robot: RobotModel, *, name: str = "forces", weight: float = 1.0) -> None:
        super().__init__(name, weight)
        self._scale = 1.0 / (robot.mass * float(np.linalg.norm(robot.gravity_vector)))
        self._rows: tuple[tuple[int, int], Rows] | None = None

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Equality rows ``(n - nv, n)``: every contact component divided by ``m g``, target 0.

        They depend on the layout only: built once per layout and reused (read-only).
        """
        key = (layout.n, layout.nv)
        if self._rows is None or self._rows[0] != key:
            n, nv = key
            A = np.zeros((n - nv, n))
            A[:, nv:] = self._scale * np.eye(n - nv)
            b = np.zeros(n - nv)
            A.flags.writeable = b.flags.writeable = False  # shared by every step
            self._rows = key, Rows(A=A, b=b)
        return self._rows[1]

    def error(self) -> np.ndarray:
        """Empty: the task has no goal other than zero force."""
        return np.zeros(0)
