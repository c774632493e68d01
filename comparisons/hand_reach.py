"""``hand-reach``: hand position control under joint-limit constraints (seed 003, section 5).

The experiment of the hierarchy paper's Figures 3-5 on ``paper-humanoid``
(24 DoF, 1.65 m, 71 kg), standing on both feet. The right hand is commanded
to a fixed target low in front of and beside the robot, out of reach because
of joint limits (the paper: hip, knee-flexion and right-elbow limits; here the
hip-flexion and right-elbow limits, not the knee's: see below). Tasks (eq. 24-26),
each with the PD law with velocity saturation of eq. 27-28:

- joint limits (``V_JLC``): HQP: the viable position/velocity bounds at the
  joint-limit sub-level; null-space law: the papers' activation zones at the
  top task level;
- centre of gravity (``V_COG``): horizontal position over the centre of the
  feet (eq. 24);
- right-hand position (``V_HAND``);
- symmetry posture (``V_SYM = ||W (q - q_mid)||^2``, eq. 26).

Hierarchies:

- ``shared`` (eq. 29-30): joint limits; {centre of gravity, hand} in one
  level; posture;
- ``cog-first`` (eq. 31): joint limits; centre of gravity; hand; posture.

Duration: 2 s (the paper's plots run 3 s). Measured with
``hqp compare hand-reach --controllers hqp --json`` (scenario metrics
``<joint>_flexion_gap_rad``, ``<joint>_flexion_limit_s``, ``hand_speed_final_mps``
of :func:`limit_metrics`): in ``cog-first`` the right elbow reaches its
flexion limit (-1.30 rad) at 1.52 s and the right hip its flexion limit
(-2.09 rad) at 1.80 s; in ``shared`` neither by 2 s (0.08 and 0.13 rad short;
the hip gets there at 2.3 s). The hand is still closing in at 2 s (0.18 m/s).
The knee-flexion limit is not reached (the right knee bends from -0.30 to
-0.63 rad; limit -1.50 rad), and no target makes it:

- This robot reaches low with its trunk: hip flexion to 2.09 rad plus torso
  pitch to 1.40 rad take the hand below the floor with the knees at about
  -1.0 rad. A static reach optimisation (both feet fixed, centre of gravity
  over the feet, joint limits; for a few targets also torque limits with
  optimal contact wrenches) over about 280 targets and 150 reach directions
  never puts the right knee below -1.14 rad: once the hip flexion (-2.09)
  and the ankle dorsiflexion (-0.35) are at their limits, more knee flexion
  turns the thigh, hence the trunk, upright and raises the shoulder, so the hand moves away.
  The deepest balanced squat (knee at -1.5, hip at -2.09, both ankles at
  -0.35, base 0.64 m) exists, but with the knee held there the hand gets
  3-5 cm less close to any target tried than with the knee free.
- In MuJoCo the legs follow the same path: with the hand target
  ``(0.9, -0.5, 0.2)`` and a slow symmetry posture (``posture_gains`` (1, 2)) the
  hand comes to rest 24.5 cm short at 2.5 s in ``cog-first`` (cog max 0.95 mm)
  with the knees at -1.0/-1.1 rad and the right ankle at its dorsiflexion limit
  (the leg limit that stops the squat), but joints pass their limits by up to
  3 mm (``shared``: 13 mm), so it is not the default.

Beyond about 2 s the HQP runs with the default posture gains are erratic: the
symmetry posture (eq. 26, ``kp`` 25, ``kv`` 10) swings the arms towards their
mid-range at the joint velocity bounds, the torso-pitch motor (78 N m) is
saturated from about 1 s holding the bent trunk, and once the right elbow is
straight and the target out of reach the hand level's near-singular least
squares drives the shoulder at its velocity bounds: the torso yaw hits its
limit and the hand swings away (at 3 s the centre of gravity is 27 mm off in
``cog-first`` and the hand 0.9 m from its target, no fall, joints at most
0.02 rad past their limits; ``hqp compare hand-reach --controllers hqp
--duration 3``). The paper's law-based simulation had no torque limits.

Joint limits of the HQP stack use :data:`comparisons.common.JOINT_LIMIT_MARGIN`
and :data:`comparisons.common.JOINT_VELOCITY_SCALE` (see there).

PlaCo (``placo``) has hard and soft tasks only: ``cog-first`` maps to a hard
centre-of-gravity task and soft hand and posture tasks; ``shared`` to soft
centre-of-gravity and hand tasks of equal weight. In both, the posture is a
soft task with a small weight beside the hand (not strictly below it), which
is where PlaCo's priorities cannot express the paper's hierarchy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from comparisons.base import Progress, RunResult, RunSpec, Scenario
from comparisons.common import Hierarchy, run_controller, standing_setup
from comparisons.metrics import Trace
from comparisons.record import trace_from_log
from hqp.plots import Line, Panel


@dataclass(frozen=True)
class HandReachParameters:
    """Target and gains of the experiment (tuned once, the same for every controller).

    Attributes:
        target_offset: Hand target relative to the centre of the feet ``(3,)``
            (x forward, y left, z up from the floor) [m].
        hand_gains: ``(kp [1/s^2], kv [1/s], max_velocity [m/s])`` of the hand.
        hand_max_acceleration: Saturation of the hand's feedback acceleration
            [m/s^2] (seed 001's example hand task: 3 m/s^2).
        cog_gains: ``(kp, kv, max_velocity)`` of the centre of gravity.
        posture_gains: ``(kp, kv)`` of the symmetry posture.
        shared_weights: ``(cog, hand)`` weights in the ``shared`` level.
        zone: Activation-zone width of the null-space law's joint limits [rad].
        torque_scale: Factor on the robot's torque limits (controller model and motors; the
            seed's law-based simulation had no torque limits:
            :mod:`comparisons.law_conditions`).

    """

    target_offset: tuple[float, float, float] = (0.85, -0.30, 0.10)
    hand_gains: tuple[float, float, float] = (100.0, 20.0, 0.5)
    hand_max_acceleration: float = 3.0
    cog_gains: tuple[float, float, float] = (100.0, 20.0, 0.5)
    posture_gains: tuple[float, float] = (25.0, 10.0)
    shared_weights: tuple[float, float] = (1.0, 1.0)
    zone: float = 0.1
    torque_scale: float = 1.0


PLOTTED_JOINTS = ("right_elbow", "right_knee", "right_hip_pitch", "right_ankle_pitch")
"""Joints drawn against their limits (the paper's Figures 4c-d, plus the hip and the ankle)."""

LIMIT_TOLERANCE = 0.02
"""A joint has reached a position limit when it comes within this distance of it [rad]."""

HAND_REST_WINDOW = 0.1
"""Window at the end of a run over which the hand's mean speed is measured [s]."""


def limit_metrics(trace: Trace) -> dict[str, float | None]:
    """Closest approach of each plotted joint to its flexion limit, when reached, hand speed.

    The paper's limits are flexion limits (hip, elbow, knee flexion); on
    ``paper-humanoid`` flexion is the negative direction of every plotted joint
    (elbow, knee, hip pitch; ankle pitch: dorsiflexion), so its flexion limit is
    its lower limit. Scenario metrics added to the contract's row (extra fields
    are allowed there):

    - ``<joint>_flexion_gap_rad``: ``min_t (q - q_lower)`` over the run
      (negative: past the limit) [rad];
    - ``<joint>_flexion_limit_s``: first time the joint came within
      :data:`LIMIT_TOLERANCE` of that limit (``None``: never) [s];
    - ``hand_speed_final_mps``: mean speed of the hand over the last
      :data:`HAND_REST_WINDOW` [m/s] (``None`` without a hand).

    """
    out: dict[str, float | None] = {}
    for joint in PLOTTED_JOINTS:
        if joint not in trace.joint_names:
            continue
        i = trace.joint_names.index(joint)
        gap = trace.q[:, i] - trace.q_lower[i]
        near = np.flatnonzero(gap <= LIMIT_TOLERANCE)
        out[f"{joint}_flexion_gap_rad"] = float(gap.min())
        out[f"{joint}_flexion_limit_s"] = float(trace.t[near[0]]) if near.size else None
    out["hand_speed_final_mps"] = None
    if trace.hand is not None and trace.t.size > 1:
        last = trace.t >= trace.t[-1] - HAND_REST_WINDOW
        last[-2:] = True
        idx = np.flatnonzero(last)
        span = trace.t[idx[-1]] - trace.t[idx[0]]
        path = np.linalg.norm(np.diff(trace.hand[idx], axis=0), axis=1).sum()
        out["hand_speed_final_mps"] = float(path / span) if span > 0.0 else 0.0
    return out


class HandReach(Scenario):
    """Seed 003, section 5: reach an unreachable target under joint limits."""

    name = "hand-reach"
    title = "right hand to an unreachable low target under joint limits (CoG, symmetry posture)"
    paper = "hierarchy paper (seed 003), section 5, Figures 3-5, eq. 24-31"
    robots = ("paper-humanoid",)
    hierarchies = ("shared", "cog-first")
    duration = 2.0

    def __init__(self, parameters: HandReachParameters | None = None) -> None:
        self.parameters = parameters or HandReachParameters()

    # -- tasks ------------------------------------------------------------------------------

    def build(self, robot_name: str, spec: RunSpec) -> tuple[object, object, Hierarchy, dict]:
        """Robot, controller model, hierarchy and goals of one run."""
        from hqp.tasks.com import CoMTask
        from hqp.tasks.position import PositionTask
        from hqp.tasks.posture import PostureTask

        p = self.parameters
        robot, model, feet = standing_setup(robot_name)
        goal_cog = feet[:2].copy()
        target = np.array([feet[0], feet[1], 0.0]) + np.array(p.target_offset)
        w_cog, w_hand = p.shared_weights if spec.hierarchy == "shared" else (1.0, 1.0)
        cog = CoMTask(model, horizontal=True, name="cog", weight=w_cog, kp=p.cog_gains[0],
                      kv=p.cog_gains[1], max_velocity=p.cog_gains[2])
        cog.set_goal(goal_cog)
        hand = PositionTask(model, robot.hands[1], name="hand", weight=w_hand,
                            kp=p.hand_gains[0], kv=p.hand_gains[1], max_velocity=p.hand_gains[2],
                            max_acceleration=p.hand_max_acceleration)
        hand.set_goal(target)
        sym = PostureTask.symmetry(model, name="symmetry", kp=p.posture_gains[0],
                                   kv=p.posture_gains[1])
        if spec.hierarchy == "shared":
            levels = [("cog+hand", [cog, hand]), ("posture", [sym])]
        else:
            levels = [("cog", [cog]), ("hand", [hand]), ("posture", [sym])]
        goals = {"cog": goal_cog, "hand": target, "feet": feet}
        return robot, model, Hierarchy(levels), goals

    # -- run --------------------------------------------------------------------------------

    def simulate(self, robot: str, spec: RunSpec, duration: float, progress: Progress) -> RunResult:
        """Run one controller on one hierarchy in MuJoCo."""
        rob, model, hierarchy, goals = self.build(robot, spec)
        log, note, support, own = run_controller(spec.controller, rob, model, hierarchy, duration,
                                                 progress, zone=self.parameters.zone,
                                                 contacts=self.contacts,
                                                 torque_scale=self.parameters.torque_scale)
        trace = trace_from_log(rob, log, goals["cog"], hand_frame=rob.hands[1],
                               hand_goal=goals["hand"], support=support,
                               tau_max=model.tau_max)
        return RunResult(spec, {**limit_metrics(trace), **own}, trace, self.panels(trace), note)

    # -- figure -----------------------------------------------------------------------------

    @staticmethod
    def panels(trace: Trace) -> list[Panel]:
        """Panels like the paper's Figures 4-5: CoG error, hand height, elbow, knee (+ hip)."""
        t = trace.t
        err = 1e3 * trace.cog_error  # [mm], as in the tables
        out = [
            Panel("Balancing Error", "error [mm]", t,
                  (Line("X Direction", err[:, 0]), Line("Y Direction", err[:, 1]))),
        ]
        if trace.hand is not None and trace.hand_goal is not None:
            out.append(Panel("Right Hand Vertical Position", "Z [m]", t,
                             (Line("Hand Goal", trace.hand_goal[:, 2], "dashed"),
                              Line("Hand Position", trace.hand[:, 2]))))
        labels = {"right_elbow": ("Right Elbow Angle", "Elbow"),
                  "right_knee": ("Right Knee Flexion", "Knee Flexion"),
                  "right_hip_pitch": ("Right Hip Flexion", "Hip Flexion"),
                  "right_ankle_pitch": ("Right Ankle Pitch (dorsiflexion < 0)", "Ankle Pitch")}
        for joint in PLOTTED_JOINTS:
            if joint not in trace.joint_names:
                continue
            i = trace.joint_names.index(joint)
            q = trace.q[:, i]
            lo, hi = trace.q_lower[i], trace.q_upper[i]
            title, short = labels[joint]
            out.append(Panel(title, "angle [rad]", t,
                             (Line(f"{short} Limits", np.full_like(q, lo), "dashed"),
                              Line(f"{short} Angle", q),
                              Line(f"{short} Limits", np.full_like(q, hi), "dashed"))))
        if trace.hand is not None and trace.hand_goal is not None:
            d = 1e2 * np.linalg.norm(trace.hand - trace.hand_goal, axis=1)
            out.append(Panel("Right Hand Distance to Target", "distance [cm]", t,
                             (Line("distance", d),)))
        return out
