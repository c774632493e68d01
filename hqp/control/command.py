"""What a controller sends at one control step: the command and its feasibility report.

:class:`Command` holds the torques ``tau (na,)`` [N m], the expected accelerations
``qdd (nv,)``, the contact wrenches and a :class:`FeasibilityReport`: one
:class:`TaskStatus` per task (satisfied, in conflict with a higher level, singular, inactive),
the seed's feasibility flag (001, "the servo module sends a flag to the active behavior
indicating infeasibility").
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from hqp.errors import UnknownName


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
        weak_directions: Directions of the task's level filtered by its weak-direction
            threshold at this step (:meth:`hqp.stack.Stack.set_weak_threshold`; 0 without
            one).

    """

    name: str
    level: int
    status: Feasibility
    residual: float = 0.0
    yields_to: int | None = None
    sigma_min: float = float("nan")
    weak_directions: int = 0

    @property
    def feasible(self) -> bool:
        """Whether the task is satisfied (or inactive)."""
        return self.status in (Feasibility.SATISFIED, Feasibility.INACTIVE)


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

    A report made from a step's raw results (``statuses=``, a function of none, as the
    native step makes it: residuals, singular values and costs computed in the step) builds
    its :class:`TaskStatus` objects when :attr:`tasks` is first read. Immutable; equal when
    its fields are.

    """

    __slots__ = ("_tasks", "_statuses", "safe_mode", "strictness_suspended", "notes",
                 "_level_costs")

    def __init__(self, tasks: Sequence[TaskStatus] = (), safe_mode: bool = False,
                 strictness_suspended: bool = False, notes: Sequence[str] = (),
                 level_costs: Sequence[float] = (), *,
                 statuses: Callable[[], tuple[TaskStatus, ...]] | None = None) -> None:
        object.__setattr__(self, "_tasks", None if statuses is not None else tuple(tasks))
        object.__setattr__(self, "_statuses", statuses)
        object.__setattr__(self, "safe_mode", bool(safe_mode))
        object.__setattr__(self, "strictness_suspended", bool(strictness_suspended))
        object.__setattr__(self, "notes", tuple(notes))
        object.__setattr__(self, "_level_costs", level_costs)

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"FeasibilityReport is immutable (cannot set {name!r})")

    @property
    def tasks(self) -> tuple[TaskStatus, ...]:
        """One status per task of the stack, in level order."""
        if self._tasks is None:
            assert self._statuses is not None
            object.__setattr__(self, "_tasks", tuple(self._statuses()))
            object.__setattr__(self, "_statuses", None)
        return self._tasks

    @property
    def level_costs(self) -> tuple[float, ...]:
        """Optimal cost of each level (as reported by the solver)."""
        costs = self._level_costs
        if not isinstance(costs, tuple):
            costs = tuple(float(c) for c in costs)
            object.__setattr__(self, "_level_costs", costs)
        return costs

    def _fields(self) -> tuple[object, ...]:
        return (self.tasks, self.safe_mode, self.strictness_suspended, self.notes,
                self.level_costs)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FeasibilityReport):
            return NotImplemented
        return self._fields() == other._fields()

    def __hash__(self) -> int:
        return hash(self._fields())

    def __repr__(self) -> str:
        return (f"FeasibilityReport(tasks={self.tasks!r}, safe_mode={self.safe_mode!r}, "
                f"strictness_suspended={self.strictness_suspended!r}, notes={self.notes!r}, "
                f"level_costs={self.level_costs!r})")

    def __reduce__(self) -> tuple[object, ...]:
        return (FeasibilityReport, self._fields())

    def __getitem__(self, name: str) -> TaskStatus:
        """Return the status of a task by name.

        Raises:
            UnknownName: No task of that name in the report.

        """
        for s in self.tasks:
            if s.name == name:
                return s
        raise UnknownName("task", name, [s.name for s in self.tasks])

    def __contains__(self, name: object) -> bool:
        return any(s.name == name for s in self.tasks)

    @property
    def feasible(self) -> bool:
        """Whether every task is satisfied or inactive and no safe mode was needed."""
        return not self.safe_mode and all(s.feasible for s in self.tasks)

    @property
    def any_conflict(self) -> bool:
        """Whether a task is in conflict (:meth:`conflicts` not empty).

        A report made from a step's raw results answers from its residuals without making
        the :class:`TaskStatus` objects (when its ``statuses`` function has an
        ``any_conflict`` of its own, as the native step's has).
        """
        if self._tasks is None:
            quick = getattr(self._statuses, "any_conflict", None)
            if quick is not None:
                return bool(quick())
        return any(s.status is Feasibility.CONFLICT for s in self.tasks)

    @property
    def names(self) -> tuple[str, ...]:
        """Task names, in the order of :attr:`tasks`.

        A report made from a step's raw results answers without making the statuses.
        """
        if self._tasks is None:
            quick = getattr(self._statuses, "names", None)
            if quick is not None:
                return tuple(quick())
        return tuple(s.name for s in self.tasks)

    def conflicts(self) -> list[TaskStatus]:
        """Return the tasks in conflict with a higher level or their own.

        A report made from a step's raw results makes only these statuses (when its
        ``statuses`` function has a ``conflicts`` of its own, as the native step's has).
        """
        if self._tasks is None:
            quick = getattr(self._statuses, "conflicts", None)
            if quick is not None:
                return list(quick())
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
