"""What a behavior file may say about each task type.

For every task type: its frame-valued parameters (checked against the
robot), its goal-valued parameters (expressions, evaluated every control
step, possibly from runtime inputs or a planner) and its static parameters
(gains, axes, ...). The loader rejects any other key, naming the ones that
are expected.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hqp.tasks.base import Category

GAINS: dict[str, type | tuple[type, ...]] = {
    "kp": (int, float),
    "kv": (int, float),
    "max_velocity": (int, float),
    "max_acceleration": (int, float),
}
"""PD parameters shared by every tracking task (seed: kp, velocity and acceleration saturation)."""


@dataclass(frozen=True)
class TaskSchema:
    """Keys a task type accepts in a behavior file.

    Attributes:
        type: Type name as written in files.
        category: Default priority category.
        frames: Frame-valued keys; the first one is required when ``frame_required``.
        goals: Goal-valued keys (expressions or constants); the first is the primary goal,
            the one a phase's ``goals.<task> = "..."`` shorthand overrides.
        params: Static keys and their accepted Python types.
        required: Keys that must be present.
        description: One line for ``hqp behaviors --tasks`` and error messages.

    """

    type: str
    category: Category
    frames: tuple[str, ...] = ()
    goals: tuple[str, ...] = ()
    params: dict[str, type | tuple[type, ...]] = field(default_factory=dict)
    required: tuple[str, ...] = ()
    description: str = ""

    def keys(self) -> list[str]:
        """Every key the type accepts (besides ``type``, ``level``, ``weight``)."""
        return [*self.frames, *self.goals, *self.params]


_TRACK = ("goal", "goal_velocity", "goal_acceleration")

SCHEMAS: dict[str, TaskSchema] = {
    s.type: s
    for s in (
        TaskSchema(
            "com", Category.BALANCE, goals=_TRACK,
            params={**GAINS, "axes": str},
            description="centre of gravity position (axes 'xy' for static balance, 'z' hip height)",
        ),
        TaskSchema(
            "cop", Category.BALANCE, goals=("goal",),
            params={"kp": (int, float)},
            description="centre of pressure / ZMP of the support (2D goal)",
        ),
        TaskSchema(
            "momentum", Category.BALANCE, goals=("goal",),
            params={"part": str, "kv": (int, float), "max_acceleration": (int, float)},
            description="centroidal momentum (part 'angular' (default), 'linear' or 'all'; "
            "goal default zero: damping with gain kv [1/s], rate saturated at max_acceleration)",
        ),
        TaskSchema(
            "position", Category.OPERATIONAL, frames=("frame",), goals=_TRACK,
            params={**GAINS, "axes": str}, required=("frame",),
            description="position of a frame point in the world",
        ),
        TaskSchema(
            "orientation", Category.OPERATIONAL, frames=("frame",), goals=("goal",),
            params={**GAINS}, required=("frame",),
            description="orientation of a frame (goal: roll-pitch-yaw [rad] or a 3x3 matrix)",
        ),
        TaskSchema(
            "pose", Category.OPERATIONAL, frames=("frame",),
            goals=("goal", "goal_rotation", "goal_velocity", "goal_acceleration"),
            params={**GAINS}, required=("frame",),
            description="position and orientation of a frame",
        ),
        TaskSchema(
            "gaze", Category.OPERATIONAL, frames=("frame",), goals=("target",),
            params={**GAINS, "axis": list}, required=("frame",),
            description="2 coordinates of the ray from a frame (head) pointing at a target",
        ),
        TaskSchema(
            "internal_forces", Category.OPERATIONAL, goals=("goal",),
            params={"contacts": list, "kp": (int, float)},
            description="internal forces between two contacts (driven to a goal, default zero)",
        ),
        TaskSchema(
            "posture", Category.POSTURE, goals=("goal",),
            params={**GAINS, "joints": list},
            description="joint posture (a captured pose; 'standing' for the robot's standing pose)",
        ),
        TaskSchema(
            "effort", Category.POSTURE,
            params={},
            description="minimise joint torques",
        ),
        TaskSchema(
            "forces", Category.POSTURE,
            params={},
            description="minimise the contact forces (how the feet share the load)",
        ),
        TaskSchema(
            "obstacle", Category.COLLISION, frames=("frame",),
            params={"radius": (int, float), "center": list, "obstacle_radius": (int, float),
                    "d_safe": (int, float)}, required=("frame",),
            description="keep a frame's sphere at least d_safe from a spherical obstacle",
        ),
    )
}
"""Task types a behavior file may use, by name."""
