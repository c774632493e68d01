"""Centroidal momentum: linear and/or angular momentum about the centre of mass."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.tasks.base import Category, Rows, Task
from hqp.tasks.reference import PDReference, Trajectory, TrajectorySample, check_trajectory

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout

_COMPONENTS = {"linear": (0, 1, 2), "angular": (3, 4, 5), "all": (0, 1, 2, 3, 4, 5)}


class CentroidalMomentumTask(Task):
    """Centroidal momentum ``h = A_g v = [m c_dot; k]`` (world axes, about the CoM).

    Rows ``S A_g qdd = hdot_ref - S dA_g v`` over the ``qdd`` columns, with
    ``S`` the selected components and the momentum-rate reference

        hdot_ref = hdot_goal + sat(-gain (h - h_goal), max_rate)

    (the PD reference of :class:`~hqp.tasks.reference.PDReference` with
    ``kp = 0``, ``kv = gain``: momentum is a velocity-level quantity, so the
    reference is a damping towards the goal momentum). Goal zero angular
    momentum is the usual "damp the angular momentum" task.

    Args:
        robot: Robot model.
        components: ``"linear"``, ``"angular"`` (default), ``"all"``, or
            indices into ``[0, 6)`` of ``[linear (kg m/s); angular (kg m^2/s)]``.
        name: Task name.
        weight: Weight within its level.
        gain: Damping ``[1/s]`` (non-negative).
        max_rate: Saturation of ``||hdot_ref - hdot_goal||`` (``inf``: none).

    Goal: :meth:`set_goal` with the selected momentum ``(k,)`` (default zero)
    and an optional momentum rate ``(k,)``; or :meth:`set_trajectory`.

    Raises:
        InvalidInput: Bad components.
        InvalidGain: Negative or non-finite gain or rate.

    """

    category = Category.BALANCE

    def __init__(
        self,
        robot: RobotModel,
        components: str | Sequence[int] = "angular",
        *,
        name: str = "centroidal",
        weight: float = 1.0,
        gain: float = 10.0,
        max_rate: float = math.inf,
    ) -> None:
        super().__init__(name, weight)
        w = self.where()
        if isinstance(components, str):
            if components not in _COMPONENTS:
                raise InvalidInput(
                    f"{w}: components {components!r}; expected one of {', '.join(_COMPONENTS)} "
                    "or indices"
                )
            idx = list(_COMPONENTS[components])
        else:
            try:
                idx = sorted(int(i) for i in components)
            except (TypeError, ValueError):
                raise InvalidInput(f"{w}: bad components {components!r}") from None
            if not idx or len(set(idx)) != len(idx) or idx[0] < 0 or idx[-1] > 5:
                raise InvalidInput(f"{w}: components must be distinct indices in [0, 6)")
        self.components = np.array(idx, dtype=int)
        self.reference = PDReference(0.0, gain, math.inf, max_rate, where=w)
        m = len(idx)
        self._goal = TrajectorySample(np.zeros(m), np.zeros(m), np.zeros(m))
        self._trajectory: Trajectory | None = None
        self._last: np.ndarray | None = None

    def set_gains(self, gain: float | None = None, max_rate: float | None = None) -> None:
        """Change the damping or the rate saturation (``None`` keeps a value).

        Raises:
            InvalidGain: Bad values.

        """
        ref = self.reference
        self.reference = PDReference(
            0.0,
            ref.kv if gain is None else gain,
            math.inf,
            ref.max_acceleration if max_rate is None else max_rate,
            where=self.where(),
        )

    def set_goal(self, momentum: object, rate: object | None = None) -> None:
        """Set the goal momentum ``(k,)`` (copied) and optional momentum rate ``(k,)``.

        Raises:
            InvalidInput: Wrong shape or NaN (names the primitive).

        """
        m = len(self.components)
        w = self.where()
        h = check_array(momentum, (m,), f"{w}: goal")
        hd = np.zeros(m) if rate is None else check_array(rate, (m,), f"{w}: goal rate")
        self._goal = TrajectorySample(h, hd, np.zeros(m))
        self._trajectory = None

    def set_trajectory(self, trajectory: Trajectory) -> None:
        """Follow a momentum trajectory (samples: position = momentum, velocity = its rate).

        Raises:
            InvalidInput: ``trajectory`` has no ``sample`` method.

        """
        self._trajectory = check_trajectory(trajectory, self.where())

    @property
    def trajectory(self) -> Trajectory | None:
        """The momentum trajectory being followed, if any."""
        return self._trajectory

    def value(self, model: RobotModel) -> np.ndarray:
        """Return the selected momentum ``S A_g v`` ``(k,)``."""
        return model.centroidal_matrix[self.components] @ model.v

    def kinematics(
        self, model: RobotModel, t: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(e, J, drift)``: ``e = S h - h_goal``, ``de/dt = J qdd + drift``.

        ``J = S A_g`` ``(k, nv)``, ``drift = S dA_g v - hdot_goal`` ``(k,)``.
        """
        if self._trajectory is not None:
            s = self._trajectory.sample(t)
            m = len(self.components)
            w = self.where()
            goal = TrajectorySample(
                check_array(s.position, (m,), f"{w}: goal"),
                check_array(s.velocity, (m,), f"{w}: goal rate"),
                np.zeros(m),
            )
        else:
            goal = self._goal
        c = self.components
        A = model.centroidal_matrix[c]
        drift = model.centroidal_drift[c] - goal.velocity
        return A @ model.v - goal.position, A, drift

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Equality rows ``[S A_g | 0] x = sat(-gain (S h - h_goal)) + hdot_goal - S dA_g v``.

        Raises:
            InvalidInput: A layout that does not match the robot.

        """
        if layout.nv != model.nv:
            raise InvalidInput(f"{self.where()}: layout nv={layout.nv}, robot nv={model.nv}")
        e, J, drift = self.kinematics(model, t)
        # kp = 0: the feedback is -kv * (h - h_goal), saturated at max_rate.
        a = self.reference.feedback(np.zeros_like(e), e)
        A = layout.zeros(len(self.components))
        A[:, : layout.nv] = J
        self._last = e
        return Rows(A=A, b=a - drift)

    def error(self) -> np.ndarray:
        """``h_goal - S h`` at the last step (empty before)."""
        self._fetch_error()
        return np.zeros(0) if self._last is None else -self._last

    def record_error(self, e: np.ndarray) -> None:
        """Record ``S h - h_goal`` of a step whose rows were computed elsewhere (native)."""
        self._last = np.array(e, dtype=float)
