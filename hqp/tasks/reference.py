"""PD references of the control primitives, and goal trajectories.

The reference of a task follows the hierarchy paper (seed 003, eq. 27-28),
written in error coordinates ``e = x - x_goal`` (for which ``V = ||e||^2``,
so ``grad V / 2 = e``; the factor 2 is absorbed in ``kp``):

    v_des  = -(kp / kv) e                                     (eq. 28)
    nu     = min(1, max_velocity / ||v_des||)                 (eq. 28)
    a_fb   = -kv (de/dt - nu v_des) = -kv de/dt - nu kp e     (eq. 27)
    a_fb  <- a_fb * min(1, max_acceleration / ||a_fb||)       (seed 001's saturation)
    xdd_ref = xdd_goal + a_fb

with ``de/dt = xd - xd_goal``: the goal's velocity and acceleration
(feedforward, e.g. from a :class:`MinimumJerk` trajectory) enter exactly, so
a moving goal is tracked without steady lag. Without feedforward and below
the saturations this is the plain PD ``kp (x_goal - x) - kv xd``. The
saturations bound the *feedback* part (the velocity with which an error is
closed, and the acceleration spent on it); the feedforward of a trajectory
passes unchanged (a trajectory that respects the limits is tracked exactly).

Minimum-jerk trajectories (:class:`MinimumJerk` for vectors,
:class:`MinimumJerkRotation` for orientations, :class:`MinimumJerkPose` for
placements) move a goal that jumps: from the current value to the new goal
over a duration, with zero velocity and acceleration at the goal.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin

from hqp.errors import InvalidGain, InvalidInput, check_array
from hqp.tasks.base import Tracked


def _nonnegative(value: float | None, what: str, where: str, *, allow_inf: bool) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidGain(f"{where}: {what} must be a number, got {value!r}") from None
    if math.isnan(v) or v < 0.0 or (math.isinf(v) and not allow_inf):
        kind = "non-negative" + ("" if allow_inf else " and finite")
        raise InvalidGain(f"{where}: {what} must be {kind}, got {value!r}")
    return v


def _norm(x: np.ndarray) -> float:
    """Euclidean norm of a vector, as ``np.linalg.norm`` computes it (``sqrt(x . x)``)."""
    return math.sqrt(x.dot(x)) if x.ndim == 1 else float(np.linalg.norm(x))


class PDReference(Tracked):
    """The saturated PD law of seed 003 eq. 27-28 with feedforward (module docstring).

    Args:
        kp: Stiffness ``[1/s^2]`` (non-negative, finite).
        kv: Damping ``[1/s]`` (non-negative, finite). ``None``: critical
            damping ``2 sqrt(kp)``. ``kv = 0`` requires ``kp = 0`` (the paper's
            form divides by ``kv``).
        max_velocity: Saturation of the corrective velocity ``||nu v_des||``
            in task units per second (``inf``: none). Non-negative.
        max_acceleration: Saturation of the feedback acceleration ``||a_fb||``
            in task units per second squared (``inf``: none). Non-negative.
        where: Prefix of error messages (the primitive's type and name).

    Raises:
        InvalidGain: A negative, NaN or (for gains) infinite value, or
            ``kv = 0 < kp``.

    """

    def __init__(
        self,
        kp: float,
        kv: float | None = None,
        max_velocity: float = math.inf,
        max_acceleration: float = math.inf,
        *,
        where: str = "PDReference",
    ) -> None:
        self.where = where
        self.kp = _nonnegative(kp, "kp", where, allow_inf=False)
        self.kv = (
            2.0 * math.sqrt(self.kp)
            if kv is None
            else _nonnegative(kv, "kv", where, allow_inf=False)
        )
        if self.kv == 0.0 and self.kp > 0.0:
            raise InvalidGain(
                f"{where}: kv = 0 with kp = {self.kp} > 0 (eq. 28 divides by kv); "
                "give kv > 0 or leave it None for critical damping"
            )
        self.max_velocity = _nonnegative(max_velocity, "max_velocity", where, allow_inf=True)
        self.max_acceleration = _nonnegative(
            max_acceleration, "max_acceleration", where, allow_inf=True
        )

    def __repr__(self) -> str:
        return (
            f"PDReference(kp={self.kp}, kv={self.kv}, max_velocity={self.max_velocity}, "
            f"max_acceleration={self.max_acceleration})"
        )

    def desired_velocity(self, error: np.ndarray) -> np.ndarray:
        """Saturated corrective velocity ``nu v_des`` with ``v_des = -(kp/kv) e`` (eq. 28)."""
        e = np.asarray(error, dtype=float)
        if self.kv == 0.0:
            return np.zeros_like(e)
        v_des = -(self.kp / self.kv) * e
        if self.max_velocity < math.inf:  # else no saturation: skip the norm
            norm = _norm(v_des)
            if norm > self.max_velocity:
                v_des = v_des * (self.max_velocity / norm)
        return v_des

    def feedback(self, error: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """Feedback acceleration ``a_fb`` (eq. 27 with both saturations).

        Args:
            error: ``e = x - x_goal`` ``(m,)``.
            rate: ``de/dt = xd - xd_goal`` ``(m,)``.

        Returns:
            ``a_fb`` ``(m,)``: ``-kv (de/dt - nu v_des)``, scaled down to norm
            ``max_acceleration`` when larger.

        """
        a = -self.kv * (np.asarray(rate, dtype=float) - self.desired_velocity(error))
        if self.max_acceleration < math.inf:
            norm = _norm(a)
            if norm > self.max_acceleration:
                a = a * (self.max_acceleration / norm)
        return a

    def __call__(
        self,
        value: np.ndarray,
        velocity: np.ndarray,
        goal: np.ndarray,
        goal_velocity: np.ndarray | None = None,
        goal_acceleration: np.ndarray | None = None,
    ) -> np.ndarray:
        """Acceleration reference ``xdd_ref = xdd_goal + a_fb`` of a vector task.

        Args:
            value: Current task value ``x`` ``(m,)``.
            velocity: Current task velocity ``xd`` ``(m,)``.
            goal: Goal ``x_goal`` ``(m,)``.
            goal_velocity: Feedforward ``xd_goal`` ``(m,)`` (default zero).
            goal_acceleration: Feedforward ``xdd_goal`` ``(m,)`` (default zero).

        Returns:
            ``xdd_ref`` ``(m,)``.

        """
        x = np.asarray(value, dtype=float)
        e = x - np.asarray(goal, dtype=float)
        rate = np.asarray(velocity, dtype=float)
        if goal_velocity is not None:
            rate = rate - np.asarray(goal_velocity, dtype=float)
        a = self.feedback(e, rate)
        if goal_acceleration is not None:
            a = a + np.asarray(goal_acceleration, dtype=float)
        return a


# -- trajectories -------------------------------------------------------------------------------


@dataclass(frozen=True)
class TrajectorySample:
    """A goal and its derivatives at one time.

    Attributes:
        position: Goal value: a vector ``(m,)``, a rotation ``(3, 3)`` or a
            homogeneous placement ``(4, 4)``.
        velocity: Its velocity ``(m,)`` (angular parts: world-frame angular velocity).
        acceleration: Its acceleration ``(m,)`` (angular parts: world frame).

    """

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


class Trajectory(Protocol):
    """Anything that samples a goal and its derivatives at a time ``t`` [s]."""

    def sample(self, t: float) -> TrajectorySample:
        """Goal, velocity and acceleration at time ``t``."""
        ...


def check_trajectory(trajectory: object, where: str) -> Trajectory:
    """Check that ``trajectory`` has a callable ``sample(t)``; return it unchanged.

    Raises:
        InvalidInput: ``trajectory`` has no ``sample`` method.

    """
    if not callable(getattr(trajectory, "sample", None)):
        raise InvalidInput(f"{where}: a trajectory needs a sample(t) method")
    return trajectory  # type: ignore[return-value]


MIN_JERK_PEAK_VELOCITY = 1.875
"""Peak velocity of a minimum-jerk move of length ``d`` over ``T``, in units of ``d / T``."""
MIN_JERK_PEAK_ACCELERATION = 10.0 / math.sqrt(3.0)
"""Peak acceleration of a minimum-jerk move, in units of ``d / T^2`` (5.77)."""


def min_jerk(s: float) -> float:
    """Minimum-jerk profile ``10 s^3 - 15 s^4 + 6 s^5`` of a fraction ``s`` clipped to [0, 1].

    The ramps of :mod:`hqp.stack`, the controller's blend and the behavior files'
    ``min_jerk(u)`` use it. Its Horner form is kept as it was: the fraction of
    :func:`min_jerk_profile` is the same polynomial evaluated otherwise, and the two differ
    by a few ulps (up to 17) on about half the inputs.
    """
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def _held(ends: list[TrajectorySample | None], tau: float, duration: float,
          make: Callable[[bool], TrajectorySample]) -> TrajectorySample | None:
    """Return the sample held before (``tau <= 0``) or after (``tau >= duration``) a motion.

    Made once by ``make(after)``, its arrays read-only, and kept in ``ends``; ``None`` within
    the motion.
    """
    if not (tau <= 0.0 or tau >= duration):
        return None
    after = tau > 0.0
    sample = ends[after]
    if sample is None:
        sample = ends[after] = make(after)
        for array in (sample.position, sample.velocity, sample.acceleration):
            array.setflags(write=False)
    return sample


def min_jerk_profile(tau: float, duration: float) -> tuple[float, float, float]:
    """Minimum-jerk fraction and its first two time derivatives.

    Args:
        tau: Time since the start [s], clipped to ``[0, duration]``.
        duration: Length ``T`` of the profile [s] (``1.0``: derivatives with respect to the
            fraction of time ``u``).

    Returns:
        ``s = 10 u^3 - 15 u^4 + 6 u^5`` with ``u = tau / T``, ``ds/dt`` [1/s] and
        ``d2s/dt2`` [1/s^2]; zero velocity and acceleration at both ends.

    """
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau >= duration:
        return 1.0, 0.0, 0.0
    u = tau / duration
    s = u**3 * (10.0 - 15.0 * u + 6.0 * u * u)
    ds = 30.0 * u * u * (1.0 - u) ** 2 / duration
    dds = 60.0 * u * (1.0 - 3.0 * u + 2.0 * u * u) / duration**2
    return s, ds, dds


def _check_timing(duration: float, t0: float, where: str) -> tuple[float, float]:
    d = float(duration)
    s = float(t0)
    if not (math.isfinite(d) and d > 0.0):
        raise InvalidInput(f"{where}: duration must be positive and finite, got {duration!r}")
    if not math.isfinite(s):
        raise InvalidInput(f"{where}: t0 must be finite, got {t0!r}")
    return d, s


class MinimumJerk:
    """Quintic from ``start`` to ``goal`` over ``[t0, t0 + duration]``.

    Boundary conditions: position, velocity and acceleration at ``t0`` are
    ``start``, ``start_velocity``, ``start_acceleration`` (default zero);
    at ``t0 + duration`` they are ``goal``, 0, 0. Before ``t0`` the sample is
    the start state (with zero derivatives); after, the goal at rest. With zero
    start derivatives it is the minimum-jerk path
    ``x = start + (goal - start) (10 u^3 - 15 u^4 + 6 u^5)``, ``u = (t - t0)/T``.

    Args:
        start: Start value ``(m,)``.
        goal: Final value ``(m,)``.
        duration: ``T`` [s] > 0.
        t0: Start time [s].
        start_velocity: ``(m,)`` (default zero), e.g. to retarget a moving goal.
        start_acceleration: ``(m,)`` (default zero).

    Raises:
        InvalidInput: Shapes differ, NaN/inf entries, or a non-positive duration.

    """

    def __init__(
        self,
        start: np.ndarray,
        goal: np.ndarray,
        duration: float,
        t0: float = 0.0,
        *,
        start_velocity: np.ndarray | None = None,
        start_acceleration: np.ndarray | None = None,
    ) -> None:
        where = "MinimumJerk"
        x0 = check_array(start, (None,), f"{where}: start")
        m = x0.shape[0]
        x1 = check_array(goal, (m,), f"{where}: goal")
        v0 = np.zeros(m) if start_velocity is None else check_array(
            start_velocity, (m,), f"{where}: start_velocity")
        a0 = np.zeros(m) if start_acceleration is None else check_array(
            start_acceleration, (m,), f"{where}: start_acceleration")
        self.duration, self.t0 = _check_timing(duration, t0, where)
        self.start = x0
        self.goal = x1
        T = self.duration
        d = x1 - x0
        # x(tau) = c0 + c1 tau + ... + c5 tau^5 with x(T) = x1, xd(T) = xdd(T) = 0.
        self._c = np.stack(
            [
                x0,
                v0,
                0.5 * a0,
                (20.0 * d - 12.0 * v0 * T - 3.0 * a0 * T * T) / (2.0 * T**3),
                (-30.0 * d + 16.0 * v0 * T + 3.0 * a0 * T * T) / (2.0 * T**4),
                (12.0 * d - 6.0 * v0 * T - a0 * T * T) / (2.0 * T**5),
            ]
        )
        self._v0 = v0
        self._a0 = a0
        self._ends: list[TrajectorySample | None] = [None, None]  # (before, after)

    def sample(self, t: float) -> TrajectorySample:
        """Position, velocity and acceleration ``(m,)`` each at time ``t`` [s].

        Before the start and after the end, the same read-only sample at every call (a
        controller holding the goal then pushes nothing down).
        """
        tau = float(t) - self.t0
        if not 0.0 < tau < self.duration:  # (the test of _held, inline: at every step)
            m = self.start.shape[0]
            held = _held(self._ends, tau, self.duration, lambda end: TrajectorySample(
                (self.goal if end else self.start).copy(), np.zeros(m), np.zeros(m)))
            if held is not None:
                return held
        c = self._c
        p = c[0] + tau * (c[1] + tau * (c[2] + tau * (c[3] + tau * (c[4] + tau * c[5]))))
        v = c[1] + tau * (2 * c[2] + tau * (3 * c[3] + tau * (4 * c[4] + tau * 5 * c[5])))
        a = 2 * c[2] + tau * (6 * c[3] + tau * (12 * c[4] + tau * 20 * c[5]))
        return TrajectorySample(p, v, a)


def check_rotation(value: object, where: str) -> np.ndarray:
    """Check a ``(3, 3)`` rotation matrix (orthonormal within 1e-6, det +1); return a copy.

    Raises:
        InvalidInput: Wrong shape, NaN/inf, or not a rotation.

    """
    R = check_array(value, (3, 3), where)
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0.0:
        raise InvalidInput(f"{where}: not a rotation matrix (R^T R != I or det < 0)")
    return R


def check_placement(value: object, where: str) -> np.ndarray:
    """Check a placement (``pin.SE3`` or ``(4, 4)`` array); return a ``(4, 4)`` copy.

    Raises:
        InvalidInput: Wrong shape, NaN/inf, bad last row, or a non-rotation block.

    """
    T = value.homogeneous if isinstance(value, pin.SE3) else value
    H = check_array(T, (4, 4), where)
    if np.abs(H[3] - np.array([0.0, 0.0, 0.0, 1.0])).max() > 1e-9:
        raise InvalidInput(f"{where}: last row of a placement must be [0, 0, 0, 1]")
    check_rotation(H[:3, :3], where)
    return H


class MinimumJerkRotation:
    """Minimum-jerk rotation ``R(t) = R0 exp(s(t) log(R0^T R1))`` over ``[t0, t0 + duration]``.

    The angular velocity and acceleration are in the world frame:
    ``omega = R0 w ds/dt``, ``alpha = R0 w d2s/dt2`` with ``w = log3(R0^T R1)``.

    Args:
        start: Start rotation ``(3, 3)``.
        goal: Final rotation ``(3, 3)``.
        duration: [s] > 0.
        t0: Start time [s].

    Raises:
        InvalidInput: Not rotations, or a non-positive duration.

    """

    def __init__(self, start: np.ndarray, goal: np.ndarray, duration: float, t0: float = 0.0):
        where = "MinimumJerkRotation"
        self.start = check_rotation(start, f"{where}: start")
        self.goal = check_rotation(goal, f"{where}: goal")
        self.duration, self.t0 = _check_timing(duration, t0, where)
        self._w = pin.log3(self.start.T @ self.goal)
        self._w_world = self.start @ self._w
        self._ends: list[TrajectorySample | None] = [None, None]  # (before, after)

    def sample(self, t: float) -> TrajectorySample:
        """Rotation ``(3, 3)``, world angular velocity and acceleration ``(3,)`` at ``t``.

        Before the start and after the end, the same read-only sample at every call.
        """
        tau = float(t) - self.t0
        held = _held(self._ends, tau, self.duration, lambda _end: self._sample(tau))
        return self._sample(tau) if held is None else held

    def _sample(self, tau: float) -> TrajectorySample:
        s, ds, dds = min_jerk_profile(tau, self.duration)
        R = self.start @ pin.exp3(s * self._w)
        return TrajectorySample(R, ds * self._w_world, dds * self._w_world)


class MinimumJerkPose:
    """Minimum-jerk placement: :class:`MinimumJerk` position and :class:`MinimumJerkRotation`.

    Samples are a homogeneous ``(4, 4)`` placement and 6-vectors
    ``[linear; angular]`` (world frame) of velocity and acceleration.

    Args:
        start: Start placement (``pin.SE3`` or ``(4, 4)``).
        goal: Final placement.
        duration: [s] > 0.
        t0: Start time [s].

    """

    def __init__(self, start: object, goal: object, duration: float, t0: float = 0.0) -> None:
        where = "MinimumJerkPose"
        H0 = check_placement(start, f"{where}: start")
        H1 = check_placement(goal, f"{where}: goal")
        self._p = MinimumJerk(H0[:3, 3], H1[:3, 3], duration, t0)
        self._r = MinimumJerkRotation(H0[:3, :3], H1[:3, :3], duration, t0)
        self.duration, self.t0 = self._p.duration, self._p.t0
        self._ends: list[TrajectorySample | None] = [None, None]  # (before, after)

    def sample(self, t: float) -> TrajectorySample:
        """Placement ``(4, 4)``, velocity and acceleration ``(6,)`` at ``t``.

        Before the start and after the end, the same read-only sample at every call.
        """
        held = _held(self._ends, float(t) - self._p.t0, self._p.duration,
                     lambda _end: self._sample(t))
        return self._sample(t) if held is None else held

    def _sample(self, t: float) -> TrajectorySample:
        p = self._p.sample(t)
        r = self._r.sample(t)
        H = np.eye(4)
        H[:3, :3] = r.position
        H[:3, 3] = p.position
        return TrajectorySample(
            H,
            np.concatenate([p.velocity, r.velocity]),
            np.concatenate([p.acceleration, r.acceleration]),
        )
