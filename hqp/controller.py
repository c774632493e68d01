"""The execution layer (the seed's servo): robot state -> levels -> one HQP solve -> torques.

One control step of :class:`WholeBodyController`:

1. ``model.update(q, v)``, once, shared by every task;
2. the rows of every task, stacked into the levels of the :class:`~hqp.stack.Stack`
   (``Stack.build``, apart from the solve);
3. one solve of the strict hierarchy with a persistent
   :class:`hqp.solver.HierarchicalSolver`;
4. joint torques from the solution ``x = [qdd | f_1 | ... | f_k]`` through the actuated rows of
   ``M qdd + h = S^T tau + J_c^T f``;
5. a :class:`FeasibilityReport`: per task, satisfied / in conflict with a higher level (its
   residual and the level it yields to) / singular (smallest singular value of the task
   projected on the optimal set of the levels above). This is the seed's feasibility flag
   (001, "the servo module sends a flag to the active behavior indicating infeasibility").

The controller never returns NaN torques: if the solve fails or returns non-finite values, it
sends a defined safe command (gravity and contact-force compensation with joint damping on the
current contacts) and says so in the report (``Command.safe_mode``).

Every controller (this one and the null-space cross-check of :mod:`hqp.nullspace`) implements the
:class:`Controller` interface: ``step(state, t) -> Command``, task and contact management.
"""

from __future__ import annotations

import abc
import enum
import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from hqp.model import RobotModel, RobotState
    from hqp.stack import Stack
    from hqp.tasks.base import Category, Task

logger = logging.getLogger(__name__)


class Feasibility(enum.Enum):
    """Feasibility status of one task at one control step."""

    SATISFIED = "satisfied"
    """The task's rows are met (residual below the controller's tolerance)."""
    CONFLICT = "conflict"
    """The task's rows are not met because a higher level (or a task of its own level) wins."""
    SINGULAR = "singular"
    """The task is met but its rows, projected on the optimal set above, are (nearly) singular."""
    INACTIVE = "inactive"
    """The task produced no rows at this step (e.g. a released contact, an empty task)."""


@dataclass(frozen=True)
class TaskStatus:
    """Feasibility of one task at one control step.

    Attributes:
        name: Task name.
        level: Index of the task's level (0 is the highest priority).
        status: Satisfied, conflict, singular or inactive.
        residual: Norm of the task's unweighted residual: equality residual ``A x - b`` and
            inequality violations ``dist(C x, [lower, upper])`` stacked (units of the rows,
            e.g. [m/s^2] for a position task).
        yields_to: For a conflict, the index of the highest-priority level whose optimal set
            makes the task unreachable (the task's own level when it is traded against a
            task of its own level by weights); ``None`` otherwise, or when the task is
            infeasible on its own.
        sigma_min: Smallest singular value of the task's rows projected on the optimal set of
            the levels above (``nan`` when not computed).

    """

    name: str
    level: int
    status: Feasibility
    residual: float = 0.0
    yields_to: int | None = None
    sigma_min: float = float("nan")

    @property
    def feasible(self) -> bool:
        """Whether the task is satisfied (or inactive)."""
        return self.status in (Feasibility.SATISFIED, Feasibility.INACTIVE)


@dataclass(frozen=True)
class FeasibilityReport:
    """Per-task feasibility of one control step (the seed's feasibility flags).

    Attributes:
        tasks: One status per task of the stack, in level order.
        safe_mode: The safe command was sent (solve failed or non-finite result).
        strictness_suspended: The torques sent were interpolated between two hierarchies (a
            change that could not be ramped: contact made, task or contact removed), so for
            this step the strict hierarchy is not exactly enforced.
        notes: Human-readable notes (why safe mode, which change is being blended, ...).
        level_costs: Optimal cost of each level (as reported by the solver).

    """

    tasks: tuple[TaskStatus, ...] = ()
    safe_mode: bool = False
    strictness_suspended: bool = False
    notes: tuple[str, ...] = ()
    level_costs: tuple[float, ...] = ()

    def __getitem__(self, name: str) -> TaskStatus:
        """Return the status of a task by name.

        Raises:
            UnknownName: No task of that name in the report.

        """
        for s in self.tasks:
            if s.name == name:
                return s
        from hqp.errors import UnknownName

        raise UnknownName("task", name, [s.name for s in self.tasks])

    def __contains__(self, name: object) -> bool:
        return any(s.name == name for s in self.tasks)

    @property
    def feasible(self) -> bool:
        """Whether every task is satisfied or inactive and no safe mode was needed."""
        return not self.safe_mode and all(s.feasible for s in self.tasks)

    def conflicts(self) -> list[TaskStatus]:
        """Return the tasks in conflict with a higher level or their own."""
        return [s for s in self.tasks if s.status is Feasibility.CONFLICT]

    def singular(self) -> list[TaskStatus]:
        """Return the tasks reported singular."""
        return [s for s in self.tasks if s.status is Feasibility.SINGULAR]


@dataclass(frozen=True)
class Command:
    """What a controller sends to the robot at one control step.

    Attributes:
        tau: Joint torques ``(na,)`` [N m] over the actuated joints, in the model's order.
        qdd: Joint accelerations ``(nv,)`` the controller expects (pinocchio convention).
        wrenches: Contact wrench ``(6,)`` or force ``(3,)`` by contact name, at the contact
            frame's origin, world axes, force first [N, N m].
        report: Per-task feasibility report.
        safe_mode: The safe command was sent instead of the hierarchy's solution.
        timings: Wall-clock durations of the step's phases [s]: ``update`` (model update),
            ``rows`` (task rows and levels), ``solve``, ``report``, ``total``.
        t: Control time of the step [s].

    """

    tau: np.ndarray
    qdd: np.ndarray
    wrenches: Mapping[str, np.ndarray]
    report: FeasibilityReport
    safe_mode: bool = False
    timings: Mapping[str, float] = field(default_factory=dict)
    t: float = 0.0


class Controller(abc.ABC):
    """Interface of a whole-body controller (HQP and null-space alike).

    A controller holds a robot model, a :class:`~hqp.stack.Stack` of tasks and the declared
    contacts; each control step turns a measured :class:`~hqp.model.RobotState` into a
    :class:`Command`. Tasks and contacts may be added and removed while it runs; the
    controller keeps the torques continuous (ramps, or a stated torque interpolation flagged
    in the report as ``strictness_suspended``).

    Attributes:
        model: The controller's robot model (updated once per step).
        stack: The ordered levels of tasks.
        dt: Control period [s].

    """

    model: RobotModel
    stack: Stack
    dt: float

    @abc.abstractmethod
    def step(self, state: RobotState, t: float) -> Command:
        """One control step.

        Args:
            state: Measured state (configuration, velocity, optional contact flags and wrenches).
            t: Control time [s].

        Returns:
            The command: torques, accelerations, contact wrenches, feasibility report.

        """

    # -- tasks ------------------------------------------------------------------------------

    def add_task(
        self,
        task: Task,
        level: int | Category | None = None,
        *,
        t: float | None = None,
        ramp_time: float | None = None,
    ) -> None:
        """Add a task at a level (default: its category's level), ramped in from zero effect.

        Args:
            task: The task (its name must be unique in the stack).
            level: Level index, or a category whose level is used; ``None``: the task's
                category.
            t: Time of the addition [s] (default: the time of the last step).
            ramp_time: Duration of the ramp [s] (default: the stack's).

        """
        self.stack.add(task, level, t=self._now(t), ramp_time=ramp_time)

    def remove_task(self, name: str, *, t: float | None = None) -> None:
        """Remove a task; the torque jump is blended out (see :class:`~hqp.stack.Stack`)."""
        self.stack.remove(name, t=self._now(t))

    def task(self, name: str) -> Task:
        """Return a task of the stack by name."""
        return self.stack.task(name)

    # -- contacts ---------------------------------------------------------------------------

    def activate_contact(self, name: str, *, t: float | None = None) -> None:
        """Declare a contact made (its slot becomes free; the change is torque-blended)."""
        self.stack.activate_contact(name, t=self._now(t))

    def deactivate_contact(
        self, name: str, *, t: float | None = None, unload_time: float | None = None
    ) -> None:
        """Release a contact: its normal force bound is ramped to zero, then the slot is freed.

        Args:
            name: Contact name.
            t: Time at which unloading starts [s] (default: the time of the last step).
            unload_time: Duration of the unloading ramp [s] (default: the stack's).

        """
        self.stack.deactivate_contact(name, t=self._now(t), unload_time=unload_time)

    @property
    def active_contacts(self) -> tuple[str, ...]:
        """Names of the contacts currently active (loaded or unloading)."""
        return self.stack.active_contacts

    def _now(self, t: float | None) -> float:
        """Time of a change: ``t`` when given, else the time of the last step (or 0)."""
        if t is not None:
            return float(t)
        return float(getattr(self, "last_t", 0.0))
