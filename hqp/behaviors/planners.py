"""Trajectory generators feeding a behavior's ``plan.*`` names.

:class:`PlacoWalkPlanner` wraps PlaCo's walking planners (PlaCo 0.10.2):
``placo.FootstepsPlannerNaive`` places footsteps towards a target,
``FootstepsPlanner.make_supports`` turns them into single and double
supports, and ``placo.WalkPatternGenerator`` (a LIPM / ZMP preview planner,
``placo.LIPM``'s natural frequency ``omega = sqrt(g / h)``) plans the centre
of mass, the ZMP and the swing-foot trajectories. hqp does not write another
ZMP preview controller; it tracks these trajectories with its own tasks.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hqp.errors import BehaviorFileError
from hqp.model import RobotModel

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
}
"""Parameters of the ``placo_walk`` planner: ``distance`` to walk forward [m], maximum
``step_length`` between consecutive footsteps [m] (each foot moves twice this per
step), support durations [s] and ratios, swing ``foot_height`` [m], ZMP margin in
the sole [m], CoM height offset from the initial one [m], and ``start_delay``: time
after the behavior starts at which the plan begins [s]."""


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
        self.trajectory: Any = None
        self.footsteps: list[np.ndarray] = []
        self.t_start = 0.0
        self.omega = 0.0
        self._last: tuple[float, dict[str, Any]] | None = None

    def start(self, model: RobotModel, t: float) -> None:
        """Plan from the current feet and centre of mass (``model`` updated), from time ``t``."""
        import placo

        p = self.params
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
        wpg = placo.WalkPatternGenerator(robot, hp)
        self.trajectory = wpg.plan(supports, com, 0.0)
        self.footsteps = [np.array(f.frame) for f in footsteps]
        self.omega = float(placo.LIPM.compute_omega(hp.walk_com_height))
        self.t_start = float(t) + float(p["start_delay"])
        self._sides = (placo.HumanoidRobot_Side.left, placo.HumanoidRobot_Side.right)
        self._com_height = hp.walk_com_height

    @property
    def duration(self) -> float:
        """Duration of the plan [s]."""
        return float(self.trajectory.t_end) if self.trajectory is not None else 0.0

    def outputs(self, t: float) -> dict[str, Any]:
        """Return the ``plan.*`` values at behavior time ``t`` [s] (clamped to the plan)."""
        if self.trajectory is None:
            raise BehaviorFileError("placo_walk planner: outputs() before start()")
        if self._last is not None and self._last[0] == t:
            return self._last[1]
        traj = self.trajectory
        tau = min(max(float(t) - self.t_start, 0.0), traj.t_end - 1e-6)
        both = bool(traj.support_is_both(tau))
        side = None if both else traj.support_side(tau)
        left, right = self._sides
        T_l = np.array(traj.get_T_world_left(tau))
        T_r = np.array(traj.get_T_world_right(tau))
        # swing-foot velocity and acceleration by central differences of the planned frames
        h = 2e-3
        lo, hi = max(tau - h, 0.0), min(tau + h, traj.t_end - 1e-6)
        p_l = [np.array(traj.get_T_world_left(x))[:3, 3] for x in (lo, tau, hi)]
        p_r = [np.array(traj.get_T_world_right(x))[:3, 3] for x in (lo, tau, hi)]
        v_l = (p_l[2] - p_l[0]) / (hi - lo)
        v_r = (p_r[2] - p_r[0]) / (hi - lo)
        a_l = (p_l[2] - 2 * p_l[1] + p_l[0]) / h**2 if hi - lo > 1.9 * h else 0 * v_l
        a_r = (p_r[2] - 2 * p_r[1] + p_r[0]) / h**2 if hi - lo > 1.9 * h else 0 * v_r
        com = np.array(traj.get_p_world_CoM(tau))
        out = {
            "com": com,
            "com_velocity": np.array(traj.get_v_world_CoM(tau)),
            "com_acceleration": np.array(traj.get_a_world_CoM(tau)),
            "zmp": np.array(traj.get_p_world_ZMP(tau, self.omega)),
            "left_foot": T_l[:3, 3].copy(),
            "right_foot": T_r[:3, 3].copy(),
            "left_foot_velocity": v_l,
            "right_foot_velocity": v_r,
            "left_foot_acceleration": a_l,
            "right_foot_acceleration": a_r,
            "trunk_rotation": np.array(traj.get_R_world_trunk(tau)),
            "left_swing": side == right,
            "right_swing": side == left,
            "double_support": both,
            "started": float(t) >= self.t_start,
            "done": float(t) - self.t_start >= traj.t_end,
            "steps_planned": len(self.footsteps),
            "support_center": 0.5 * (T_l[:3, 3] + T_r[:3, 3]),
        }
        self._last = (t, out)
        return out
