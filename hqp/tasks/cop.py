"""Dynamic balance: centre of pressure (ZMP) of the support, as rows over the contact wrenches."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.model.layout import ContactType
from hqp.tasks.base import Category, Rows, Task
from hqp.tasks.reference import Trajectory, check_trajectory

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import ContactSlot, Layout


def support_wrench_rows(
    model: RobotModel, slots: Sequence[ContactSlot], n: int, height: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linear maps from ``x`` to ``F_z``, and to the CoP numerators on the plane ``z = height``.

    With contact ``i`` at origin ``p_i`` carrying force ``F_i`` and torque
    ``tau_i`` (world axes, at ``p_i``; zero torque for a point contact), the
    total force is ``F = sum F_i`` and the moment about the world origin
    ``tau_O = sum tau_i + p_i x F_i``. The centre of pressure ``c`` on the
    plane ``z = h`` is the point about which the horizontal moment vanishes:

        c_x F_z = h F_x - tau_O,y,        c_y F_z = h F_y + tau_O,x.

    Returns:
        ``(fz, nx, ny)``, each ``(n,)``: ``F_z = fz . x``, ``c_x F_z = nx . x``,
        ``c_y F_z = ny . x``.

    """
    fz = np.zeros(n)
    nx = np.zeros(n)
    ny = np.zeros(n)
    for slot in slots:
        p = model.frame_placement(slot.frame).translation
        i = slot.start
        fz[i + 2] = 1.0
        # h F_x - (tau_y + p_z F_x - p_x F_z)
        nx[i + 0] = height - p[2]
        nx[i + 2] = p[0]
        # h F_y + (tau_x + p_y F_z - p_z F_y)
        ny[i + 1] = height - p[2]
        ny[i + 2] = p[1]
        if slot.kind is ContactType.SURFACE:
            nx[i + 4] = -1.0
            ny[i + 3] = 1.0
    return fz, nx, ny


class CoPTask(Task):
    """Centre of pressure (ZMP) of the support driven to a goal point (2 rows over wrenches).

    The CoP ``c = (n_x . x, n_y . x) / (f_z . x)`` of the selected contacts
    (:func:`support_wrench_rows`) is a ratio of linear functions of the
    contact wrenches; ``c = c_goal`` is linear once multiplied by the total
    normal force ``F_z``:

        (c_goal,x f_z - n_x) . x = 0,     (c_goal,y f_z - n_y) . x = 0,

    i.e. the horizontal moment of the support wrench about the goal point
    vanishes. The residual of these rows is ``F_z (c_goal - c)`` [N m]; they
    are divided by the robot's weight ``m g`` so that, at nominal load, it
    reads as a CoP error [m]. The rows do not force ``F_z > 0`` (the dynamics
    and the unilateral contact rows above do); with ``F_z = 0`` they hold
    trivially. There is no PD: the CoP is an algebraic function of the
    wrenches, so a ZMP planner's trajectory is the goal
    (:meth:`set_goal` each step or :meth:`set_trajectory`).

    Args:
        robot: Robot model (mass and gravity for the scaling).
        contacts: Names of the layout's contacts forming the support
            (``None``: every contact of the layout; an inactive contact's
            slot is zero anyway).
        height: Height ``h`` of the ground plane [m] (``None``: mean height
            of the support's contact frames at each step).
        name: Task name.
        weight: Weight within its level.

    Goal: :meth:`set_goal` with the CoP goal ``(2,)`` [m] in the world's
    horizontal plane, or :meth:`set_trajectory` (samples' ``position``).

    Raises:
        InvalidInput: Bad height or contacts.

    """

    category = Category.BALANCE

    def __init__(
        self,
        robot: RobotModel,
        contacts: Sequence[str] | None = None,
        *,
        height: float | None = None,
        name: str = "cop",
        weight: float = 1.0,
    ) -> None:
        super().__init__(name, weight)
        w = self.where()
        if height is not None and not math.isfinite(float(height)):
            raise InvalidInput(f"{w}: height must be finite, got {height!r}")
        if contacts is not None and (not contacts or len(set(contacts)) != len(contacts)):
            raise InvalidInput(f"{w}: contacts must be non-empty and distinct")
        self.contacts = None if contacts is None else tuple(contacts)
        self.height = None if height is None else float(height)
        g = float(np.linalg.norm(robot.gravity_vector))
        self._scale = 1.0 / (robot.mass * g) if robot.mass * g > 0 else 1.0
        self._goal: np.ndarray | None = None
        self._trajectory: Trajectory | None = None
        self._measured: np.ndarray | None = None
        self._last_goal: np.ndarray | None = None

    def set_goal(self, point: object) -> None:
        """Set the CoP goal ``(2,)`` [m] (copied).

        Raises:
            InvalidInput: Wrong shape or NaN (names the primitive).

        """
        self._goal = check_array(point, (2,), f"{self.where()}: goal")
        self._trajectory = None

    def set_trajectory(self, trajectory: Trajectory) -> None:
        """Follow a CoP trajectory (the samples' ``position`` ``(2,)``).

        Raises:
            InvalidInput: ``trajectory`` has no ``sample`` method.

        """
        self._trajectory = check_trajectory(trajectory, self.where())

    def goal_at(self, t: float) -> np.ndarray:
        """Return the CoP goal ``(2,)`` at time ``t``.

        Raises:
            InvalidInput: No goal set or a bad sample.

        """
        if self._trajectory is not None:
            pos = self._trajectory.sample(t).position
            return check_array(pos, (2,), f"{self.where()}: goal")
        if self._goal is None:
            raise InvalidInput(f"{self.where()}: goal not set (call set_goal or set_trajectory)")
        return self._goal

    def _slots(self, layout: Layout) -> list[ContactSlot]:
        if self.contacts is None:
            if not layout.contacts:
                raise InvalidInput(f"{self.where()}: the layout declares no contacts")
            return list(layout.contacts)
        try:
            return [layout.contact(c) for c in self.contacts]
        except InvalidInput as exc:
            raise InvalidInput(f"{self.where()}: {exc}") from None

    def plane_height(self, model: RobotModel, layout: Layout) -> float:
        """Return the ground height ``h`` [m] used at this state."""
        if self.height is not None:
            return self.height
        slots = self._slots(layout)
        return float(np.mean([model.frame_placement(s.frame).translation[2] for s in slots]))

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Equality rows ``(2, n)`` over the support's wrench slots, target zero.

        Raises:
            InvalidInput: Goal not set, or a contact not in the layout.
            InvalidFrame: A contact frame not in the model.

        """
        slots = self._slots(layout)
        for s in slots:
            model.frame_id(s.frame, self.where())
        goal = self.goal_at(t)
        self._last_goal = goal
        fz, nx, ny = support_wrench_rows(model, slots, layout.n, self.plane_height(model, layout))
        A = self._scale * np.vstack([goal[0] * fz - nx, goal[1] * fz - ny])
        return Rows(A=A, b=np.zeros(2))

    def measure(self, model: RobotModel, layout: Layout, x: object) -> np.ndarray:
        """CoP ``(2,)`` [m] of a solution ``x`` (its wrenches); stored for :meth:`error`.

        Raises:
            InvalidInput: ``x`` of the wrong shape, or no normal force.

        """
        xv = check_array(x, (layout.n,), f"{self.where()}: x")
        fz, nx, ny = support_wrench_rows(
            model, self._slots(layout), layout.n, self.plane_height(model, layout)
        )
        F = float(fz @ xv)
        if F <= 0.0:
            raise InvalidInput(f"{self.where()}: no normal force (F_z = {F}), no CoP")
        c = np.array([nx @ xv, ny @ xv]) / F
        self._measured = c
        return c

    def error(self) -> np.ndarray:
        """``c_goal - c``: goal of the last :meth:`rows`, CoP of the last :meth:`measure`.

        Empty until both have been called.
        """
        if self._measured is None or self._last_goal is None:
            return np.zeros(0)
        return self._last_goal - self._measured
