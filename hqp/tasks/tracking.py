"""Shared machinery of the motion primitives that track a goal with the PD reference.

A tracking task defines an error ``e(q, t)`` ``(m,)`` that vanishes at its
goal (the goal may move with time), and reports, at the updated state,

    e,   de/dt = J v + (goal terms),   d2e/dt2 = J qdd + drift,

(:class:`TaskKinematics`; ``drift`` holds every term that does not depend on
``qdd``, including the goal's acceleration). Its rows over
``x = [qdd | f]`` are then

    [J | 0] x = a_fb(e, de/dt) - drift

with ``a_fb`` the saturated PD feedback of :class:`~hqp.tasks.reference.PDReference`
(seed 003 eq. 27-28); for a vector task ``e = x - x_goal`` this is exactly
``J qdd = xdd_ref - dJ v`` with ``xdd_ref = xdd_goal + a_fb``.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.tasks.base import Rows, Task
from hqp.tasks.reference import (
    MinimumJerk,
    MinimumJerkPose,
    MinimumJerkRotation,
    PDReference,
    Trajectory,
    TrajectorySample,
    check_trajectory,
)

_VALIDATED_TRAJECTORIES = (MinimumJerk, MinimumJerkRotation, MinimumJerkPose)
"""The bundled trajectories: their samples are valid by construction (see ``goal_at``)."""

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout

AXIS_NAMES = {"x": 0, "y": 1, "z": 2}


def parse_axes(axes: str | Sequence[int] | None, size: int, where: str) -> np.ndarray:
    """Return the indices of selected axes from ``"xz"``-style strings or integers.

    Args:
        axes: ``None`` (all), a string of ``x``/``y``/``z`` (only when ``size == 3``),
            or indices in ``[0, size)``.
        size: Number of available axes.
        where: Prefix of error messages.

    Raises:
        InvalidInput: Empty, repeated, unknown or out-of-range axes.

    """
    if axes is None:
        return np.arange(size)
    if isinstance(axes, str):
        if size != 3 or any(c not in AXIS_NAMES for c in axes):
            raise InvalidInput(f"{where}: axes {axes!r} must be letters of 'xyz'")
        idx = [AXIS_NAMES[c] for c in axes]
    else:
        try:
            idx = [int(i) for i in axes]
        except (TypeError, ValueError):
            raise InvalidInput(
                f"{where}: axes must be a string or integers, got {axes!r}"
            ) from None
    if not idx or len(set(idx)) != len(idx) or min(idx) < 0 or max(idx) >= size:
        raise InvalidInput(
            f"{where}: axes {axes!r} must be distinct, non-empty, within [0, {size})"
        )
    return np.array(sorted(idx), dtype=int)


@dataclass(frozen=True)
class TaskKinematics:
    """Error of a task and its derivatives at the updated state.

    Attributes:
        error: ``e`` ``(m,)`` (zero at the goal).
        rate: ``de/dt`` ``(m,)``.
        jacobian: ``J`` ``(m, nv)``: ``d2e/dt2 = J qdd + drift`` (and ``de/dt = J v + ...``).
        drift: ``(m,)``, everything in ``d2e/dt2`` that does not depend on ``qdd``.

    """

    error: np.ndarray
    rate: np.ndarray
    jacobian: np.ndarray
    drift: np.ndarray


@dataclass(frozen=True)
class Gains:
    """Gains and saturations of a tracking task's :class:`PDReference` (seed 003 eq. 27-28).

    The tracking tasks take them as the keywords ``kp``, ``kv``, ``max_velocity`` and
    ``max_acceleration`` of their constructors and hand them to :class:`TrackingTask` as one
    record; :meth:`reference` checks them.

    Attributes:
        kp: Stiffness [1/s^2].
        kv: Damping [1/s] (``None``: ``2 sqrt(kp)``).
        max_velocity: Saturation of the corrective velocity (task units/s).
        max_acceleration: Saturation of the feedback acceleration (task units/s^2).

    """

    kp: float = 100.0
    kv: float | None = None
    max_velocity: float = math.inf
    max_acceleration: float = math.inf

    def reference(self, where: str) -> PDReference:
        """Return the PD reference of these gains.

        Raises:
            InvalidGain: Bad gains (the message starts with ``where``).

        """
        return PDReference(self.kp, self.kv, self.max_velocity, self.max_acceleration, where=where)


class TrackingTask(Task):
    """Base of the primitives that track a goal through :class:`PDReference` rows.

    Args:
        name: Task name.
        weight: Weight within its level.
        gains: The PD reference's gains and saturations (default: ``kp = 100``, critical
            damping, no saturation).

    Raises:
        InvalidGain: Bad gains or weight (names the primitive).

    """

    def __init__(self, name: str, weight: float = 1.0, gains: Gains = Gains()) -> None:
        super().__init__(name, weight)
        self.reference = gains.reference(self.where())
        self._goal: TrajectorySample | None = None
        self._trajectory: Trajectory | None = None
        self._trusted = False  # samples of a bundled trajectory: see goal_at
        self._last: TaskKinematics | None = None
        self._last_reference: np.ndarray = np.zeros(0)
        self._recorded: np.ndarray | None = None  # e of a step computed elsewhere

    # -- gains ----------------------------------------------------------------------------------

    def set_gains(
        self,
        kp: float | None = None,
        kv: float | None = None,
        max_velocity: float | None = None,
        max_acceleration: float | None = None,
    ) -> None:
        """Change gains or saturations (``None`` keeps a value, except ``kv``).

        ``kv=None`` with a new ``kp`` gives critical damping ``2 sqrt(kp)``;
        with ``kp=None`` it keeps the current ``kv``.

        Raises:
            InvalidGain: Bad values (the task keeps its old reference).

        """
        ref = self.reference
        new_kp = ref.kp if kp is None else kp
        new_kv = (ref.kv if kp is None else None) if kv is None else kv
        self.reference = PDReference(
            new_kp,
            new_kv,
            ref.max_velocity if max_velocity is None else max_velocity,
            ref.max_acceleration if max_acceleration is None else max_acceleration,
            where=self.where(),
        )

    # -- goals ----------------------------------------------------------------------------------

    def set_trajectory(self, trajectory: Trajectory) -> None:
        """Follow a goal trajectory (sampled at the time passed to :meth:`rows`).

        The samples must have the shapes :meth:`set_goal` accepts; a bundled trajectory's
        are checked here, any other's at every sample (see :meth:`goal_at`).

        Raises:
            InvalidInput: ``trajectory`` has no ``sample`` method, or a bundled trajectory
                of the wrong shape (the task's goal is then left as it was).

        """
        checked = check_trajectory(trajectory, self.where())
        trusted = type(checked) in _VALIDATED_TRAJECTORIES
        if trusted:  # its shapes, once (before anything is replaced)
            s = checked.sample(0.0)
            self._check_goal(s.position, s.velocity, s.acceleration)
        self._trajectory, self._trusted = checked, trusted
        self._goal = None

    @property
    def trajectory(self) -> Trajectory | None:
        """The goal trajectory being followed, if any."""
        return self._trajectory

    def goal_at(self, t: float) -> TrajectorySample:
        """Return the goal and its derivatives at time ``t`` (validated).

        A sample of a bundled trajectory (``MinimumJerk``, ``MinimumJerkRotation``,
        ``MinimumJerkPose``: endpoints and timing validated when built, finite arrays, fresh
        within the motion and one read-only sample before and after it) is not validated
        again once its shapes were checked by :meth:`set_trajectory` (about 40 us per
        orientation sample); any other trajectory's samples are validated at every call.

        Raises:
            InvalidInput: No goal set, or a trajectory sample of the wrong shape.

        """
        if self._trajectory is not None:
            s = self._trajectory.sample(t)
            if self._trusted:
                return s
            return self._check_goal(s.position, s.velocity, s.acceleration)
        if self._goal is None:
            raise InvalidInput(f"{self.where()}: goal not set (call set_goal or set_trajectory)")
        return self._goal

    def _goal_sample(
        self,
        position: np.ndarray,
        velocity: object | None,
        acceleration: object | None,
        size: int,
    ) -> TrajectorySample:
        """Sample of a validated goal ``position`` with checked derivatives ``(size,)``.

        Missing ``velocity`` or ``acceleration`` default to zero.

        Raises:
            InvalidInput: A derivative of the wrong shape or NaN/inf (names the primitive).

        """
        w = self.where()
        v = (
            np.zeros(size)
            if velocity is None
            else check_array(velocity, (size,), f"{w}: goal velocity")
        )
        a = (
            np.zeros(size)
            if acceleration is None
            else check_array(acceleration, (size,), f"{w}: goal acceleration")
        )
        return TrajectorySample(position, v, a)

    def _store_goal(self, sample: TrajectorySample) -> None:
        # read-only: a goal changes through set_goal only (the native step pushes a goal
        # down when it is a new sample, hqp.control.native)
        for array in (sample.position, sample.velocity, sample.acceleration):
            array.setflags(write=False)
        self._goal = sample
        self._trajectory = None

    @abc.abstractmethod
    def _check_goal(
        self, goal: object, velocity: object | None, acceleration: object | None
    ) -> TrajectorySample:
        """Validate a goal and its derivatives (copies), raising :class:`InvalidInput`."""

    # -- kinematics and rows --------------------------------------------------------------------

    @abc.abstractmethod
    def kinematics(self, model: RobotModel, t: float = 0.0) -> TaskKinematics:
        """Error, its rate, Jacobian and drift at the updated state and time ``t``."""

    def feedback(self, kin: TaskKinematics) -> np.ndarray:
        """PD feedback ``a_fb(e, de/dt)`` of the reference (eq. 27-28)."""
        return self.reference.feedback(kin.error, kin.rate)

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Equality rows ``[J | 0] x = a_fb - drift`` ``(m, n)``.

        Raises:
            InvalidInput: Goal not set, or a layout that does not match the robot.

        """
        nv = layout.nv
        if nv != model.nv:
            raise InvalidInput(f"{self.where()}: layout nv={nv}, robot nv={model.nv}")
        kin = self.kinematics(model, t)
        a = self.feedback(kin)
        A = np.zeros((kin.jacobian.shape[0], layout.n))
        A[:, :nv] = kin.jacobian
        self._last = kin
        self._last_reference = a
        self._recorded = None
        return Rows(A=A, b=a - kin.drift)

    def error(self) -> np.ndarray:
        """``-e`` (goal minus current, in the task's coordinates) at the last step."""
        self._fetch_error()
        if self._recorded is not None:
            return -self._recorded
        return np.zeros(0) if self._last is None else -self._last.error

    def record_error(self, e: np.ndarray) -> None:
        """Record ``e`` (current minus goal) of a step whose rows were computed elsewhere.

        The native step computes the task's rows in its kernel; this keeps :meth:`error`
        that of the last step until the next :meth:`rows`.
        """
        self._recorded = np.array(e, dtype=float)

    def reference_acceleration(self) -> np.ndarray:
        """Return the feedback acceleration ``a_fb`` of the last :meth:`rows` (empty before)."""
        return self._last_reference.copy()


class VectorGoalTask(TrackingTask):
    """A tracking task whose goal is a vector ``(goal_size,)`` (with velocity and acceleration)."""

    goal_size: int = 3

    @abc.abstractmethod
    def value(self, model: RobotModel) -> np.ndarray:
        """Return the current value a goal replaces (start of :meth:`move_to`) ``(goal_size,)``."""

    def _check_goal(
        self, goal: object, velocity: object | None, acceleration: object | None
    ) -> TrajectorySample:
        m = self.goal_size
        g = check_array(goal, (m,), f"{self.where()}: goal")
        return self._goal_sample(g, velocity, acceleration, m)

    def set_goal(
        self,
        goal: object,
        velocity: object | None = None,
        acceleration: object | None = None,
    ) -> None:
        """Set a goal (copied) with optional feedforward velocity and acceleration.

        Args:
            goal: ``(goal_size,)`` in task units.
            velocity: ``(goal_size,)`` goal velocity (default zero).
            acceleration: ``(goal_size,)`` goal acceleration (default zero).

        Raises:
            InvalidInput: Wrong shape or NaN/inf (names the primitive).

        """
        self._store_goal(self._check_goal(goal, velocity, acceleration))

    def move_to(self, model: RobotModel, goal: object, duration: float, t0: float) -> None:
        """Reach ``goal`` along a :class:`MinimumJerk` from the current value, from ``t0`` [s].

        Raises:
            InvalidInput: Bad goal or duration.

        """
        g = self._check_goal(goal, None, None).position
        self.set_trajectory(MinimumJerk(self.value(model), g, duration, t0))


class VectorTrackingTask(VectorGoalTask):
    """A tracking task on a vector ``x(q)`` ``(m,)``: ``e = W (x - x_goal)``.

    Subclasses implement :meth:`measure` (``x``, ``xd``, ``J_x``, ``dJ_x v``);
    the optional diagonal ``scale`` ``W`` (e.g. the normalising matrix of
    seed 003 eq. 26) multiplies the error and its derivatives.
    """

    scale: np.ndarray | None = None

    @abc.abstractmethod
    def measure(self, model: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(x, xd, J_x, dJ_x v)`` at the updated state; ``xdd = J_x qdd + dJ_x v``."""

    def value(self, model: RobotModel) -> np.ndarray:
        """Return the current task value ``x`` ``(m,)`` (unscaled)."""
        return self.measure(model)[0].copy()

    def kinematics(self, model: RobotModel, t: float = 0.0) -> TaskKinematics:
        """``e = W (x - x_goal)`` and its derivatives (see :class:`TaskKinematics`)."""
        goal = self.goal_at(t)
        x, xd, J, dJv = self.measure(model)
        e = x - goal.position
        rate = xd - goal.velocity
        drift = dJv - goal.acceleration
        if self.scale is not None:
            w = self.scale
            return TaskKinematics(w * e, w * rate, w[:, None] * J, w * drift)
        return TaskKinematics(e, rate, J, drift)
