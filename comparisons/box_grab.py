"""``box-grab``: both hands to the sides of a box, balance and an upright torso (seed 003 Figure 1).

"In this sequence, we control the robot's hands to grab a box while
maintaining body self-balance (based on the control of the global center of
gravity) and control of the torso's upright posture." On ``paper-humanoid``
standing on both feet, the hands move from their rest positions to the two
sides of a box in front of the robot, low enough that the robot has to bend
(goals reached along minimum-jerk paths of ``REACH_TIME``; PD with velocity
saturation). Tasks: joint limits (constraint sub-level), centre of gravity
over the centre of the feet, both hand positions, trunk orientation upright
(the seed's posture "kept vertical"), symmetry posture (eq. 26).

Hierarchies:

- ``cog-first``: centre of gravity; hands; upright trunk; symmetry posture;
- ``shared``: {centre of gravity, hands} in one level; upright trunk; posture.

Extra metrics: ``left_hand_final_distance_cm``, ``trunk_tilt_max_deg``
(angle of the trunk's vertical axis from the world vertical).
"""

from __future__ import annotations

import numpy as np

from comparisons.base import Progress, RunResult, RunSpec, Scenario
from comparisons.common import Hierarchy, run_controller, standing_setup
from comparisons.metrics import Trace
from comparisons.record import positions, trace_from_log
from hqp.plots import Line, Panel

BOX_CENTER = (0.38, 0.0, 0.62)
"""Box centre relative to the centre of the feet on the floor [m]."""
BOX_HALF_WIDTH = 0.17
"""Half width of the box along y: the hand goals are its two sides [m]."""
REACH_TIME = 1.5
"""Duration of the hands' minimum-jerk paths to the box [s]."""


def tilt_deg(robot: object, q: np.ndarray, frame: str) -> np.ndarray:
    """Angle between a frame's z axis and the world vertical along ``q`` ``(N,)`` [deg]."""
    import pinocchio as pin

    model = robot.model()
    pm, data = model.model, model.model.createData()
    fid = model.frame_id(frame)
    out = np.zeros(q.shape[0])
    for k, qk in enumerate(q):
        pin.forwardKinematics(pm, data, qk)
        z = pin.updateFramePlacement(pm, data, fid).rotation[:, 2]
        out[k] = np.degrees(np.arccos(np.clip(z[2], -1.0, 1.0)))
    return out


class BoxGrab(Scenario):
    """Seed 003, Figure 1: hands to a box, centre of gravity over the feet, torso upright."""

    name = "box-grab"
    title = "both hands to the sides of a box; centre of gravity over the feet; upright torso"
    paper = "hierarchy paper (seed 003), Figure 1"
    robots = ("paper-humanoid",)
    hierarchies = ("cog-first", "shared")
    duration = 3.0

    def build(self, robot_name: str, spec: RunSpec) -> tuple[object, object, Hierarchy, dict]:
        """Robot, controller model, hierarchy and goals of one run."""
        from hqp.tasks.com import CoMTask
        from hqp.tasks.orientation import OrientationTask
        from hqp.tasks.position import PositionTask
        from hqp.tasks.posture import PostureTask
        from hqp.tasks.reference import MinimumJerk

        robot, model, feet = standing_setup(robot_name)
        center = np.array([feet[0], feet[1], 0.0]) + np.array(BOX_CENTER)
        cog = CoMTask(model, horizontal=True, name="cog", kp=100.0, kv=20.0, max_velocity=0.5)
        cog.set_goal(feet[:2])
        hands = []
        goals = {}
        for frame, side in zip(robot.hands, (1.0, -1.0)):
            task = PositionTask(model, frame, name=frame, kp=100.0, kv=20.0, max_velocity=0.5)
            goal = center + np.array([0.0, side * BOX_HALF_WIDTH, 0.0])
            start = model.frame_placement(frame).translation.copy()
            task.set_trajectory(MinimumJerk(start, goal, REACH_TIME, 0.0))
            hands.append(task)
            goals[frame] = goal
        upright = OrientationTask(model, "trunk", name="upright", kp=100.0, kv=20.0)
        upright.set_goal(np.eye(3))
        sym = PostureTask.symmetry(model, name="symmetry", kp=25.0, kv=10.0)
        if spec.hierarchy == "shared":
            levels = [("cog+hands", [cog, *hands]), ("upright", [upright]), ("posture", [sym])]
        else:
            levels = [("cog", [cog]), ("hands", hands), ("upright", [upright]),
                      ("posture", [sym])]
        return robot, model, Hierarchy(levels), {"cog": feet[:2].copy(), **goals}

    def simulate(self, robot: str, spec: RunSpec, duration: float, progress: Progress) -> RunResult:
        """Run one controller on one hierarchy in MuJoCo."""
        rob, model, hierarchy, goals = self.build(robot, spec)
        log, note, support, own = run_controller(spec.controller, rob, model, hierarchy, duration,
                                                 progress, contacts=self.contacts)
        right, left = rob.hands[1], rob.hands[0]
        q = np.asarray(log.q)
        _, left_pos = positions(rob, q, (left,))
        tilt = tilt_deg(rob, q, "trunk")
        trace = trace_from_log(rob, log, goals["cog"], hand_frame=right, hand_goal=goals[right],
                               extra={"left_hand": left_pos, "trunk_tilt_deg": tilt},
                               support=support)
        metrics = {
            "left_hand_final_distance_cm": 1e2 * float(np.linalg.norm(left_pos[-1] - goals[left])),
            "trunk_tilt_max_deg": float(tilt.max()),
        }
        left_goal = np.broadcast_to(goals[left], left_pos.shape)
        return RunResult(spec, {**metrics, **own}, trace,
                         self.panels(trace, left_pos, left_goal), note)

    @staticmethod
    def panels(trace: Trace, left: np.ndarray, left_goal: np.ndarray) -> list[Panel]:
        """CoG error, hand distances to the box sides, trunk tilt, right hand height."""
        t = trace.t
        err = 1e3 * trace.cog_error  # [mm], as in the tables
        assert_hand = trace.hand is not None and trace.hand_goal is not None
        hand = trace.hand if assert_hand else np.zeros((t.size, 3))
        goal = trace.hand_goal if assert_hand else np.zeros((t.size, 3))
        d_right = 1e2 * np.linalg.norm(hand - goal, axis=1)
        d_left = 1e2 * np.linalg.norm(left - left_goal, axis=1)
        return [
            Panel("Balancing Error", "error [mm]", t,
                  (Line("X Direction", err[:, 0]), Line("Y Direction", err[:, 1]))),
            Panel("Hands to the Box", "distance [cm]", t,
                  (Line("right hand", d_right), Line("left hand", d_left))),
            Panel("Trunk Upright", "tilt [deg]", t,
                  (Line("trunk tilt", trace.extra["trunk_tilt_deg"]),)),
            Panel("Right Hand Vertical Position", "Z [m]", t,
                  (Line("Hand Goal", goal[:, 2], "dashed"),
                   Line("Hand Position", hand[:, 2]))),
        ]
