"""Turn a simulator log (:class:`hqp.sim.run.Log`) into a scenario :class:`Trace`.

Centre of gravity and hand positions are recomputed from the logged true
states with the controller's model (pinocchio), so every controller is
measured the same way; contacts with the floor, the pelvis height, torque
clipping and step times come from the log (read from MuJoCo there).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from comparisons.metrics import Trace
from hqp.robots import Robot


def positions(robot: Robot, q: np.ndarray, frames: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    """Centre of gravity ``(N, 3)`` and world positions ``(N, 3)`` of ``frames`` along ``q``.

    Args:
        robot: The robot (its controller model is built here).
        q: Configurations ``(N, nq)`` (pinocchio convention).
        frames: Frame names.

    Returns:
        ``(com, frame_0, frame_1, ...)``.

    """
    model = robot.model()
    pm, data = model.model, model.model.createData()
    ids = [model.frame_id(f) for f in frames]
    com = np.zeros((q.shape[0], 3))
    out = [np.zeros((q.shape[0], 3)) for _ in frames]
    for k, qk in enumerate(q):
        com[k] = pin.centerOfMass(pm, data, qk)  # also runs forward kinematics
        for j, fid in enumerate(ids):
            out[j][k] = pin.updateFramePlacement(pm, data, fid).translation
    return (com, *out)


def trace_from_log(
    robot: Robot,
    log: Any,
    cog_goal: np.ndarray,
    *,
    hand_frame: str | None = None,
    hand_goal: np.ndarray | None = None,
    extra: Mapping[str, np.ndarray] | None = None,
    support: Any = None,
    tau_max: np.ndarray | None = None,
) -> Trace:
    """Build the trace of a run.

    Args:
        robot: The robot.
        log: The simulator's log (``t``, ``q``, ``base_height``, ``other_contact``,
            ``clipped``, ``step_time``, ``standing_height``).
        cog_goal: Horizontal goal of the centre of gravity ``(2,)`` or ``(N, 2)`` [m].
        hand_frame: Frame of the tracked hand (``None``: no hand task).
        hand_goal: Its target ``(3,)`` or ``(N, 3)`` [m].
        extra: Further series for plots.
        support: The run's :class:`comparisons.common.Support` (``None``: not recorded).
        tau_max: The motors' torque limits ``(na,)`` [N m] (``None``: the robot model's).

    """
    model = robot.model()
    q = np.asarray(log.q)
    n = q.shape[0]
    frames = (hand_frame,) if hand_frame else ()
    com, *frame_pos = positions(robot, q, frames)
    goal = np.broadcast_to(np.asarray(cog_goal, dtype=float), (n, 2)).copy()
    hand = frame_pos[0] if hand_frame else None
    hgoal = (
        np.broadcast_to(np.asarray(hand_goal, dtype=float), (n, 3)).copy()
        if hand_frame and hand_goal is not None
        else None
    )
    return Trace(
        t=np.asarray(log.t),
        q=q[:, model.actuated_q],
        q_lower=model.q_lower,
        q_upper=model.q_upper,
        joint_names=tuple(model.joint_names),
        com=com,
        com_goal=goal,
        pelvis_z=np.asarray(log.base_height),
        standing_height=float(log.standing_height or robot.standing_height),
        hand=hand,
        hand_goal=hgoal,
        non_foot_floor_contact=np.asarray(log.other_contact, dtype=bool),
        torque_clipped=np.asarray(log.clipped, dtype=float),
        step_ms=1e3 * np.asarray(log.step_time),
        safe_mode=np.asarray(log.safe_mode, dtype=bool),
        fell_at=getattr(log, "fell_at", None),
        realtime_factor=log.realtime_factor if log.wall_time > 0.0 else None,
        foot_wrench=None if support is None else support.foot_wrench[:n],
        sole_cop=None if support is None else support.sole_cop[:n],
        sole_half=None if support is None else support.sole_half,
        commanded_margin=(None if support is None or support.commanded_margin is None
                          else support.commanded_margin[:n]),
        tau=None if getattr(log, "tau", None) is None else np.asarray(log.tau),
        tau_max=model.tau_max if tau_max is None else np.asarray(tau_max, dtype=float),
        extra=dict(extra or {}),
    )
