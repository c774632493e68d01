"""The papers' joint-limit activation zones, as equality rows.

The hierarchy paper (seed 003, eq. 25) handles joint limits with the potential

    V_JLC = ||q_violating - q_limit||^2,

where ``q_violating`` are the joints that have entered an activation zone
near a limit and ``q_limit`` their safety positions, away from the hard
limits. Its top priority level drives those joints to their safety positions
with the saturated PD law of eq. 27-28:

    qdd_ref = -kv (v - nu v_des),   v_des = (kp / kv) (q_limit - q),
    nu = min(1, v_max / ||v_des||),

over the vector of active joints. The rows are ``qdd_i = qdd_ref_i`` for each
active joint (one row each; none when no joint is in a zone). This is the
primitive of the null-space controller, which cannot use inequalities; the
QP controller uses :class:`~hqp.tasks.joint_limits.JointLimits` instead.

Zone of joint ``i``: ``q_i > q_upper_i - zone_i`` or ``q_i < q_lower_i + zone_i``.
Safety position: ``q_upper_i - depth_i`` (resp. ``q_lower_i + depth_i``),
with ``depth`` the zone width by default (the zone's border).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidGain, check_array
from hqp.tasks.base import Category, Rows, Task

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout


class JointLimitZone(Task):
    """Equality rows for the joints inside a joint-limit activation zone (eq. 25, 27-28).

    Args:
        name: Task name.
        zone: Width of the activation zone inside each limit [rad or m],
            scalar or ``(na,)`` (>= 0).
        depth: Distance of the safety position from the hard limit, scalar or
            ``(na,)`` (>= 0; default: ``zone``).
        kp: Position gain [1/s^2] (> 0).
        kv: Damping gain [1/s] (> 0).
        max_velocity: Velocity saturation ``v_max`` of eq. 28 [rad/s] (> 0, ``inf``: none).
        weight: Weight within its level.

    Raises:
        InvalidGain: Negative or non-finite widths or gains.

    """

    category = Category.JOINT_LIMITS

    def __init__(
        self,
        name: str = "joint_limit_zone",
        zone: np.ndarray | float = 0.1,
        *,
        depth: np.ndarray | float | None = None,
        kp: float = 100.0,
        kv: float = 20.0,
        max_velocity: float = np.inf,
        weight: float = 1.0,
    ) -> None:
        super().__init__(name, weight)
        w = self.where()
        self.zone = check_array(np.atleast_1d(zone), (None,), f"{w}: zone")
        self.depth = (
            self.zone.copy()
            if depth is None
            else check_array(np.atleast_1d(depth), (None,), f"{w}: depth")
        )
        if np.any(self.zone < 0) or np.any(self.depth < 0):
            raise InvalidGain(f"{w}: zone and depth must be >= 0")
        for label, value in (("kp", kp), ("kv", kv)):
            if not (np.isfinite(value) and value > 0):
                raise InvalidGain(f"{w}: {label} must be finite and > 0, got {value}")
        if np.isnan(max_velocity) or max_velocity <= 0:
            raise InvalidGain(f"{w}: max_velocity must be > 0, got {max_velocity}")
        self.kp = float(kp)
        self.kv = float(kv)
        self.max_velocity = float(max_velocity)
        self.active: tuple[str, ...] = ()
        """Names of the joints in a zone at the last :meth:`rows` (for reports)."""
        self._error = np.zeros(0)

    def _per_joint(self, value: np.ndarray, model: RobotModel, label: str) -> np.ndarray:
        if value.size not in (1, model.na):
            raise InvalidGain(
                f"{self.where()}: {label} has {value.size} entries, robot has {model.na} joints"
            )
        return np.broadcast_to(value, (model.na,)).astype(float)

    def safety_positions(self, model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
        """Safety positions near the lower and upper limits, each ``(na,)``."""
        depth = self._per_joint(self.depth, model, "depth")
        return model.q_lower + depth, model.q_upper - depth

    def active_indices(self, model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
        """Active joints at ``model`` and their safety positions.

        Returns:
            ``(indices, q_limit)``: indices in the actuated vector (ascending)
            of the joints inside a zone, and their safety positions.

        """
        zone = self._per_joint(self.zone, model, "zone")
        q = model.q[model.actuated_q]
        low_safe, high_safe = self.safety_positions(model)
        upper = q > model.q_upper - zone
        lower = q < model.q_lower + zone
        idx = np.flatnonzero(upper | lower)
        q_limit = np.where(upper, high_safe, low_safe)[idx]
        return idx, q_limit

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """One equality row ``qdd_i = qdd_ref_i`` per active joint (``(k, n)``, ``k >= 0``)."""
        idx, q_limit = self.active_indices(model)
        self.active = tuple(model.joint_names[i] for i in idx)
        q = model.q[model.actuated_q][idx]
        v = model.v[model.actuated][idx]
        self._error = q_limit - q
        v_des = (self.kp / self.kv) * self._error
        speed = float(np.linalg.norm(v_des))
        nu = 1.0 if speed <= self.max_velocity else self.max_velocity / speed
        qdd_ref = -self.kv * (v - nu * v_des)
        if idx.size == 0:
            return Rows()
        A = np.zeros((idx.size, layout.n))
        A[np.arange(idx.size), model.nv_base + idx] = 1.0
        return Rows(A=A, b=qdd_ref)

    def error(self) -> np.ndarray:
        """``q_limit - q`` of the active joints at the last :meth:`rows`."""
        return self._error

    def record_error(self, active: tuple[str, ...], error: np.ndarray) -> None:
        """Set :attr:`active` and :meth:`error` for a step whose rows were computed elsewhere.

        Args:
            active: Names of the joints inside a zone.
            error: Their ``q_limit - q`` ``(k,)`` [rad].

        """
        self.active = active
        self._error = error
