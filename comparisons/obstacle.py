"""``obstacle``: avoid an obstacle moved towards the body, hand held still (seed 003 Figure 2).

"This sequence depicts a robot avoiding an obstacle that is moved
interactively towards several points near the robot's body. While the right
hand is commanded to stay at a fixed location, the center of gravity is
controlled for balance, and the additional posture is controlled to minimize
distance with respect to a symmetrical posture." On ``paper-humanoid``: a
sphere of radius :data:`RADIUS` moves along straight segments through
:data:`WAYPOINTS` (in front of the chest, beside the left arm, in front of
the pelvis). Obstacle avoidance (the robot's capsule proxies against the
sphere, ``d_safe = 0.1 m``) is the collision sub-level, under the physics,
contact/torque-limit and joint-limit sub-levels; then the centre of gravity,
the right hand (held at its start position) and the symmetry posture.

The obstacle is the controller's (virtual) obstacle, as in the paper's
interactive demonstration: it is not a MuJoCo body.

Extra metric: ``obstacle_distance_min_cm``, the smallest distance over the
run between the sphere and the robot's capsules (feet excluded: they are on
the floor) [cm]; ``d_safe`` is 10 cm.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from comparisons.base import Progress, RunResult, RunSpec, Scenario
from comparisons.common import Hierarchy, run_controller, standing_setup
from comparisons.metrics import Trace
from comparisons.record import trace_from_log
from hqp.plots import Line, Panel

D_SAFE = 0.1
"""Safety distance of the obstacle-avoidance rows [m]."""
RADIUS = 0.05
"""Radius of the spherical obstacle [m]."""
WAYPOINTS: tuple[tuple[float, tuple[float, float, float]], ...] = (
    (0.0, (0.80, 0.00, 1.10)),
    (1.0, (0.80, 0.00, 1.10)),
    (3.0, (0.33, 0.00, 1.10)),
    (5.0, (0.20, 0.38, 1.00)),
    (7.0, (0.33, 0.00, 0.80)),
)
"""``(time [s], position relative to the centre of the feet on the floor [m])``: the
obstacle moves at 0.12-0.24 m/s (a hand moving it interactively, as in the paper). Twice as
fast (0.47 m/s towards the chest) it enters the damper's influence zone faster than the
allowed approach speed ``xi`` (0.3 m/s): the collision level is in conflict from 1.15 s and,
as its priority says, HQP gives up the centre of gravity (12 cm) and the hand (88 cm); the
whole-body motion this causes then also outruns the joint-limit braking assumption (a joint
up to 0.27 rad past its limit: an open defect of the viability bound, see the README)."""


def obstacle_path(t: float, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position ``(3,)`` [m] and velocity ``(3,)`` [m/s] of the obstacle at time ``t`` [s]."""
    times = [w[0] for w in WAYPOINTS]
    points = [origin + np.array(w[1]) for w in WAYPOINTS]
    if t >= times[-1]:
        return points[-1], np.zeros(3)
    k = max(i for i, ti in enumerate(times) if ti <= t)
    t0, t1 = times[k], times[k + 1]
    velocity = (points[k + 1] - points[k]) / (t1 - t0)
    return points[k] + (t - t0) * velocity, velocity


class MovingObstacle:
    """Wrap a controller: place the obstacle of the world at its path position before each step."""

    def __init__(self, controller: Any, world: Any, name: str, origin: np.ndarray) -> None:
        self.controller = controller
        self.world = world
        self.name = name
        self.origin = origin
        self.dt = controller.dt
        self.stack = controller.stack

    def step(self, state: Any, t: float) -> Any:
        """Move the obstacle to its position at ``t``, then run the controller's step."""
        position, velocity = obstacle_path(t, self.origin)
        self.world.move(self.name, position, velocity)
        return self.controller.step(state, t)


def _segment_point_distance(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> float:
    """Distance from ``p`` to the segment ``[a, b]`` [m]."""
    u = b - a
    s = float(np.clip(np.dot(p - a, u) / max(np.dot(u, u), 1e-18), 0.0, 1.0))
    return float(np.linalg.norm(a + s * u - p))


def obstacle_distances(robot: Any, q: np.ndarray, t: np.ndarray, origin: np.ndarray,
                       capsules: list[Any]) -> np.ndarray:
    """Smallest capsule-to-sphere surface distance at each sample ``(N,)`` [m]."""
    model = robot.model()
    pm, data = model.model, model.model.createData()
    ids = [model.frame_id(c.frame) for c in capsules]
    out = np.zeros(q.shape[0])
    for k, qk in enumerate(q):
        pin.forwardKinematics(pm, data, qk)
        p, _ = obstacle_path(float(t[k]), origin)
        best = np.inf
        for c, fid in zip(capsules, ids):
            T = pin.updateFramePlacement(pm, data, fid)
            a = T.act(np.array(c.a, dtype=float))
            b = T.act(np.array(c.b, dtype=float))
            best = min(best, _segment_point_distance(a, b, p) - c.radius - RADIUS)
        out[k] = best
    return out


class Obstacle(Scenario):
    """Seed 003, Figure 2: obstacle avoidance in the collision sub-level."""

    name = "obstacle"
    title = "an obstacle moved towards the body while the right hand holds still"
    paper = "hierarchy paper (seed 003), Figure 2"
    robots = ("paper-humanoid",)
    hierarchies = ("cog-first",)
    duration = 8.0

    def simulate(self, robot: str, spec: RunSpec, duration: float, progress: Progress) -> RunResult:
        """Run one controller in MuJoCo while the obstacle moves."""
        from hqp.model.world import Sphere, World
        from hqp.tasks.collision import ObstacleAvoidance
        from hqp.tasks.com import CoMTask
        from hqp.tasks.position import PositionTask
        from hqp.tasks.posture import PostureTask

        rob, model, feet = standing_setup(robot)
        origin = np.array([feet[0], feet[1], 0.0])
        start, _ = obstacle_path(0.0, origin)
        world = World([Sphere("obstacle", start, RADIUS)])
        capsules = [c for c in rob.capsules if "foot" not in c.name]
        avoid = ObstacleAvoidance("avoid_obstacle", world, capsules, d_safe=D_SAFE,
                                  d_influence=D_SAFE + 0.15)
        cog = CoMTask(model, horizontal=True, name="cog", kp=100.0, kv=20.0, max_velocity=0.5)
        cog.set_goal(feet[:2])
        hand_goal = model.frame_placement(rob.hands[1]).translation.copy()
        hand = PositionTask(model, rob.hands[1], name="hand", kp=100.0, kv=20.0,
                            max_velocity=0.5)
        hand.set_goal(hand_goal)
        sym = PostureTask.symmetry(model, name="symmetry", kp=25.0, kv=10.0)
        hierarchy = Hierarchy([("cog", [cog]), ("hand", [hand]), ("posture", [sym])],
                              collision=[avoid])
        if spec.controller == "placo":
            hierarchy = Hierarchy(hierarchy.levels)  # PlaCo: no obstacle primitive mapped

        def wrap(controller: Any) -> Any:
            return MovingObstacle(controller, world, "obstacle", origin)

        log, note, support, own = run_controller(spec.controller, rob, model, hierarchy, duration,
                                                 progress, wrap=wrap, contacts=self.contacts)
        if spec.controller == "placo":
            note += "; the obstacle is not given to PlaCo (no capsule-to-sphere primitive mapped)"
        q, t = np.asarray(log.q), np.asarray(log.t)
        dist = obstacle_distances(rob, q, t, origin, capsules)
        trace = trace_from_log(rob, log, feet[:2], hand_frame=rob.hands[1], hand_goal=hand_goal,
                               extra={"obstacle_distance": dist}, support=support)
        metrics = {"obstacle_distance_min_cm": 1e2 * float(dist.min())}
        return RunResult(spec, {**metrics, **own}, trace, self.panels(trace), note)

    @staticmethod
    def panels(trace: Trace) -> list[Panel]:
        """CoG error, obstacle distance against ``d_safe``, hand error, a torso joint."""
        t = trace.t
        err = 1e3 * trace.cog_error  # [mm], as in the tables
        dist = 1e2 * trace.extra["obstacle_distance"]
        out = [
            Panel("Balancing Error", "error [mm]", t,
                  (Line("X Direction", err[:, 0]), Line("Y Direction", err[:, 1]))),
            Panel("Obstacle Distance", "distance [cm]", t,
                  (Line("d_safe", np.full_like(dist, 1e2 * D_SAFE), "dashed"),
                   Line("closest capsule", dist))),
        ]
        if trace.hand is not None and trace.hand_goal is not None:
            d = 1e2 * np.linalg.norm(trace.hand - trace.hand_goal, axis=1)
            out.append(Panel("Right Hand Held Still", "error [cm]", t, (Line("hand error", d),)))
        for joint in ("torso_pitch", "torso_yaw"):
            if joint in trace.joint_names:
                out.append(Panel(joint.replace("_", " ").title(), "angle [rad]", t,
                                 (Line(joint, trace.joint(joint)),)))
        return out
