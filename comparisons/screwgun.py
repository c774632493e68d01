"""``screwgun``: the teleoperated screwgun behavior of the architecture paper (seed 001, Table 1).

Task decomposition of seed 001, Table 1 / Figure 7, on ``paper-humanoid``
standing on both feet:

- balance: centre of gravity horizontal position (2 rows) over the feet, and
  the internal forces between the feet driven to zero (the seed's "internal
  forces between legs are controlled to vanish");
- right hand: position and orientation (6 rows) tracking a teleoperated
  point that moves along a beam in front of the robot (minimum-jerk segments
  through :data:`WAYPOINTS`), the tool (screw) axis pointing forward;
- head gaze (2 coordinates) at the teleoperated point;
- whole-body posture switching between two captured poses (a standing pose,
  then a crouched working pose at :data:`SWITCH_TIME`).

Hierarchy ``cog-first``: balance; hand and gaze (operational); posture.

Not reproduced: the *hybrid* part of the hand task (a pushing force along
the screw axis) needs a beam the hand presses on; the MuJoCo scene holds the
robot and the floor only, so the hand task here is the 6-D pose task. The
null-space law cannot use the internal-force rows (they act on contact
forces); PlaCo has no internal-force or gaze task mapped.

Extra metrics: ``hand_tracking_error_max_cm`` and
``hand_tracking_error_final_cm`` (distance of the hand to the moving point
after the approach, :data:`APPROACH_TIME`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from comparisons.base import Progress, RunResult, RunSpec, Scenario
from comparisons.common import Hierarchy, run_controller, standing_setup
from comparisons.metrics import Trace, final_window
from comparisons.record import trace_from_log
from hqp.plots import Line, Panel
from hqp.tasks.reference import MinimumJerk, MinimumJerkRotation, TrajectorySample

APPROACH_TIME = 1.5
"""The hand reaches the beam's first point at this time [s]."""
WAYPOINTS: tuple[tuple[float, tuple[float, float, float]], ...] = (
    (1.5, (0.42, -0.20, 1.00)),
    (3.0, (0.42, 0.00, 1.10)),
    (4.5, (0.42, -0.25, 0.95)),
)
"""``(time [s], teleoperated point relative to the centre of the feet on the floor [m])``."""
SWITCH_TIME = 2.25
"""Time at which the posture switches to the second captured pose [s]."""
WORK_POSE = {
    "left_hip_pitch": -0.45, "right_hip_pitch": -0.45, "left_knee": -0.80,
    "right_knee": -0.80, "left_ankle_pitch": 0.35, "right_ankle_pitch": 0.35,
    "torso_pitch": 0.15,
}
"""Joints of the second captured pose that differ from standing [rad]."""


class Waypoints:
    """A goal through waypoints: minimum-jerk segments from a start position (a ``Trajectory``)."""

    def __init__(self, start: np.ndarray, points: list[tuple[float, np.ndarray]]) -> None:
        self.segments: list[MinimumJerk] = []
        t0, x0 = 0.0, np.asarray(start, dtype=float)
        for t1, x1 in points:
            self.segments.append(MinimumJerk(x0, np.asarray(x1, dtype=float), t1 - t0, t0))
            t0, x0 = t1, np.asarray(x1, dtype=float)

    def sample(self, t: float) -> TrajectorySample:
        """Goal, velocity and acceleration at time ``t`` [s]."""
        for seg in self.segments:
            if t <= seg.t0 + seg.duration:
                return seg.sample(t)
        return self.segments[-1].sample(t)


class PostureSwitch:
    """Wrap a controller: switch the posture task's goal to the work pose at ``SWITCH_TIME``."""

    def __init__(self, controller: Any, posture: Any, pose: np.ndarray) -> None:
        self.controller = controller
        self.posture = posture
        self.pose = pose
        self.switched = False
        self.dt = controller.dt
        self.stack = controller.stack

    def step(self, state: Any, t: float) -> Any:
        """Switch the posture goal once, then run the controller's step."""
        if not self.switched and t >= SWITCH_TIME:
            self.posture.set_goal(self.pose)
            self.switched = True
        return self.controller.step(state, t)


class Screwgun(Scenario):
    """Seed 001, Table 1: hand pose and gaze on a teleoperated point, posture switching."""

    name = "screwgun"
    title = "teleoperated hand pose and gaze, internal forces, posture switching (seed 001)"
    paper = "architecture paper (seed 001), Table 1 and Figure 7"
    robots = ("paper-humanoid",)
    hierarchies = ("cog-first",)
    duration = 4.5

    def simulate(self, robot: str, spec: RunSpec, duration: float, progress: Progress) -> RunResult:
        """Run one controller in MuJoCo while the teleoperated point moves."""
        from hqp.tasks.com import CoMTask
        from hqp.tasks.gaze import GazeTask
        from hqp.tasks.internal_forces import InternalForcesTask
        from hqp.tasks.orientation import OrientationTask
        from hqp.tasks.position import PositionTask
        from hqp.tasks.posture import PostureTask

        rob, model, feet = standing_setup(robot)
        origin = np.array([feet[0], feet[1], 0.0])
        hand_frame = rob.hands[1]
        start = model.frame_placement(hand_frame).translation.copy()
        path = Waypoints(start, [(t, origin + np.array(p)) for t, p in WAYPOINTS])
        cog = CoMTask(model, horizontal=True, name="cog", kp=100.0, kv=20.0, max_velocity=0.5)
        cog.set_goal(feet[:2])
        internal = InternalForcesTask(model, list(rob.feet), name="internal_forces")
        hand = PositionTask(model, hand_frame, name="hand", kp=100.0, kv=20.0)
        hand.set_trajectory(path)
        tool = OrientationTask(model, hand_frame, name="tool_axis", kp=100.0, kv=20.0)
        R0 = model.frame_placement(hand_frame).rotation.copy()
        tool.set_trajectory(MinimumJerkRotation(R0, pin.utils.rpyToMatrix(0.0, -np.pi / 2, 0.0),
                                                APPROACH_TIME, 0.0))
        head = rob.head_frame or "head"
        gaze = GazeTask(model, head, name="gaze", kp=100.0, kv=20.0)
        gaze.set_trajectory(path)
        posture = PostureTask(model, name="posture", kp=25.0, kv=10.0)
        posture.set_configuration(rob.q_standing, model)
        work = np.array(rob.q_standing[model.actuated_q])
        for joint, value in WORK_POSE.items():
            work[model.joint_index(joint)] = value
        balance = [cog] if spec.controller == "placo" else [cog, internal]
        operational = [hand, tool] if spec.controller == "placo" else [hand, tool, gaze]
        hierarchy = Hierarchy([("balance", balance), ("operational", operational),
                               ("posture", [posture])])

        def wrap(controller: Any) -> Any:
            return PostureSwitch(controller, posture, work)

        log, note = run_controller(spec.controller, rob, model, hierarchy, duration, progress,
                                   wrap=wrap)
        if spec.controller == "nullspace":
            note = "the null-space law skips the internal-force rows (they act on contact forces)"
        if spec.controller == "placo":
            note += "; no internal-force or gaze task mapped to PlaCo"
        t = np.asarray(log.t)
        goal = np.array([path.sample(float(tk)).position for tk in t])
        trace = trace_from_log(rob, log, feet[:2], hand_frame=hand_frame, hand_goal=goal)
        metrics = self.metrics(trace)
        return RunResult(spec, metrics, trace, self.panels(trace), note)

    @staticmethod
    def metrics(trace: Trace) -> dict[str, float]:
        """Hand tracking errors after the approach."""
        if trace.hand is None or trace.hand_goal is None:
            return {}
        err = np.linalg.norm(trace.hand - trace.hand_goal, axis=1)
        after = trace.t >= APPROACH_TIME
        if not after.any():
            after[-1] = True
        return {
            "hand_tracking_error_max_cm": 1e2 * float(err[after].max()),
            "hand_tracking_error_final_cm": 1e2 * float(err[final_window(trace.t)].mean()),
        }

    @staticmethod
    def panels(trace: Trace) -> list[Panel]:
        """CoG error, hand tracking error, hand height against the point, a knee angle."""
        t = trace.t
        err = 1e2 * trace.cog_error
        hand = trace.hand if trace.hand is not None else np.zeros((t.size, 3))
        goal = trace.hand_goal if trace.hand_goal is not None else hand
        d = 1e2 * np.linalg.norm(hand - goal, axis=1)
        out = [
            Panel("Balancing Error", "error [cm]", t,
                  (Line("X Direction", err[:, 0]), Line("Y Direction", err[:, 1]))),
            Panel("Hand to Teleoperated Point", "distance [cm]", t, (Line("hand", d),)),
            Panel("Right Hand Vertical Position", "Z [m]", t,
                  (Line("Teleoperated Point", goal[:, 2], "dashed"),
                   Line("Hand Position", hand[:, 2]))),
        ]
        if "right_knee" in trace.joint_names:
            out.append(Panel("Right Knee (posture switch)", "angle [rad]", t,
                             (Line("right knee", trace.joint("right_knee")),)))
        return out
