"""Trajectory generators feeding a behavior's ``plan.*`` names.

:class:`PlacoWalkPlanner` wraps PlaCo's walking planners (PlaCo 0.10.2):
``placo.FootstepsPlannerNaive`` places footsteps towards a target,
``FootstepsPlanner.make_supports`` turns them into single and double
supports, and ``placo.WalkPatternGenerator`` (a LIPM / ZMP preview planner,
``placo.LIPM``'s natural frequency ``omega = sqrt(g / h)``) plans the centre
of mass and the ZMP. hqp does not write another ZMP preview controller; it
tracks these trajectories with its own tasks.

The swing feet follow :class:`SwingTrajectory` (PlaCo's own swing spline starts
with a non-zero acceleration): between the lift-off and the touchdown of
PlaCo's single supports, a minimum-jerk horizontal motion from the footstep
left to the footstep reached, plus a vertical bump ``64 h s^3 (1 - s)^3`` of
peak ``h``; position, velocity and acceleration are continuous, and both are
zero at lift-off and at touchdown (the foot lands with no impact velocity).
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hqp.errors import BehaviorFileError
from hqp.model import RobotModel
from hqp.tasks.reference import min_jerk_profile

logger = logging.getLogger(__name__)


@contextlib.contextmanager
def placo_stderr_to_log() -> Iterator[None]:
    """Contain what PlaCo's C++ code writes on stderr: logged at debug level instead.

    PlaCo's ``HumanoidRobot`` prints ``WARNING: Can't find trunk frames ...`` for robots
    without its frame names (its leg-spacing and camera helpers, which hqp does not use).
    """
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no real file descriptor (a test harness's stream)
        yield
        return
    with tempfile.TemporaryFile(mode="w+b") as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            for line in sink.read().decode(errors="replace").splitlines():
                if line.strip():
                    logger.debug("placo: %s", line)


WALK_DEFAULTS: dict[str, float | int] = {
    "distance": 1.0,
    "step_length": 0.11,
    "single_support_duration": 0.6,
    "double_support_ratio": 0.5,
    "startend_double_support_ratio": 2.0,
    "foot_height": 0.05,
    "foot_rise_ratio": 0.2,
    "zmp_margin": 0.02,
    "com_height_offset": 0.0,
    "planned_timesteps": 100,
    "single_support_timesteps": 10,
    "start_delay": 0.0,
    "swing_delay": 0.0,
    "landing_margin": 0.0,
    "unload_lead": 0.05,
}
"""Parameters of the ``placo_walk`` planner: ``distance`` to walk forward [m], maximum
``step_length`` between consecutive footsteps [m] (each foot moves twice this per
step), support durations [s] and ratios, swing ``foot_height`` [m], ZMP margin in
the sole [m], CoM height offset from the initial one [m], PlaCo's preview horizon and
time discretisation (``planned_timesteps``, ``single_support_timesteps`` per single
support), ``start_delay``: time after the behavior starts at which the plan begins [s];
``swing_delay`` and ``landing_margin``: the swing foot lifts this long after a single
support begins and lands this long before it ends [s]; ``unload_lead``: how long before
a lift-off ``plan.<side>_unload`` is true (the time given to unload the foot) [s]."""

_SIDES = ("left", "right")


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
            raise BehaviorFileError(f"placo_walk planner: a {side} swing lands at {t_land:.3f} s, "
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


_OUTPUT_GROUP: dict[str, str] = {
    "com": "com", "com_velocity": "com", "com_acceleration": "com", "zmp": "zmp",
    "trunk_rotation": "trunk", "double_support": "plan", "started": "plan", "done": "plan",
    "steps_planned": "plan", "swings": "plan", "support_center": "feet",
    **{f"{side}_{key}": "feet" for side in ("left", "right")
       for key in ("foot", "foot_velocity", "foot_acceleration", "swing", "swing_progress",
                   "unload")},
}
"""Each ``plan.*`` value and the group computed with it (:meth:`PlacoWalkPlanner.output`)."""

OUTPUT_NAMES: tuple[str, ...] = tuple(_OUTPUT_GROUP)
"""The ``plan.*`` values of :class:`PlacoWalkPlanner`."""


class PlacoWalkPlanner:
    """Footsteps and centre-of-mass / ZMP trajectories from PlaCo, as ``plan.*`` values.

    Args:
        urdf: Path of the robot's URDF (PlaCo expects frames ``trunk``,
            ``left_foot``, ``right_foot``).
        params: Planner parameters (see :data:`WALK_DEFAULTS`).
        foot_length: Sole length [m].
        foot_width: Sole width [m].
        where: Prefix of error messages (the behavior file).

    Raises:
        BehaviorFileError: An unknown or invalid parameter.

    Attributes:
        trajectory: PlaCo's ``WPGTrajectory`` (after :meth:`start`).
        footsteps: PlaCo's footsteps, homogeneous transforms ``(4, 4)`` (the first two are
            the initial feet).
        swings: The swing trajectories, in time order.

    """

    def __init__(
        self,
        urdf: str | Path,
        params: Mapping[str, Any],
        *,
        foot_length: float,
        foot_width: float,
        where: str = "planner",
    ) -> None:
        for key, value in params.items():
            if key not in WALK_DEFAULTS:
                raise BehaviorFileError(f"{where}: planner.{key}: unknown key; expected one of "
                                        f"{', '.join(sorted(WALK_DEFAULTS))}")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                key != "com_height_offset" and value < 0
            ):
                raise BehaviorFileError(f"{where}: planner.{key}: expected a non-negative "
                                        f"number, got {value!r}")
        self.params = {**WALK_DEFAULTS, **params}
        self.urdf = Path(urdf)
        self.foot_length = float(foot_length)
        self.foot_width = float(foot_width)
        self.where = where
        self.trajectory: Any = None
        self.footsteps: list[np.ndarray] = []
        self.swings: list[SwingTrajectory] = []
        self.t_start = 0.0
        self.omega = 0.0
        self._last: tuple[float, dict[str, Any]] | None = None

    def start(self, model: RobotModel, t: float) -> None:
        """Plan from the current feet and centre of mass (``model`` updated), from time ``t``."""
        import placo

        p = self.params
        with placo_stderr_to_log():
            robot = placo.HumanoidRobot("", 0, self.urdf.read_text())
        T_left = model.frame_placement("left_foot").homogeneous.copy()
        T_right = model.frame_placement("right_foot").homogeneous.copy()
        com = model.com.copy()
        hp = placo.HumanoidParameters()
        hp.single_support_duration = float(p["single_support_duration"])
        hp.single_support_timesteps = int(p["single_support_timesteps"])
        hp.double_support_ratio = float(p["double_support_ratio"])
        hp.startend_double_support_ratio = float(p["startend_double_support_ratio"])
        hp.planned_timesteps = int(p["planned_timesteps"])
        hp.walk_com_height = float(com[2] + p["com_height_offset"])
        hp.walk_foot_height = float(p["foot_height"])
        hp.walk_foot_rise_ratio = float(p["foot_rise_ratio"])
        hp.walk_trunk_pitch = 0.0
        hp.foot_length = self.foot_length
        hp.foot_width = self.foot_width
        hp.feet_spacing = float(np.linalg.norm(T_left[:2, 3] - T_right[:2, 3]))
        hp.zmp_margin = float(p["zmp_margin"])
        hp.walk_max_dx_forward = float(p["step_length"])
        planner = placo.FootstepsPlannerNaive(hp)
        target_left, target_right = T_left.copy(), T_right.copy()
        target_left[0, 3] += float(p["distance"])
        target_right[0, 3] += float(p["distance"])
        planner.configure(target_left, target_right)
        footsteps = planner.plan(placo.HumanoidRobot_Side.left, T_left, T_right)
        supports = placo.FootstepsPlanner.make_supports(footsteps, 0.0, True, True, True)
        with placo_stderr_to_log():
            wpg = placo.WalkPatternGenerator(robot, hp)
            self.trajectory = wpg.plan(supports, com, 0.0)
        self.footsteps = [np.array(f.frame) for f in footsteps]
        self.omega = float(placo.LIPM.compute_omega(hp.walk_com_height))
        self.t_start = float(t) + float(p["start_delay"])
        self._sides = (placo.HumanoidRobot_Side.left, placo.HumanoidRobot_Side.right)
        self._com_height = hp.walk_com_height
        self.swings = self._plan_swings()
        self._last = None

    def _single_supports(self) -> list[tuple[str, float, float]]:
        """PlaCo's single supports as ``(swing side, t_begin, t_end)`` [s] (plan time)."""
        traj = self.trajectory
        out: list[tuple[str, float, float]] = []
        grid = np.arange(0.0, float(traj.t_end), 1e-3)
        current: tuple[str, float] | None = None
        for x in grid:
            side = None
            if not traj.support_is_both(float(x)):
                side = "left" if traj.support_side(float(x)) == self._sides[1] else "right"
            if current is not None and side != current[0]:
                out.append((current[0], current[1], float(x)))
                current = None
            if side is not None and current is None:
                current = (side, float(x))
        if current is not None:
            out.append((current[0], current[1], float(traj.t_end)))
        # exact bounds from PlaCo's trajectory parts
        exact = []
        for side, a, b in out:
            mid = 0.5 * (a + b)
            exact.append((side, float(traj.get_part_t_start(mid)), float(traj.get_part_t_end(mid))))
        return exact

    def _plan_swings(self) -> list[SwingTrajectory]:
        traj = self.trajectory
        p = self.params
        swings = []
        for side, a, b in self._single_supports():
            frame = traj.get_T_world_left if side == "left" else traj.get_T_world_right
            start = np.array(frame(a))[:3, 3]
            end = np.array(frame(max(b - 1e-6, a)))[:3, 3]
            swings.append(SwingTrajectory(side, a + float(p["swing_delay"]),
                                          b - float(p["landing_margin"]), start, end,
                                          float(p["foot_height"])))
        return swings

    @property
    def duration(self) -> float:
        """Duration of the plan [s]."""
        return float(self.trajectory.t_end) if self.trajectory is not None else 0.0

    def _foot(self, side: str, tau: float) -> dict[str, Any]:
        """Planned state of one foot at plan time ``tau`` [s]."""
        lead = float(self.params["unload_lead"])
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
        frame = self.trajectory.get_T_world_left if side == "left" else \
            self.trajectory.get_T_world_right
        return {"position": np.array(frame(tau))[:3, 3].copy(), "velocity": np.zeros(3),
                "acceleration": np.zeros(3), "swing": False, "progress": 0.0, "unload": False}

    output_names = OUTPUT_NAMES
    """The names of :meth:`outputs`."""

    def outputs(self, t: float) -> dict[str, Any]:
        """Return the ``plan.*`` values at behavior time ``t`` [s] (clamped to the plan).

        ``com``, ``com_velocity``, ``com_acceleration`` ``(3,)`` and ``zmp`` from PlaCo;
        per foot (``left_``/``right_`` prefix): ``foot`` position ``(3,)`` [m] with its
        ``foot_velocity`` and ``foot_acceleration``, ``swing`` (in the air between lift-off
        and touchdown), ``swing_progress`` (fraction of the swing done, 0 outside one),
        ``unload`` (within ``unload_lead`` before a lift-off); ``double_support`` (PlaCo's),
        ``started``, ``done``, ``steps_planned`` (footsteps, initial feet included),
        ``swings`` (swing phases planned), ``support_center``.

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
        if self.trajectory is None:
            raise BehaviorFileError("placo_walk planner: outputs() before start()")
        if self._last is None or self._last[0] != t:
            self._last = (t, {})
        values = self._last[1]
        try:
            return values[name]
        except KeyError:
            pass
        group = _OUTPUT_GROUP[name]  # KeyError: not an output
        traj = self.trajectory
        tau = min(max(float(t) - self.t_start, 0.0), traj.t_end - 1e-6)
        if group == "com":
            values["com"] = np.array(traj.get_p_world_CoM(tau))
            values["com_velocity"] = np.array(traj.get_v_world_CoM(tau))
            values["com_acceleration"] = np.array(traj.get_a_world_CoM(tau))
        elif group == "zmp":
            values["zmp"] = np.array(traj.get_p_world_ZMP(tau, self.omega))
        elif group == "trunk":
            values["trunk_rotation"] = np.array(traj.get_R_world_trunk(tau))
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
            values["double_support"] = bool(traj.support_is_both(tau))
            values["started"] = float(t) >= self.t_start
            values["done"] = float(t) - self.t_start >= traj.t_end
            values["steps_planned"] = len(self.footsteps)
            values["swings"] = len(self.swings)
        return values[name]
