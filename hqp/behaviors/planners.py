"""Trajectory generators feeding a behavior's ``plan.*`` names: hqp's walking planner.

:class:`WalkPlanner` (planner type ``walk``) plans a straight walk from the robot's current
stance, in three parts written from the equations:

- **Footsteps** (:func:`plan_footsteps`), a naive planner: the feet step in turn (left
  first) towards their targets ``distance`` ahead along the robot's heading, each footstep
  at most ``step_length`` ahead of the foot that supports it, at the robot's own foot
  spacing (read from its feet frames, so any humanoid walks at its own stance width); the
  last footsteps bring the feet side by side.
- **Supports** (:func:`make_supports`): a start double support of
  ``startend_double_support_ratio * single_support_duration``, then for each footstep a
  single support of ``single_support_duration`` on the other foot, separated by double
  supports of ``double_support_ratio * single_support_duration``, and an end double support
  as long as the start one.
- **Centre of mass** (:mod:`hqp.behaviors.lipm`): ZMP preview control of the cart-table
  model at the robot's standing centre-of-mass height (Kajita et al. 2003; gains from the
  discrete Riccati equation). The ZMP reference is the centre of the support polygon: the
  stance sole's centre in single support, moving in a straight line from one sole centre to
  the next in double support (through the centre of the two feet), from the standing
  centre of mass to the first stance sole over the second half of the start double support
  and to the centre of the final feet over the first half of the end one. The plan is
  checked: its ZMP ``p = c - c_ddot / omega^2`` stays inside every support polygon.

The swing feet follow :class:`SwingTrajectory` between the lift-off and the touchdown of
each single support: a minimum-jerk horizontal motion from the footstep left to the
footstep reached, plus a vertical bump ``64 h s^3 (1 - s)^3`` of peak ``h``; position,
velocity and acceleration are continuous, and both are zero at lift-off and at touchdown
(the foot lands with no impact velocity).

Behavior files written for the earlier planner (PlaCo's, type ``placo_walk``) keep working:
``placo_walk`` is an alias of ``walk`` and its parameters are the same, except PlaCo's own
discretisation (``planned_timesteps``, ``single_support_timesteps``, ``foot_rise_ratio``),
replaced by ``preview_time`` and ``timestep``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import ConvexHull

from hqp.behaviors.lipm import lipm_omega, preview_com, preview_gains
from hqp.errors import BehaviorFileError
from hqp.model import RobotModel
from hqp.tasks.reference import min_jerk_profile

PLANNER_TYPES: tuple[str, ...] = ("walk", "placo_walk")
"""Planner types of :class:`WalkPlanner` (``placo_walk``: the earlier name, an alias)."""

WALK_DEFAULTS: dict[str, float | int] = {
    "distance": 1.0,
    "step_length": 0.11,
    "single_support_duration": 0.6,
    "double_support_ratio": 0.5,
    "startend_double_support_ratio": 2.0,
    "foot_height": 0.05,
    "zmp_margin": 0.02,
    "com_height_offset": 0.0,
    "preview_time": 1.6,
    "timestep": 0.005,
    "start_delay": 0.0,
    "swing_delay": 0.0,
    "landing_margin": 0.0,
    "unload_lead": 0.05,
}
"""Parameters of the ``walk`` planner: ``distance`` to walk forward [m], maximum
``step_length`` of a footstep ahead of the supporting foot [m] (a foot moves up to twice
this per step), ``single_support_duration`` [s], ``double_support_ratio`` and
``startend_double_support_ratio`` (double supports between footsteps, and at the start and
the end, as fractions of a single support), swing ``foot_height`` [m], ``zmp_margin``: the
least distance [m] the planned ZMP keeps from the edges of the support polygon (its
reference is the polygon's centre; tests check the margin), ``com_height_offset``: walking
centre-of-mass height above the standing one [m], ``preview_time``: the preview
controller's horizon [s], ``timestep``: its sampling period [s], ``start_delay``: time after
the behavior starts at which the plan begins [s]; ``swing_delay`` and ``landing_margin``: the
swing foot lifts this long after a single support begins and lands this long before it ends
[s]; ``unload_lead``: how long before a lift-off ``plan.<side>_unload`` is true (the time
given to unload the foot) [s]."""

_PLACO_ONLY = {"planned_timesteps": "preview_time", "single_support_timesteps": "timestep",
               "foot_rise_ratio": "foot_height"}
"""Parameters of PlaCo's planner that this one does not have, and what to set instead."""

_POSITIVE = ("step_length", "single_support_duration", "preview_time", "timestep")
"""Parameters that must be strictly positive."""

_SIDES = ("left", "right")

ZMP_WEIGHT = 1.0
"""Weight ``Q_e`` of the ZMP error in the preview controller's cost [1/m^2]."""

JERK_WEIGHT = 1e-6
"""Weight ``R`` of the jerk increment in the preview controller's cost (Kajita et al.'s)."""


def _bump(s: float) -> tuple[float, float, float]:
    """Swing height profile ``64 s^3 (1 - s)^3`` (peak 1 at ``s = 1/2``) and its derivatives."""
    u = 1.0 - s
    return (64.0 * s**3 * u**3,
            192.0 * s * s * u * u * (u - s),
            384.0 * s * u * ((u - s) ** 2 - s * u))


class SwingTrajectory:
    """Trajectory of a swing foot's frame origin between two footsteps.

    ``p(t) = p0 + (p1 - p0) m(s) + e_z h b(s)`` with ``s = (t - t_lift) / (t_land - t_lift)``,
    ``m`` the minimum-jerk profile and ``b(s) = 64 s^3 (1 - s)^3`` the height profile:
    velocity and acceleration are zero at lift-off and at touchdown.

    Args:
        side: ``"left"`` or ``"right"``.
        t_lift: Lift-off time [s] (plan time).
        t_land: Touchdown time [s], after ``t_lift``.
        start: Position at lift-off ``(3,)`` [m].
        end: Position at touchdown ``(3,)`` [m].
        height: Peak height above the straight line from ``start`` to ``end`` [m].

    Raises:
        BehaviorFileError: ``t_land <= t_lift``.

    """

    def __init__(self, side: str, t_lift: float, t_land: float, start: np.ndarray,
                 end: np.ndarray, height: float) -> None:
        if not t_land > t_lift:
            raise BehaviorFileError(f"walk planner: a {side} swing lands at {t_land:.3f} s, "
                                    f"not after its lift-off at {t_lift:.3f} s (increase the "
                                    "single support duration or reduce swing_delay and "
                                    "landing_margin)")
        self.side = side
        self.t_lift = float(t_lift)
        self.t_land = float(t_land)
        self.start = np.asarray(start, dtype=float).copy()
        self.end = np.asarray(end, dtype=float).copy()
        self.height = float(height)

    @property
    def duration(self) -> float:
        """Time in the air [s]."""
        return self.t_land - self.t_lift

    def progress(self, t: float) -> float:
        """Fraction ``s`` of the swing done at time ``t`` [s], clipped to [0, 1]."""
        return min(max((float(t) - self.t_lift) / self.duration, 0.0), 1.0)

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position ``(3,)`` [m], velocity [m/s] and acceleration [m/s^2] at time ``t`` [s]."""
        s = self.progress(t)
        T = self.duration
        m, dm, ddm = min_jerk_profile(s, 1.0)
        b, db, ddb = _bump(s)
        delta = self.end - self.start
        up = np.array([0.0, 0.0, self.height])
        p = self.start + m * delta + b * up
        v = (dm * delta + db * up) / T
        a = (ddm * delta + ddb * up) / T**2
        return p, v, a


@dataclass(frozen=True)
class Footstep:
    """A placement of one foot on the floor.

    Attributes:
        side: ``"left"`` or ``"right"``.
        position: Sole centre (the foot frame's origin) in the world ``(3,)`` [m].
        rotation: Foot frame orientation ``R_world_foot`` ``(3, 3)``.

    """

    side: str
    position: np.ndarray
    rotation: np.ndarray

    def corners(self, half_length: float, half_width: float) -> np.ndarray:
        """Sole corners in the world's horizontal plane ``(4, 2)`` [m]."""
        local = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
        local = local * [half_length, half_width]
        return self.position[:2] + local @ self.rotation[:2, :2].T


@dataclass(frozen=True)
class Support:
    """A support phase of the walk: the feet on the floor over ``[t_start, t_end)``.

    Attributes:
        t_start: Start [s] (plan time).
        t_end: End [s].
        feet: The footsteps on the floor: two in double support, one in single support.

    """

    t_start: float
    t_end: float
    feet: tuple[Footstep, ...]

    @property
    def double(self) -> bool:
        """Both feet on the floor."""
        return len(self.feet) == 2

    def polygon(self, half_length: float, half_width: float) -> np.ndarray:
        """Return the support polygon as half-planes ``(m, 3)``, rows ``(n, d)``.

        A horizontal point ``p`` is inside where every row's ``n . p + d <= 0`` (``n`` a unit
        normal), and ``-(n . p + d)`` is its distance to that edge [m].
        """
        corners = np.vstack([f.corners(half_length, half_width) for f in self.feet])
        return ConvexHull(corners).equations


def _heading(T_left: np.ndarray, T_right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward and leftward horizontal unit vectors of a stance ``(3,)``, ``(3,)``."""
    forward = T_left[:3, 0] + T_right[:3, 0]
    forward[2] = 0.0
    norm = float(np.linalg.norm(forward))
    if norm < 1e-9:
        raise BehaviorFileError("walk planner: the feet frames' x axes do not point forward "
                                "(they are vertical or opposite)")
    forward /= norm
    return forward, np.array([-forward[1], forward[0], 0.0])


def plan_footsteps(T_left: np.ndarray, T_right: np.ndarray, distance: float,
                   step_length: float, *, max_steps: int = 1000) -> list[Footstep]:
    """Naive footsteps of a straight walk of ``distance`` along the stance's heading.

    The heading is the mean of the feet frames' horizontal x axes; the feet keep their
    lateral offsets and orientations (so the robot's own foot spacing). The feet step in
    turn, left first: a footstep lands at most ``step_length`` ahead of (or behind) the
    supporting foot, along the heading, as close as it can to its own target
    ``distance`` ahead of where it started. The walk ends when a step reaches its target
    and the next one, of the other foot, does too.

    Args:
        T_left: Left foot placement ``T_world_left`` ``(4, 4)``.
        T_right: Right foot placement ``(4, 4)``.
        distance: Forward distance [m] (negative: backward).
        step_length: Largest offset along the heading between a footstep and the
            supporting foot [m], positive.
        max_steps: Guard on the number of footsteps.

    Returns:
        The initial left and right feet, then the footsteps in order.

    Raises:
        BehaviorFileError: A step length that is not positive, feet frames with no
            horizontal heading, or more than ``max_steps`` footsteps.

    """
    if not step_length > 0.0:
        raise BehaviorFileError(f"walk planner: step_length must be positive, got {step_length!r}")
    T = {"left": np.asarray(T_left, dtype=float), "right": np.asarray(T_right, dtype=float)}
    forward, _ = _heading(T["left"], T["right"])
    along = {side: float(T[side][:3, 3] @ forward) for side in _SIDES}
    target = {side: along[side] + float(distance) for side in _SIDES}
    steps = [Footstep(side, T[side][:3, 3].copy(), T[side][:3, :3].copy()) for side in _SIDES]
    arrived = {"left": False, "right": False}
    swing, support = "left", "right"
    while not (arrived["left"] and arrived["right"]):
        if len(steps) - 2 >= max_steps:
            raise BehaviorFileError(f"walk planner: more than {max_steps} footsteps "
                                    f"(distance {distance!r} m, step_length {step_length!r} m)")
        error = target[swing] - along[support]
        advance = min(max(error, -step_length), step_length)
        arrived[swing] = abs(error) <= step_length
        # along the heading: the supporting foot's position plus the advance; across: unchanged
        position = T[swing][:3, 3] + (along[support] + advance
                                      - float(T[swing][:3, 3] @ forward)) * forward
        along[swing] = along[support] + advance
        steps.append(Footstep(swing, position, T[swing][:3, :3].copy()))
        swing, support = support, swing
    return steps


def make_supports(footsteps: Sequence[Footstep], single: float, double: float,
                  startend: float) -> list[Support]:
    """Support phases of a footstep sequence (initial left and right feet first).

    Args:
        footsteps: From :func:`plan_footsteps`.
        single: Single support duration [s] (one per footstep after the initial feet).
        double: Double support duration between footsteps [s] (0: none).
        startend: Duration of the start and end double supports [s].

    Returns:
        The supports in time order, contiguous from 0.

    """
    feet = {footsteps[0].side: footsteps[0], footsteps[1].side: footsteps[1]}
    supports: list[Support] = []
    t = 0.0

    def add(duration: float, on: tuple[Footstep, ...]) -> None:
        nonlocal t
        if duration > 0.0:
            supports.append(Support(t, t + duration, on))
            t += duration

    add(startend, (feet["left"], feet["right"]))
    moves = footsteps[2:]
    for i, step in enumerate(moves):
        stance = feet["right" if step.side == "left" else "left"]
        add(single, (stance,))
        feet[step.side] = step
        add(startend if i == len(moves) - 1 else double, (feet["left"], feet["right"]))
    return supports


def zmp_reference(supports: Sequence[Support], com_xy: np.ndarray, t: np.ndarray) -> np.ndarray:
    """ZMP reference ``(n, 2)`` [m] at times ``t`` ``(n,)`` [s] (module docstring).

    Single support: the stance sole's centre. Double support between footsteps: a straight
    line from the previous stance sole's centre to the next one. Start: the standing centre
    of mass, then (second half) a line to the first stance sole; end: a line to the centre
    of the final feet (first half), then held. Beyond the last support: held.
    """
    knots_t: list[float] = []
    knots_p: list[np.ndarray] = []
    n = len(supports)
    for i, s in enumerate(supports):
        if not s.double:
            knots_t += [s.t_start, s.t_end]
            knots_p += [s.feet[0].position[:2], s.feet[0].position[:2]]
        elif i == 0:
            mid = 0.5 * (s.t_start + s.t_end) if n > 1 else s.t_end
            knots_t += [s.t_start, mid]
            knots_p += [np.asarray(com_xy, dtype=float), np.asarray(com_xy, dtype=float)]
        elif i == n - 1:
            centre = 0.5 * (s.feet[0].position[:2] + s.feet[1].position[:2])
            mid = 0.5 * (s.t_start + s.t_end)
            knots_t += [mid, s.t_end]
            knots_p += [centre, centre]
    kt = np.array(knots_t)
    kp = np.array(knots_p)
    return np.column_stack([np.interp(t, kt, kp[:, a]) for a in range(2)])


_OUTPUT_GROUP: dict[str, str] = {
    "com": "com", "com_velocity": "com", "com_acceleration": "com", "zmp": "zmp",
    "trunk_rotation": "trunk", "double_support": "plan", "started": "plan", "done": "plan",
    "steps_planned": "plan", "swings": "plan", "support_center": "feet",
    **{f"{side}_{key}": "feet" for side in _SIDES
       for key in ("foot", "foot_velocity", "foot_acceleration", "swing", "swing_progress",
                   "unload")},
}
"""Each ``plan.*`` value and the group computed with it (:meth:`WalkPlanner.output`)."""

OUTPUT_NAMES: tuple[str, ...] = tuple(_OUTPUT_GROUP)
"""The ``plan.*`` values of :class:`WalkPlanner`."""


class WalkPlanner:
    """Footsteps, supports, swing feet and the centre of mass of a walk, as ``plan.*`` values.

    Args:
        params: Planner parameters (see :data:`WALK_DEFAULTS`).
        feet: The robot's ``(left, right)`` sole frames.
        foot_length: Sole length [m].
        foot_width: Sole width [m].
        where: Prefix of error messages (the behavior file).

    Raises:
        BehaviorFileError: An unknown or invalid parameter.

    Attributes:
        footsteps: The footsteps (the first two are the initial feet), after :meth:`start`.
        supports: The support phases, in time order.
        swings: The swing trajectories, in time order.
        omega: The LIPM's natural frequency [1/s].
        com_height: The walking centre-of-mass height [m].
        samples: Times of the centre-of-mass samples ``(n,)`` [s] (plan time).
        zmp_ref: The ZMP reference at :attr:`samples` ``(n, 2)`` [m].

    """

    def __init__(
        self,
        params: Mapping[str, Any],
        *,
        feet: tuple[str, str] = ("left_foot", "right_foot"),
        foot_length: float,
        foot_width: float,
        where: str = "planner",
    ) -> None:
        for key, value in params.items():
            if key in _PLACO_ONLY:
                raise BehaviorFileError(f"{where}: planner.{key}: a parameter of PlaCo's planner, "
                                        f"which hqp no longer uses; set {_PLACO_ONLY[key]} "
                                        "instead (see docs/results/behaviors.md)")
            if key not in WALK_DEFAULTS:
                raise BehaviorFileError(f"{where}: planner.{key}: unknown key; expected one of "
                                        f"{', '.join(sorted(WALK_DEFAULTS))}")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                key != "com_height_offset" and value < 0
            ) or not math.isfinite(value):
                raise BehaviorFileError(f"{where}: planner.{key}: expected a non-negative "
                                        f"number, got {value!r}")
            if key in _POSITIVE and value == 0:
                raise BehaviorFileError(f"{where}: planner.{key}: expected a positive number, "
                                        f"got {value!r}")
        if not (foot_length > 0.0 and foot_width > 0.0):
            raise BehaviorFileError(f"{where}: walk planner: the soles must have a positive "
                                    f"size, got {foot_length!r} x {foot_width!r} m")
        self.params = {**WALK_DEFAULTS, **params}
        self.feet = (str(feet[0]), str(feet[1]))
        self.foot_length = float(foot_length)
        self.foot_width = float(foot_width)
        self.where = where
        self.footsteps: list[Footstep] = []
        self.supports: list[Support] = []
        self.swings: list[SwingTrajectory] = []
        self.omega = 0.0
        self.com_height = 0.0
        self.samples = np.zeros(0)
        self.zmp_ref = np.zeros((0, 2))
        self.t_start = 0.0
        self._states = np.zeros((0, 3, 2))
        self._jerks = np.zeros((0, 2))
        self._z0 = 0.0
        self._z1 = 0.0
        self._heading = np.eye(3)
        self._last: tuple[float, dict[str, Any]] | None = None

    @property
    def planned(self) -> bool:
        """Whether :meth:`start` has planned the walk."""
        return bool(self.supports)

    @property
    def duration(self) -> float:
        """Duration of the plan [s]: the end of its last support (0 before :meth:`start`)."""
        return self.supports[-1].t_end if self.supports else 0.0

    def start(self, model: RobotModel, t: float) -> None:
        """Plan from the current feet and centre of mass (``model`` updated), from time ``t``.

        Raises:
            BehaviorFileError: Feet frames with no horizontal heading, a swing that does
                not fit in its single support, or a planned ZMP that leaves a support
                polygon (steps too long or too fast for this robot).

        """
        p = self.params
        T_left = model.frame_placement(self.feet[0]).homogeneous.copy()
        T_right = model.frame_placement(self.feet[1]).homogeneous.copy()
        com = np.array(model.com, dtype=float)
        forward, left = _heading(T_left, T_right)
        self._heading = np.column_stack((forward, left, [0.0, 0.0, 1.0]))
        self.footsteps = plan_footsteps(T_left, T_right, float(p["distance"]),
                                        float(p["step_length"]))
        single = float(p["single_support_duration"])
        self.supports = make_supports(self.footsteps, single,
                                      float(p["double_support_ratio"]) * single,
                                      float(p["startend_double_support_ratio"]) * single)
        self.com_height = float(com[2] + p["com_height_offset"] - self._floor_height())
        if not self.com_height > 0.0:
            raise BehaviorFileError(f"{self.where}: walk planner: the centre of mass is "
                                    f"{self.com_height:.3f} m above the soles (com_height_offset "
                                    "too low)")
        self.omega = lipm_omega(self.com_height)
        self._z0 = float(com[2])
        self._z1 = float(com[2] + p["com_height_offset"])
        dt = float(p["timestep"])
        settle = float(p["preview_time"])
        n = int(math.ceil((self.duration + settle) / dt))
        self.samples = dt * np.arange(n + 1)
        self.zmp_ref = zmp_reference(self.supports, com[:2], self.samples)
        gains = preview_gains(self.omega, dt, max(1, int(round(settle / dt))),
                              q_e=ZMP_WEIGHT, r=JERK_WEIGHT)
        x0 = np.zeros((3, 2))
        x0[0] = com[:2]
        self._states, self._jerks = preview_com(x0, self.zmp_ref[:-1], gains)
        self.t_start = float(t) + float(p["start_delay"])
        self.swings = self._plan_swings()
        self._last = None
        worst, t_worst = self.zmp_support_margin()
        if worst < 0.0:
            raise BehaviorFileError(
                f"{self.where}: walk planner: the planned ZMP leaves the support polygon by "
                f"{-worst * 1e3:.1f} mm at {t_worst:.2f} s (shorter steps, longer supports or "
                "a longer preview_time)")

    def _floor_height(self) -> float:
        """Height of the floor under the initial feet [m] (the soles' mean height)."""
        return 0.5 * float(self.footsteps[0].position[2] + self.footsteps[1].position[2])

    def _plan_swings(self) -> list[SwingTrajectory]:
        """One swing per single support, from the foot's footstep before to the one after."""
        p = self.params
        swings = []
        last = {f.side: f for f in self.footsteps[:2]}
        moves = iter(self.footsteps[2:])
        for support in self.supports:
            if support.double:
                continue
            step = next(moves)
            swings.append(SwingTrajectory(
                step.side, support.t_start + float(p["swing_delay"]),
                support.t_end - float(p["landing_margin"]), last[step.side].position,
                step.position, float(p["foot_height"])))
            last[step.side] = step
        return swings

    def com_state(self, tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Planned centre of mass at plan time ``tau`` [s]: position, velocity, acceleration.

        Horizontal: the preview controller's piecewise cubic, held at its last sample after
        the plan (and the preview time that lets it settle); vertical: a minimum-jerk move
        from the standing height to the walking height over the start double support.
        """
        dt = float(self.params["timestep"])
        n = self._jerks.shape[0]
        tau = min(max(float(tau), 0.0), n * dt)
        k = min(int(tau // dt), n - 1)
        s = tau - k * dt
        # the cubic per axis in Python floats: the operations, in the order, of the
        # vector expression c + v s + a s s / 2 + j s^3 / 6 (a few floats: no numpy calls)
        (cx, cy), (vx, vy), (ax, ay) = self._states[k].tolist()
        jx, jy = self._jerks[k].tolist()
        s3 = s**3
        pos = [cx + vx * s + ax * s * s / 2 + jx * s3 / 6,
               cy + vy * s + ay * s * s / 2 + jy * s3 / 6, 0.0]
        if tau >= n * dt:
            vel = [0.0, 0.0, 0.0]
            acc = [0.0, 0.0, 0.0]
        else:
            vel = [vx + ax * s + jx * s * s / 2, vy + ay * s + jy * s * s / 2, 0.0]
            acc = [ax + jx * s, ay + jy * s, 0.0]
        ramp = self.supports[0].t_end
        m, dm, ddm = min_jerk_profile(tau, ramp)
        dz = self._z1 - self._z0
        pos[2], vel[2], acc[2] = self._z0 + m * dz, dm * dz, ddm * dz
        return np.array(pos), np.array(vel), np.array(acc)

    def support_at(self, tau: float) -> Support:
        """Return the support phase at plan time ``tau`` [s] (first or last outside the plan)."""
        for support in self.supports:
            if tau < support.t_end:
                return support
        return self.supports[-1]

    def zmp_support_margin(self) -> tuple[float, float]:
        """Least distance of the planned ZMP inside its support polygon, and when.

        Returns:
            The distance [m] (negative: outside) and the plan time [s], over the samples.

        """
        half_l, half_w = 0.5 * self.foot_length, 0.5 * self.foot_width
        worst, t_worst = np.inf, 0.0
        t = self.samples[:-1]
        zmp = self._states[:-1, 0] - self._states[:-1, 2] / self.omega**2
        for support in self.supports:
            inside = (t >= support.t_start) & (t < support.t_end)
            if not inside.any():
                continue
            eq = support.polygon(half_l, half_w)
            dist = -(zmp[inside] @ eq[:, :2].T + eq[:, 2]).max(axis=1)
            k = int(np.argmin(dist))
            if dist[k] < worst:
                worst, t_worst = float(dist[k]), float(t[inside][k])
        return worst, t_worst

    def _foot(self, side: str, tau: float) -> dict[str, Any]:
        """Planned state of one foot at plan time ``tau`` [s]."""
        lead = float(self.params["unload_lead"])
        position = next(f for f in self.footsteps[:2] if f.side == side).position
        for sw in self.swings:
            if sw.side != side:
                continue
            if sw.t_lift <= tau < sw.t_land:
                pos, vel, acc = sw.sample(tau)
                return {"position": pos, "velocity": vel, "acceleration": acc, "swing": True,
                        "progress": sw.progress(tau), "unload": False}
            if sw.t_lift - lead <= tau < sw.t_lift:
                return {"position": sw.start.copy(), "velocity": np.zeros(3),
                        "acceleration": np.zeros(3), "swing": False, "progress": 0.0,
                        "unload": True}
            if sw.t_land <= tau:
                position = sw.end
        return {"position": position.copy(), "velocity": np.zeros(3),
                "acceleration": np.zeros(3), "swing": False, "progress": 0.0, "unload": False}

    output_names = OUTPUT_NAMES
    """The names of :meth:`outputs`."""

    def outputs(self, t: float) -> dict[str, Any]:
        """Return the ``plan.*`` values at behavior time ``t`` [s] (clamped to the plan).

        ``com``, ``com_velocity``, ``com_acceleration`` ``(3,)`` and ``zmp`` (of the planned
        centre of mass, ``c - c_ddot / omega^2``, ``(2,)``); ``trunk_rotation`` (the walk's
        heading, ``(3, 3)``); per foot (``left_``/``right_`` prefix): ``foot`` position
        ``(3,)`` [m] with its ``foot_velocity`` and ``foot_acceleration``, ``swing`` (in the
        air between lift-off and touchdown), ``swing_progress`` (fraction of the swing done,
        0 outside one), ``unload`` (within ``unload_lead`` before a lift-off);
        ``double_support``, ``started``, ``done``, ``steps_planned`` (footsteps, initial feet
        included), ``swings`` (swing phases planned), ``support_center``.

        Raises:
            BehaviorFileError: Called before :meth:`start`.

        """
        return {name: self.output(name, t) for name in OUTPUT_NAMES}

    def output(self, name: str, t: float) -> Any:
        """Return one of the :meth:`outputs` at ``t``, computing only its group (kept per ``t``).

        Raises:
            BehaviorFileError: Called before :meth:`start`.
            KeyError: Not one of :data:`OUTPUT_NAMES`.

        """
        if not self.planned:
            raise BehaviorFileError("walk planner: outputs() before start()")
        if self._last is None or self._last[0] != t:
            self._last = (t, {})
        values = self._last[1]
        try:
            return values[name]
        except KeyError:
            pass
        group = _OUTPUT_GROUP[name]  # KeyError: not an output
        tau = max(float(t) - self.t_start, 0.0)
        if group in ("com", "zmp"):
            c, v, a = self.com_state(tau)
            values["com"], values["com_velocity"], values["com_acceleration"] = c, v, a
            values["zmp"] = c[:2] - a[:2] / self.omega**2
        elif group == "trunk":
            values["trunk_rotation"] = self._heading.copy()
        elif group == "feet":
            feet = {side: self._foot(side, tau) for side in _SIDES}
            values["support_center"] = 0.5 * (feet["left"]["position"]
                                              + feet["right"]["position"])
            for side, f in feet.items():
                values[f"{side}_foot"] = f["position"]
                values[f"{side}_foot_velocity"] = f["velocity"]
                values[f"{side}_foot_acceleration"] = f["acceleration"]
                values[f"{side}_swing"] = f["swing"]
                values[f"{side}_swing_progress"] = f["progress"]
                values[f"{side}_unload"] = f["unload"]
        else:
            values["double_support"] = self.support_at(tau).double
            values["started"] = float(t) >= self.t_start
            values["done"] = float(t) - self.t_start >= self.duration
            values["steps_planned"] = len(self.footsteps)
            values["swings"] = len(self.swings)
        return values[name]
