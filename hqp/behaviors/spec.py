"""Declarative pieces of the action layer: inputs, task specs, action primitives, phases.

These are plain, frozen descriptions (the seed's behavior editor made
declarative); :mod:`hqp.behaviors.loader` builds them from a TOML file and
:class:`hqp.behaviors.behavior.Behavior` turns them into live tasks on a
controller.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hqp.behaviors.expressions import Expression
from hqp.tasks.base import Category


@dataclass(frozen=True)
class InputSpec:
    """A runtime input (the seed's "in" parameters, given by a sensory layer).

    Attributes:
        name: Input name (read in expressions as ``input.<name>``).
        shape: Shape of its value (``()`` for a scalar).
        default: Value before any sample arrives (``None``: the input must be given, or
            :attr:`default_expression` gives it once the robot is known).
        interpolate: Interpolate linearly between timed samples (else zero-order hold).
        description: Free text.
        default_expression: The default written as an expression of the robot's dimensions
            (``"robot.right_shoulder + [0.3, 0, 0]"``), evaluated when the behavior is
            prepared for a robot.

    """

    name: str
    shape: tuple[int, ...]
    default: np.ndarray | None = None
    interpolate: bool = False
    description: str = ""
    default_expression: Expression | None = None


@dataclass(frozen=True)
class TaskSpec:
    """One control primitive of a behavior, as written in its file.

    Attributes:
        name: Task name (unique in the behavior; the controller's task name).
        type: Task type (a key of :data:`hqp.behaviors.factory.TASK_TYPES`).
        level: Priority level index, or a category (its default level).
        weight: Weight inside its level.
        frames: Frame-valued parameters (e.g. ``{"frame": "right_hand"}``).
        params: Static parameters (gains, axes, ...).
        goals: Goal-valued parameters as expressions (evaluated every step).

    """

    name: str
    type: str
    level: int | Category
    weight: float = 1.0
    frames: Mapping[str, str] = field(default_factory=dict)
    params: Mapping[str, Any] = field(default_factory=dict)
    goals: Mapping[str, Expression] = field(default_factory=dict)

    def inputs(self) -> set[str]:
        """Names of the runtime inputs its goals read."""
        return {a for g in self.goals.values() for (ns, a) in g.attributes if ns == "input"}


@dataclass(frozen=True)
class ActionPrimitive:
    """A named task set with a priority level per task (the seed's action primitive).

    The seed's jumping table is the model: obstacle avoidance first, static
    balance, then hip height / head orientation / right hand, then
    orientations and arm posture. Goals written ``input.<name>`` are runtime
    inputs.

    Attributes:
        name: Primitive name.
        tasks: Its tasks (with their levels and parameters).

    """

    name: str
    tasks: tuple[TaskSpec, ...]

    @property
    def task_names(self) -> tuple[str, ...]:
        """Names of its tasks."""
        return tuple(t.name for t in self.tasks)

    @property
    def runtime_inputs(self) -> tuple[str, ...]:
        """Names of the runtime inputs its goals read (sorted)."""
        return tuple(sorted(set().union(*(t.inputs() for t in self.tasks)))) if self.tasks else ()


@dataclass(frozen=True)
class Transition:
    """A transition of the behavior's state machine.

    Attributes:
        to: Target phase.
        when: Condition (an expression over sensed quantities, simulated time,
            feasibility flags, inputs and planner outputs).

    """

    to: str
    when: Expression


@dataclass(frozen=True)
class PhaseSpec:
    """One phase (state) of a behavior.

    Attributes:
        name: Phase name.
        action: The action primitive active in this phase.
        contacts: Contacts that support the robot in this phase (others are released).
        transitions: Outgoing transitions, checked in order; the first whose
            condition holds fires.
        goals: Goal overrides for this phase: task name -> goal parameter -> expression.
        final: The phase may last until the end (no exit required).
        safety: Phase entered when a watched task becomes infeasible (seed Figure 13).
        watch: Tasks whose infeasibility sends the behavior to ``safety``.
        ramp_time: Duration of the ramps of added tasks [s] (``None``: the behavior's).
        unload_time: Unloading time of the contacts it releases [s] (``None``: the
            behavior's).
        blend_time: Torque interpolation after a change that cannot be ramped (a contact
            made or released at once) while this phase is active [s] (``None``: the
            controller's).
        joint_braking: ``"contacts"`` (the joint-limit braking follows the active contacts)
            or ``"airborne"`` (braking of a limb in the air: a take-off, whose legs brake
            by leaving the floor).

    """

    name: str
    action: ActionPrimitive
    contacts: tuple[str, ...]
    transitions: tuple[Transition, ...] = ()
    goals: Mapping[str, Mapping[str, Expression]] = field(default_factory=dict)
    final: bool = False
    safety: str | None = None
    watch: tuple[str, ...] = ()
    ramp_time: float | None = None
    unload_time: float | None = None
    blend_time: float | None = None
    joint_braking: str = "contacts"


@dataclass(frozen=True)
class PlannerSpec:
    """A trajectory generator feeding ``plan.*`` names (e.g. the walk planner).

    Attributes:
        type: Planner type (``"walk"``; ``"placo_walk"`` is an alias).
        params: Its parameters.

    """

    type: str
    params: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class BehaviorSpec:
    """A whole-body behavior: a state machine over action primitives.

    Attributes:
        name: Behavior name.
        description: Free text.
        initial: Initial phase.
        phases: Phases by name, in file order.
        tasks: Every task of the behavior by name.
        inputs: Runtime inputs by name.
        planner: Optional trajectory generator.
        duration: Default run duration [s].
        robot: Default robot.
        ramp_time: Default ramp of added tasks [s].
        unload_time: Time to unload a released contact [s].
        path: File the behavior was read from (``None``: built in Python).
        contact_frames: Declared contacts (name -> frame) as written in the file,
            e.g. ``{"left_foot": "left_foot"}``; empty: the robot's own contacts.
        poses: Captured poses by name: joint -> position [rad].
        inputs_file: Default inputs file (JSON Lines), used when none is given.
        backend: QP backend of the HQP controller running the behavior (``None``: the
            controller's default).
        max_joint_acceleration: Upper clip of the HQP controller's joint-acceleration
            bounds [rad/s^2] (``None``: the controller's default, see
            :func:`hqp.controller.standing_stack`).
        max_torque_rate: The HQP servo's torque-rate level [N m/s] (``None``: the
            controller's default, :data:`hqp.control.servo.MAX_TORQUE_RATE`; ``0``: none).

    """

    name: str
    description: str
    initial: str
    phases: Mapping[str, PhaseSpec]
    tasks: Mapping[str, TaskSpec]
    inputs: Mapping[str, InputSpec] = field(default_factory=dict)
    planner: PlannerSpec | None = None
    duration: float = 5.0
    robot: str = "paper-humanoid"
    ramp_time: float = 0.2
    unload_time: float = 0.1
    path: Path | None = None
    contact_frames: Mapping[str, str] = field(default_factory=dict)
    poses: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    inputs_file: Path | None = None
    backend: str | None = None
    max_joint_acceleration: float | None = None
    max_torque_rate: float | None = None

    def phase_enum(self) -> type[enum.Enum]:
        """Return an :class:`enum.Enum` of the phases (values: the phase names, in file order)."""
        cls_name = "".join(p.capitalize() for p in self.name.replace("-", "_").split("_")) + "Phase"
        return enum.Enum(cls_name, [(p.upper().replace("-", "_"), p) for p in self.phases])
