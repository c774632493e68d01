"""Hybrid force/position control of a frame in contact."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.model.geometry import cross3
from hqp.model.layout import ContactType
from hqp.tasks.base import Category, Rows
from hqp.tasks.pose import PoseTask
from hqp.tasks.tracking import TaskKinematics

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout

WRENCH_AXES = ("fx", "fy", "fz", "tx", "ty", "tz")
"""Names of the wrench components of a contact slot (world axes, at the frame origin)."""


class HybridTask(PoseTask):
    """Selected directions force-controlled, the complementary directions motion-controlled.

    The frame is in contact through the layout's contact ``contact`` (whose
    slot holds the wrench ``[F; tau]`` at the frame origin, world axes). For
    the force-controlled components ``S_f`` (names of :data:`WRENCH_AXES`)
    the rows are ``S_f f = f_des`` over the slot's columns (desired-force
    rows; no force feedback). Each remaining direction is motion-controlled
    with PD rows over ``qdd`` (world axes): a translation direction ``x, y,
    z`` not force-controlled by ``fx, fy, fz`` keeps the origin's position
    (error ``p - p_goal``), and, for a surface contact, a rotation direction
    not force-controlled by ``tx, ty, tz`` keeps the orientation with the
    world-axes error ``e_w = R_g log3(R_g^T R)`` (derivatives of the
    rotating goal frame included). A point contact has no torque
    components and no rotation rows.

    Args:
        robot: Robot model (the frame is checked here).
        frame: Frame in contact (must be the contact slot's frame).
        contact: Name of the contact in the layout.
        force_axes: Force-controlled components (default ``("fz",)``: press
            along the vertical, slide in the plane).
        name: Task name (default: ``"hybrid_" + frame``).
        weight: Weight within its level.
        kp: Stiffness of the motion rows' PD reference [1/s^2] (as :class:`PoseTask`).
        kv: Damping [1/s] (``None``: ``2 sqrt(kp)``).
        max_velocity: Saturation of the translation's corrective velocity [m/s].
        max_acceleration: Saturation of the translation's feedback acceleration [m/s^2].
        max_angular_velocity: Saturation of the rotation's corrective velocity [rad/s]
            (``None``: the translation's number).
        max_angular_acceleration: Saturation of the rotation's feedback acceleration
            [rad/s^2] (``None``: the translation's number).

    Goals: :meth:`set_goal` (placement, as :class:`PoseTask`; only the
    motion-controlled directions matter) and :meth:`set_force` ``(k,)`` [N,
    N m] for the force-controlled components (default zero).

    Raises:
        InvalidFrame: Unknown frame.
        InvalidInput: Unknown, repeated or empty force axes.
        InvalidGain: Bad gains.

    """

    category = Category.OPERATIONAL

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        contact: str,
        force_axes: Sequence[str] = ("fz",),
        *,
        name: str | None = None,
        weight: float = 1.0,
        kp: float = 100.0,
        kv: float | None = None,
        max_velocity: float = math.inf,
        max_acceleration: float = math.inf,
        max_angular_velocity: float | None = None,
        max_angular_acceleration: float | None = None,
    ) -> None:
        super().__init__(
            robot,
            frame,
            name=name or f"hybrid_{frame}",
            weight=weight,
            kp=kp,
            kv=kv,
            max_velocity=max_velocity,
            max_acceleration=max_acceleration,
            max_angular_velocity=max_angular_velocity,
            max_angular_acceleration=max_angular_acceleration,
        )
        w = self.where()
        axes = (force_axes,) if isinstance(force_axes, str) else tuple(map(str, force_axes))
        if not axes or len(set(axes)) != len(axes) or any(a not in WRENCH_AXES for a in axes):
            raise InvalidInput(
                f"{w}: force_axes {list(axes)} must be distinct names among "
                f"{', '.join(WRENCH_AXES)}"
            )
        self.contact = contact
        self.force_axes = tuple(a for a in WRENCH_AXES if a in axes)
        self._force_index = np.array([WRENCH_AXES.index(a) for a in self.force_axes], dtype=int)
        self._linear = np.array([i for i in range(3) if i not in self._force_index], dtype=int)
        self._angular = np.array([i for i in range(3) if i + 3 not in self._force_index], dtype=int)
        self._force = np.zeros(len(self.force_axes))
        self._surface = True

    def set_force(self, values: object) -> None:
        """Set the desired force components ``(k,)`` [N, N m] (copied), in ``force_axes`` order.

        Raises:
            InvalidInput: Wrong shape or NaN (names the primitive).

        """
        self._force = check_array(values, (len(self.force_axes),), f"{self.where()}: force")

    @property
    def desired_force(self) -> np.ndarray:
        """The desired force components ``(k,)``."""
        return self._force.copy()

    def motion_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Motion-controlled translation and rotation axes (world indices) at the last layout."""
        ang = self._angular if self._surface else np.zeros(0, dtype=int)
        return self._linear, ang

    def kinematics(self, model: RobotModel, t: float = 0.0) -> TaskKinematics:
        """Return the selected translation and world-axes rotation rows (class docstring)."""
        full = super().kinematics(model, t)
        lin, ang = self.motion_axes()
        if len(ang) == 0:
            return TaskKinematics(
                full.error[lin], full.rate[lin], full.jacobian[lin], full.drift[lin]
            )
        g = self.goal_at(t)
        Rg = g.position[:3, :3]
        wg, ag = g.velocity[3:], g.acceleration[3:]
        e, de = full.error[3:], full.rate[3:]
        ew, dew0 = Rg @ e, Rg @ de
        rate = dew0 + cross3(wg, ew)
        drift = (
            Rg @ full.drift[3:]
            + 2.0 * cross3(wg, dew0)
            + cross3(ag, ew)
            + cross3(wg, cross3(wg, ew))
        )
        Jw = Rg @ full.jacobian[3:]
        return TaskKinematics(
            np.concatenate([full.error[lin], ew[ang]]),
            np.concatenate([full.rate[lin], rate[ang]]),
            np.concatenate([full.jacobian[lin], Jw[ang]]),
            np.concatenate([full.drift[lin], drift[ang]]),
        )

    def _translation_rows(self) -> int:
        """Return the number of motion-controlled translation rows leading :meth:`kinematics`."""
        return len(self._linear)

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Motion rows over ``qdd`` then force rows over the contact slot.

        Raises:
            InvalidInput: Contact not in the layout, a different frame, torque
                axes on a point contact, or no goal.

        """
        w = self.where()
        try:
            slot = layout.contact(self.contact)
        except InvalidInput as exc:
            raise InvalidInput(f"{w}: {exc}") from None
        if slot.frame != self.frame:
            raise InvalidInput(
                f"{w}: contact {self.contact!r} is on frame {slot.frame!r}, not {self.frame!r}"
            )
        self._surface = slot.kind is ContactType.SURFACE
        if not self._surface and np.any(self._force_index >= 3):
            raise InvalidInput(f"{w}: a point contact has no torque components")
        motion = super().rows(model, layout, dt, t)
        k = len(self.force_axes)
        F = np.zeros((k, layout.n))
        F[np.arange(k), slot.start + self._force_index] = 1.0
        A = F if motion.A is None or motion.A.shape[0] == 0 else np.concatenate([motion.A, F])
        b = self._force.copy() if motion.b is None or motion.b.shape[0] == 0 else np.concatenate(
            [motion.b, self._force])
        return Rows(A=A, b=b)
