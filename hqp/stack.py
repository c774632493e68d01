"""Priority levels: an ordered stack of tasks, built into solver levels apart from the solve.

A :class:`Stack` holds any number of levels (default: one per :class:`~hqp.tasks.base.Category`,
in the order of docs/concepts/levels.md "Levels of a control step": physics, contact and actuation
limits, joint limits, collision, balance, operational, posture). Tasks that share a level are
stacked into one :class:`hqp.solver.Level`, each task's rows scaled by ``sqrt(weight)``; a strict
hierarchy ignores any scaling between levels, so weights only trade tasks of the same level.

:meth:`Stack.build` turns the tasks into levels at the current state without solving them (the
``build_ik`` of mink), and records the row ranges of every task (:class:`TaskSpan`) so that a
controller can attribute residuals to tasks. It changes nothing: building twice gives the same
levels. What moves with time (ramps, contact unloading and release) is advanced by
:meth:`Stack.advance`, which the controller calls once per step before building.

Changes at runtime, without a jump in the motion:

* **Adding a task** ramps it in from zero effect (bumpless transfer). At the first step after
  the addition, the offset ``d = A x_prev - b`` between what the previous solution ``x_prev``
  does along the task and what the task asks is recorded (for inequality rows, how far
  ``C x_prev`` lies outside the bounds); then, for a ramp fraction ``s`` rising from 0 to 1
  along a minimum-jerk profile over ``ramp_time``, the task's equality target is
  ``b_s = b + (1 - s) d`` and its bounds are widened by ``(1 - s)`` times their offsets. At
  ``s = 0`` the previous solution satisfies the new task exactly, so it is still the
  lexicographic optimum (levels above are unchanged; at the task's level the added cost is zero
  at ``x_prev``; levels below are optimised over a subset that still contains it), and the
  torques start continuous. The offset is frozen at the addition while ``b`` is the task's own
  target at every step, so the task's feedback (its damping) acts from the first step; pinning
  the target to the previous step's ``A x_prev`` instead would hold the task's acceleration
  constant through the ramp and let its velocity run away.
  Besides, a tracking task with a fixed goal and ``move_to`` (the primitives of
  :mod:`hqp.tasks`) starts from zero error: its goal starts at the current value and follows a
  minimum-jerk trajectory to the requested goal over the same ``ramp_time``.
* **Releasing a contact** first unloads it: a row ``n^T f <= f_max(t)`` (``n`` the contact
  normal, world axes) at the contact-limits level, with ``f_max`` falling from the normal force
  at the start of unloading to zero along a minimum-jerk profile over ``unload_time``; then the
  contact's tasks are dropped and its slot is held at zero by a physics row.
* **Changes that cannot be ramped** (removing a task, making a contact, releasing an unloaded
  contact) are recorded as *blend events*; the controller then interpolates its torques from the
  last command to the new hierarchy's over ``blend_time`` and reports that strictness was
  suspended (see :class:`hqp.control.servo.WholeBodyController`). For a contact made, both
  hierarchies are solved during the blend (the one without the contact inside
  :meth:`Stack.contact_released`) and their torques interpolated, so that the new contact's
  wrench is phased in and the old hierarchy's feedback stays active.
"""

from __future__ import annotations

import contextlib
import enum
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import HQPError, InvalidInput, InvalidLevel, UnknownName
from hqp.model.layout import ContactType
from hqp.solver import Level
from hqp.tasks.base import Category, Edits, Rows, Task, Tracked, edited
from hqp.tasks.contact import ContactLimits
from hqp.tasks.reference import (  # min_jerk: also importable as hqp.stack.min_jerk
    MIN_JERK_PEAK_ACCELERATION,
    MIN_JERK_PEAK_VELOCITY,
    min_jerk,
)
from hqp.tasks.tracking import TrackingTask

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout

DEFAULT_LEVELS: tuple[Category, ...] = tuple(Category)
"""Default levels: one per category, highest first."""


class ContactMode(enum.Enum):
    """State of a declared contact."""

    ACTIVE = "active"
    """Loaded: the contact's tasks are in the stack."""
    UNLOADING = "unloading"
    """Active, with its normal-force bound ramping to zero."""
    INACTIVE = "inactive"
    """Released: its tasks are out of the stack and its slot is held at zero."""


@dataclass
class _TaskEntry(Tracked):
    task: Task
    level: int
    added_at: float
    ramp_time: float
    contact: str | None = None
    goal_ramp_pending: bool = False
    offsets: tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None] | None = None


def _entry_level(entry: _TaskEntry) -> int:
    return entry.level


@dataclass
class _ContactEntry(Tracked):
    name: str
    frame: str
    kind: ContactType
    mode: ContactMode
    unload_start: float = 0.0
    unload_time: float = 0.0
    f_start: float | None = None
    f_max_nominal: float | None = None


@dataclass(frozen=True)
class TaskSpan:
    """Where a task's rows sit in the built levels.

    Attributes:
        name: Task name.
        level: Index of the task's level in the stack (0: highest priority).
        built_level: Index of that level in :attr:`BuiltStack.levels` (empty levels are
            skipped).
        eq: Slice of the level's equality rows that belong to the task.
        ineq: Slice of the level's inequality rows that belong to the task.
        weight: The task's weight (its rows are scaled by ``sqrt(weight)`` in the level).
        ramp: Ramp fraction in [0, 1] (1: the task's own rows, no ramp).
        internal: A row added by the stack (contact unloading or release), not a user task.

    """

    name: str
    level: int
    built_level: int
    eq: slice
    ineq: slice
    weight: float = 1.0
    ramp: float = 1.0
    internal: bool = False


@dataclass(frozen=True)
class BuiltStack:
    """The levels of one control step and the row ranges of every task.

    Attributes:
        levels: Non-empty solver levels, highest priority first.
        level_index: Stack level index of each built level.
        spans: Row ranges of every task, in level order.
        rows: Unweighted rows of every task by name (as fed to the level, ramps applied).
        n: Number of decision variables.

    """

    levels: list[Level]
    level_index: tuple[int, ...]
    spans: tuple[TaskSpan, ...]
    rows: dict[str, Rows] = field(default_factory=dict)
    n: int = 0

    def span(self, name: str) -> TaskSpan:
        """Return the span of a task by name.

        Raises:
            UnknownName: No task of that name.

        """
        for s in self.spans:
            if s.name == name:
                return s
        raise UnknownName("task", name, [s.name for s in self.spans])


@dataclass(frozen=True)
class BlendEvent:
    """A change of the stack that cannot be ramped (the controller blends torques).

    Attributes:
        t: Time of the change [s].
        note: What changed.
        contact: Name of the contact made, for a contact made at runtime (the controller then
            interpolates between the torques of the hierarchy without and with it, see
            :meth:`Stack.contact_released`); ``None`` for other changes.

    """

    t: float
    note: str
    contact: str | None = None


class Stack:
    """An ordered list of levels of tasks, with contacts declared for the whole stack.

    Args:
        levels: Level names or categories, highest priority first (default: one level per
            :class:`Category`). A task added without a level goes to the level of its
            category.
        ramp_time: Default ramp of an added task [s].
        unload_time: Default duration of the unloading of a released contact [s].
        blend_time: Duration of the torque interpolation after a change that cannot be
            ramped [s] (used by the controller).

    Raises:
        InvalidInput: No level, duplicate level names, or negative times.

    """

    def __init__(
        self,
        levels: Sequence[str | Category] | None = None,
        *,
        ramp_time: float = 0.3,
        unload_time: float = 0.3,
        blend_time: float = 0.05,
    ) -> None:
        specs = list(DEFAULT_LEVELS if levels is None else levels)
        if not specs:
            raise InvalidInput("Stack: at least one level is needed")
        names = [s.name.lower() if isinstance(s, Category) else str(s) for s in specs]
        if len(set(names)) != len(names):
            raise InvalidInput(f"Stack: duplicate level names {names}")
        for label, value in (("ramp_time", ramp_time), ("unload_time", unload_time),
                             ("blend_time", blend_time)):
            if not math.isfinite(value) or value < 0.0:
                raise InvalidInput(f"Stack: {label} must be finite and >= 0, got {value}")
        self.level_names: tuple[str, ...] = tuple(names)
        self.level_categories: tuple[Category | None, ...] = tuple(
            s if isinstance(s, Category) else None for s in specs
        )
        self.ramp_time = float(ramp_time)
        self.unload_time = float(unload_time)
        self.blend_time = float(blend_time)
        self._tasks: list[_TaskEntry] = []
        self._contacts: dict[str, _ContactEntry] = {}
        self._events: list[BlendEvent] = []
        self._managed: tuple[int, dict[str, bool]] = (-1, {})  # (_self_managed)
        self._weak = [0.0] * len(names)

    # -- levels -----------------------------------------------------------------------------

    @property
    def n_levels(self) -> int:
        """Number of levels."""
        return len(self.level_names)

    @property
    def weak_thresholds(self) -> tuple[float, ...]:
        """The weak-direction threshold of every level (:meth:`set_weak_threshold`)."""
        return tuple(self._weak)

    def weak_threshold(self, level: int | str | Category) -> float:
        """Return the weak-direction threshold of a level (0: none)."""
        return self._weak[self.level_of(level)]

    def set_weak_threshold(self, level: int | str | Category, threshold: float) -> None:
        """Set the weak-direction threshold of a level (``hqp.solver.Level.weak_threshold``).

        Along each direction in which the level's rows, projected on what the levels above
        leave free, have a singular value ``s`` below the threshold, the level's target is
        scaled by ``(s / threshold)^2``: a nearly singular task gets a bounded step instead
        of one growing as ``1 / s``. Directions at or above it are solved exactly. In the
        units of the level's weighted rows (a task's rows times ``sqrt(weight)``: for a
        position task of weight 1, metres of task motion per unit of the decision vector).

        Raises:
            InvalidInput: An unknown level, or a threshold that is not finite and ``>= 0``.

        """
        k = self.level_of(level)
        try:
            value = float(threshold)
        except (TypeError, ValueError):
            raise InvalidInput(f"Stack.set_weak_threshold: expected a float, got "
                               f"{threshold!r}") from None
        if isinstance(threshold, bool) or not (0.0 <= value < math.inf):
            raise InvalidInput(f"Stack.set_weak_threshold: level {self.level_names[k]!r}: "
                               f"expected a finite threshold >= 0, got {threshold!r}")
        self._weak[k] = value
        edited()

    def level_of(self, level: int | str | Category | None, task: Task | None = None) -> int:
        """Resolve a level given as an index, a name, a category, or ``None`` (task's category).

        Raises:
            InvalidLevel: Index out of range, unknown name, or a category without a level.

        """
        if level is None:
            if task is None:
                raise InvalidLevel("Stack: a level or a task is needed")
            level = task.category
        if isinstance(level, Category):
            if level in self.level_categories:
                return self.level_categories.index(level)
            raise InvalidLevel(
                f"Stack: no level of category {level.name}; levels: {', '.join(self.level_names)}"
            )
        if isinstance(level, str):
            if level in self.level_names:
                return self.level_names.index(level)
            raise InvalidLevel(
                f"Stack: unknown level {level!r}; levels: {', '.join(self.level_names)}"
            )
        index = int(level)
        if not 0 <= index < self.n_levels:
            raise InvalidLevel(f"Stack: level {index} out of range 0..{self.n_levels - 1}")
        return index

    # -- tasks ------------------------------------------------------------------------------

    @property
    def tasks(self) -> tuple[Task, ...]:
        """Every task of the stack (contact tasks included), in level order."""
        return tuple(e.task for e in sorted(self._tasks, key=_entry_level))

    def task_levels(self) -> tuple[tuple[int, Task], ...]:
        """Every task with its level index, in level order (as :attr:`tasks`)."""
        return tuple((e.level, e.task) for e in sorted(self._tasks, key=_entry_level))

    def task(self, name: str) -> Task:
        """Return a task by name.

        Raises:
            UnknownName: No task of that name (lists the tasks).

        """
        return self._entry(name).task

    def level_of_task(self, name: str) -> int:
        """Return the level index of a task."""
        return self._entry(name).level

    def _entry(self, name: str) -> _TaskEntry:
        for e in self._tasks:
            if e.task.name == name:
                return e
        raise UnknownName("task", name, [e.task.name for e in self._tasks])

    def __contains__(self, name: object) -> bool:
        return any(e.task.name == name for e in self._tasks)

    def add(
        self,
        task: Task,
        level: int | str | Category | None = None,
        *,
        t: float | None = None,
        ramp_time: float | None = None,
        contact: str | None = None,
    ) -> None:
        """Add a task at a level.

        Args:
            task: The task; its name must be unique in the stack.
            level: Level index, name or category (``None``: the task's category).
            t: Time of the addition [s]. ``None`` adds the task without a ramp (building a
                stack before the first step).
            ramp_time: Ramp duration [s] (default: the stack's ``ramp_time``); 0: no ramp.
            contact: Name of a declared contact the task belongs to (it is dropped when the
                contact is released and restored when it is made again).

        Raises:
            InvalidInput: Not a task, a duplicate name, a negative ramp or an unknown contact.
            InvalidLevel: Unknown level.

        """
        if not isinstance(task, Task):
            raise InvalidInput(f"Stack.add: expected a Task, got {type(task).__name__}")
        if task.name in self:
            raise InvalidInput(f"Stack.add: a task named {task.name!r} is already in the stack")
        if contact is not None and contact not in self._contacts:
            raise UnknownName("contact", contact, self._contacts)
        ramp = self.ramp_time if ramp_time is None else float(ramp_time)
        if not math.isfinite(ramp) or ramp < 0.0:
            raise InvalidInput(f"Stack.add: ramp_time must be finite and >= 0, got {ramp}")
        index = self.level_of(level, task)
        self._tasks.append(
            _TaskEntry(task, index, -math.inf if t is None else float(t),
                       0.0 if t is None else ramp, contact,
                       goal_ramp_pending=t is not None and ramp > 0.0)
        )
        edited()

    def remove(self, name: str, *, t: float = 0.0) -> Task:
        """Remove a task (a blend event: the controller interpolates its torques).

        Returns:
            The removed task.

        Raises:
            UnknownName: No task of that name.

        """
        entry = self._entry(name)
        self._tasks.remove(entry)
        edited()
        self._events.append(BlendEvent(float(t), f"task {name!r} removed"))
        return entry.task

    def move(self, name: str, level: int | str | Category, *, t: float = 0.0) -> None:
        """Move a task to another level (a blend event)."""
        entry = self._entry(name)
        entry.level = self.level_of(level, entry.task)
        self._events.append(BlendEvent(float(t), f"task {name!r} moved to level {entry.level}"))

    # -- contacts ---------------------------------------------------------------------------

    def declare_contact(
        self,
        name: str,
        frame: str,
        kind: ContactType = ContactType.SURFACE,
        tasks: Sequence[tuple[Task, int | str | Category | None]] = (),
        *,
        active: bool = True,
    ) -> None:
        """Declare a contact (its slot exists in the layout whether it is active or not).

        Args:
            name: Contact name (as in the layout).
            frame: Contact frame.
            kind: Surface (6D wrench) or point (3D force).
            tasks: The contact's tasks with their levels (e.g. its motion constraint at the
                physics level and its friction/CoP limits at the contact-limits level).
            active: Whether the contact starts made.

        Raises:
            InvalidInput: A contact of that name already declared.

        """
        if name in self._contacts:
            raise InvalidInput(f"Stack: contact {name!r} already declared")
        self._contacts[name] = _ContactEntry(
            name, frame, ContactType(kind), ContactMode.ACTIVE if active else ContactMode.INACTIVE
        )
        for task, level in tasks:
            self.add(task, level, contact=name)
            if not active and hasattr(task, "deactivate"):
                task.deactivate()

    def add_contact(self, contact: Task, *, limits: bool = True, active: bool = True) -> None:
        """Declare a :class:`hqp.tasks.contact.Contact` with its rows at the default levels.

        The contact's physics rows go to the PHYSICS level and, with ``limits``, its
        :class:`~hqp.tasks.contact.ContactLimits` rows to the CONTACT_LIMITS level.

        Args:
            contact: A ``Contact`` task (it has ``frame``, ``kind``, ``activate()``,
                ``deactivate()``, ``max_normal_force``).
            limits: Also add its limit rows.
            active: Whether the contact starts made.

        """
        tasks: list[tuple[Task, int | str | Category | None]] = [(contact, Category.PHYSICS)]
        if limits:
            tasks.append((ContactLimits(contact), Category.CONTACT_LIMITS))
        self.declare_contact(contact.name, contact.frame, contact.kind,  # type: ignore[attr-defined]
                             tasks, active=active)

    @property
    def contacts(self) -> tuple[str, ...]:
        """Names of the declared contacts."""
        return tuple(self._contacts)

    def layout_contacts(self) -> list[tuple[str, str, ContactType]]:
        """Return the ``(name, frame, kind)`` of the declared contacts (for ``Layout.build``)."""
        return [(c.name, c.frame, c.kind) for c in self._contacts.values()]

    def contact_mode(self, name: str) -> ContactMode:
        """Return the mode of a declared contact."""
        return self._contact(name).mode

    @property
    def active_contacts(self) -> tuple[str, ...]:
        """Contacts that are loaded or unloading."""
        return tuple(c.name for c in self._contacts.values() if c.mode is not ContactMode.INACTIVE)

    def _contact(self, name: str) -> _ContactEntry:
        try:
            return self._contacts[name]
        except KeyError:
            raise UnknownName("contact", name, self._contacts) from None

    def activate_contact(self, name: str, *, t: float = 0.0) -> None:
        """Make a contact (a blend event: a rigid contact appears at once)."""
        c = self._contact(name)
        if c.mode is ContactMode.ACTIVE:
            return
        c.mode = ContactMode.ACTIVE
        c.f_start = None
        for entry in self._contact_tasks(name):
            if hasattr(entry.task, "activate"):
                entry.task.activate()
        self._restore_f_max(c)
        self._events.append(BlendEvent(float(t), f"contact {name!r} made", contact=name))

    @contextlib.contextmanager
    def contact_released(self, name: str) -> Iterator[None]:
        """Context in which an active contact is released as before it was made.

        Inside, :meth:`build` gives the hierarchy without the contact (its slot held at zero);
        on exit the contact is active again with its tasks' state (e.g. a stabilisation
        reference) as it was. The controller uses it to interpolate torques over
        ``blend_time`` from the hierarchy without a contact just made to the one with it.

        Raises:
            UnknownName: No contact of that name.

        """
        c = self._contact(name)
        if c.mode is not ContactMode.ACTIVE:
            yield
            return
        saved = [(e.task, e.task.__dict__.get("active"), e.task.__dict__.get("reference"))
                 for e in self._contact_tasks(name) if hasattr(e.task, "deactivate")]
        frames = self._active_frames()
        c.mode = ContactMode.INACTIVE
        for task, _, _ in saved:
            task.deactivate()  # type: ignore[attr-defined]
        self._set_active_frames(self._active_frames())
        try:
            yield
        finally:
            c.mode = ContactMode.ACTIVE
            self._set_active_frames(frames)
            for task, active, reference in saved:
                if active is not None:
                    task.active = active  # type: ignore[attr-defined]
                if "reference" in task.__dict__:
                    task.reference = reference  # type: ignore[attr-defined]

    def deactivate_contact(
        self, name: str, *, t: float = 0.0, unload_time: float | None = None
    ) -> None:
        """Start unloading a contact; it is released when its normal-force bound reaches zero.

        Args:
            name: Contact name.
            t: Start of the unloading [s].
            unload_time: Duration [s] (default: the stack's ``unload_time``); 0 releases at once
                (a blend event).

        """
        c = self._contact(name)
        if c.mode is not ContactMode.ACTIVE:
            return
        duration = self.unload_time if unload_time is None else float(unload_time)
        if not math.isfinite(duration) or duration < 0.0:
            raise InvalidInput(f"Stack: unload_time must be finite and >= 0, got {duration}")
        c.mode = ContactMode.UNLOADING
        c.unload_start = float(t)
        c.unload_time = duration
        c.f_start = None

    def _contact_tasks(self, name: str) -> list[_TaskEntry]:
        return [e for e in self._tasks if e.contact == name]

    def _owner(self, c: _ContactEntry) -> Task | None:
        """Return the contact task carrying ``max_normal_force`` (e.g. a ``Contact``), if any."""
        for entry in self._contact_tasks(c.name):
            if hasattr(entry.task, "max_normal_force") and hasattr(entry.task, "deactivate"):
                return entry.task
        return None

    def _restore_f_max(self, c: _ContactEntry) -> None:
        owner = self._owner(c)
        if owner is not None and c.f_max_nominal is not None:
            owner.max_normal_force = c.f_max_nominal  # type: ignore[attr-defined]
        c.f_max_nominal = None

    def steady(self, t: float) -> bool:
        """Whether the levels at ``t`` hold every task's own rows and nothing else.

        True when no task ramps in (or waits for its goal ramp), no contact unloads or is
        released without an owner holding its slot, and no blend event waits: then
        :meth:`advance` changes nothing and :meth:`build` stacks the tasks' rows as they are,
        which is what the native step computes (``hqp.control.native``).
        """
        if self._events:
            return False
        for c in self._contacts.values():
            if c.mode is ContactMode.UNLOADING:
                return False
            if c.mode is ContactMode.INACTIVE and not self._self_managed(c.name):
                return False
        for e in self._tasks:  # (what _ramping says, inline: called at every step)
            if e.goal_ramp_pending or (e.ramp_time > 0.0 and t < e.added_at + e.ramp_time):
                return False
        return True

    def native_ready(self, t: float) -> bool:
        """Whether the native step can run the step at ``t`` when :meth:`steady` does not hold.

        Contacts whose unloading is over at ``t`` are released first (as :meth:`advance`
        does). Then true when every unloading or released contact has an owner (a
        ``Contact`` task whose kernel takes its normal-force bound and holds its slot): tasks
        ramping in, goal ramps and unloading are advanced by :meth:`advance_native` and the
        ramps applied in the native rows (``NativeStep.set_ramp``, the same offsets as
        :meth:`build`). Blend events waiting (:meth:`events`) are the controller's to start.
        """
        self._update_contacts(t)
        for c in self._contacts.values():
            if c.mode is not ContactMode.ACTIVE and not self._self_managed(c.name):
                return False
        return True

    def advance_native(self, model: RobotModel, layout: Layout, t: float,
                       x_prev: np.ndarray | None) -> list[_TaskEntry]:
        """:meth:`advance` for a step whose rows the native core builds (:meth:`native_ready`).

        The same changes but the recording of ramp offsets from Python rows: unloading
        bounds, active contacts, goal ramps started. Returns the tasks ramping in at ``t``,
        whose offsets (``offsets``, ``None`` until recorded) the native step records from
        its own rows at ``x_prev`` and gives back.
        """
        for slot in layout.contacts:
            c = self._contacts[slot.name]
            if c.mode is ContactMode.UNLOADING:
                self._unload_bound(c, model, t, x_prev, slot.start, layout.n)
        self._set_active_frames(self._active_frames())
        ramping = []
        contacts = self._contacts
        for entry in self._tasks:  # (what _dropped and _ramping say, inline: every step)
            if (entry.contact is not None
                    and contacts[entry.contact].mode is ContactMode.INACTIVE
                    and not self._self_managed(entry.contact)):
                continue
            if entry.goal_ramp_pending:
                entry.goal_ramp_pending = False
                _ramp_goal(entry.task, model, entry.ramp_time, t)
            if entry.ramp_time > 0.0 and t < entry.added_at + entry.ramp_time:
                ramping.append(entry)
        return ramping

    def ramp_keep(self, entry: _TaskEntry, t: float) -> float:
        """``1 - s`` of a task ramping in at ``t`` (the share of its offsets its rows keep).

        In ``[0, 1]``: the minimum-jerk polynomial exceeds 1 by a rounding error (about
        2e-15) just below the ramp's end, which the native step's ``set_ramp`` refuses.
        """
        return min(max(1.0 - min_jerk((t - entry.added_at) / entry.ramp_time), 0.0), 1.0)

    def events(self) -> tuple[BlendEvent, ...]:
        """Return the blend events recorded since the last :meth:`pop_events`."""
        return tuple(self._events)

    def pop_events(self) -> list[BlendEvent]:
        """Return and forget the blend events recorded since the last call."""
        events, self._events = self._events, []
        return events

    # -- advance, then build ----------------------------------------------------------------

    def _update_contacts(self, t: float) -> None:
        for c in self._contacts.values():
            if c.mode is ContactMode.UNLOADING and t >= c.unload_start + c.unload_time:
                c.mode = ContactMode.INACTIVE
                self._restore_f_max(c)
                for entry in self._contact_tasks(c.name):
                    if hasattr(entry.task, "deactivate"):
                        entry.task.deactivate()
                self._events.append(BlendEvent(t, f"contact {c.name!r} released"))

    def _check_layout(self, layout: Layout, where: str) -> None:
        for slot in layout.contacts:
            if slot.name not in self._contacts:
                raise InvalidInput(
                    f"{where}: layout contact {slot.name!r} is not declared in the stack"
                )

    def _active_frames(self) -> tuple[str, ...]:
        frames = []
        for c in self._contacts.values():
            if c.mode is not ContactMode.INACTIVE:
                frames.append(c.frame)
        return tuple(frames)

    def _set_active_frames(self, frames: tuple[str, ...]) -> None:
        for entry in self._tasks:
            if entry.task.contact_aware:
                entry.task.set_active_contacts(frames)  # type: ignore[attr-defined]

    def _dropped(self, entry: _TaskEntry) -> bool:
        """Whether a task is out of the built levels (its contact released)."""
        return entry.contact is not None and (
            self._contacts[entry.contact].mode is ContactMode.INACTIVE
            and not self._self_managed(entry.contact)
        )

    @staticmethod
    def _ramping(entry: _TaskEntry, t: float) -> bool:
        return entry.ramp_time > 0.0 and t < entry.added_at + entry.ramp_time

    @staticmethod
    def _unload_fraction(c: _ContactEntry, t: float) -> float:
        return min_jerk((t - c.unload_start) / c.unload_time) if c.unload_time > 0 else 1.0

    def advance(
        self,
        model: RobotModel,
        layout: Layout,
        dt: float,
        t: float,
        x_prev: np.ndarray | None = None,
    ) -> None:
        """Advance the stack's state to time ``t`` (call once per step, before :meth:`build`).

        Contacts whose unloading is over are released (a blend event); an unloading contact
        records its normal force at the start of unloading (from ``x_prev``) and lowers its
        contact task's normal-force bound; contact-aware tasks learn the active contacts; a
        task added at runtime starts its goal ramp; a task ramping in records its offsets at
        ``x_prev`` (at its first step, or when its row count changed).

        Args:
            model: Robot model, updated at the current state.
            layout: Decision-variable layout (its contacts must be the declared ones).
            dt: Control period [s] (the rows of a task ramping in are evaluated).
            t: Time [s].
            x_prev: Previous solution ``(n,)`` (``None``: ramps start from zero).

        Raises:
            InvalidInput: A layout contact not declared in the stack, or rows of a task ramping
                in with the wrong number of columns.

        """
        self._check_layout(layout, "Stack.advance")
        self._update_contacts(t)
        n = layout.n
        for entry in self.advance_native(model, layout, t, x_prev):
            rows = entry.task.rows(model, layout, dt, t)
            _check_columns(rows, n, entry.task.where())
            if entry.offsets is None or not _offsets_fit(entry.offsets, rows):
                entry.offsets = _ramp_offsets(rows, x_prev)

    def _unload_bound(self, c: _ContactEntry, model: RobotModel, t: float,
                      x_prev: np.ndarray | None, start: int, n: int) -> None:
        """Lower an unloading contact's bound (its slot at ``start`` of ``n`` variables).

        Its normal force at the start (from ``x_prev``, world normal), then its owner's
        ``max_normal_force`` along the unloading profile.
        """
        if c.f_start is None:
            C = np.zeros((1, n))
            C[0, start:start + 3] = model.frame_placement(c.frame).rotation[:, 2]
            fz = float(C[0] @ x_prev) if x_prev is not None else 0.0
            c.f_start = max(fz, 0.0)
        owner = self._owner(c)
        if owner is not None:
            fmax = (1.0 - self._unload_fraction(c, t)) * c.f_start
            if c.f_max_nominal is None:
                c.f_max_nominal = float(owner.max_normal_force)  # type: ignore[attr-defined]
            f_min = float(getattr(owner, "f_min", 0.0))
            owner.max_normal_force = max(  # type: ignore[attr-defined]
                min(fmax, c.f_max_nominal), f_min
            )

    def advance_steady(self) -> None:
        """:meth:`advance` for a steady stack (:meth:`steady` true at this step's time).

        Then no contact unloads or is released, no task ramps in or waits for its goal
        ramp: advancing only tells the contact-aware tasks the active contacts (what the
        native step, which builds no Python rows, needs of it).
        """
        self._set_active_frames(self._active_frames())

    def build(self, model: RobotModel, layout: Layout, dt: float, t: float) -> BuiltStack:
        """Build the solver levels of one control step (no solve, no change of the stack).

        Building twice gives the same levels; what changes with time (ramps, contact
        switching) is advanced by :meth:`advance`. A task ramping in whose offsets were not
        recorded ramps from zero (as with ``x_prev = None``).

        Args:
            model: Robot model, updated at the current state.
            layout: Decision-variable layout (its contacts must be the declared ones).
            dt: Control period [s].
            t: Time [s].

        Returns:
            The levels and the row ranges of every task.

        Raises:
            InvalidInput: A layout contact not declared in the stack, or a task's rows with the
                wrong number of columns.

        """
        n = layout.n
        self._check_layout(layout, "Stack.build")
        per_level: list[list[tuple[str, Rows, float, float, bool]]] = [
            [] for _ in range(self.n_levels)
        ]
        self._contact_rows(model, layout, t, per_level)
        for entry in self._tasks:
            if self._dropped(entry):
                continue
            rows = entry.task.rows(model, layout, dt, t)
            _check_columns(rows, n, entry.task.where())
            s = 1.0
            if self._ramping(entry, t):
                s = min_jerk((t - entry.added_at) / entry.ramp_time)
                offsets = entry.offsets
                if offsets is None or not _offsets_fit(offsets, rows):
                    offsets = _ramp_offsets(rows, None)
                rows = _ramp(rows, s, offsets)
            per_level[entry.level].append((entry.task.name, rows, entry.task.weight, s, False))

        levels: list[Level] = []
        level_index: list[int] = []
        spans: list[TaskSpan] = []
        all_rows: dict[str, Rows] = {}
        for index, items in enumerate(per_level):
            items = [it for it in items if it[1].n_eq or it[1].n_in]
            if not items:
                continue
            built = len(levels)
            eq0 = in0 = 0
            scaled = []
            for name, rows, weight, s, internal in items:
                spans.append(TaskSpan(name, index, built, slice(eq0, eq0 + rows.n_eq),
                                      slice(in0, in0 + rows.n_in), weight, s, internal))
                eq0 += rows.n_eq
                in0 += rows.n_in
                all_rows[name] = rows
                scaled.append(rows.scaled(math.sqrt(weight)))
            stacked = scaled[0] if len(scaled) == 1 else Rows.stack(scaled, n)
            levels.append(Level(A=stacked.A, b=stacked.b, C=stacked.C, lower=stacked.lower,
                                upper=stacked.upper, name=self.level_names[index],
                                weak_threshold=self._weak[index]))
            level_index.append(index)
        return BuiltStack(levels, tuple(level_index), tuple(spans), all_rows, n)

    def _self_managed(self, name: str) -> bool:
        """Whether a contact's tasks hold its slot at zero themselves when inactive.

        Remembered until the next edit (:class:`~hqp.tasks.base.Edits`: adding or removing
        a task is one): asked at every step of a stack with a released contact.
        """
        count, known = self._managed
        if count != Edits.count:
            known = {}
            self._managed = (Edits.count, known)
        managed = known.get(name)
        if managed is None:
            managed = known[name] = self._owner(self._contacts[name]) is not None
        return managed

    def _contact_rows(
        self,
        model: RobotModel,
        layout: Layout,
        t: float,
        per_level: list[list[tuple[str, Rows, float, float, bool]]],
    ) -> None:
        """Stack-owned rows: zero slots of released contacts, unloading bounds."""
        n = layout.n
        limits = (
            self.level_categories.index(Category.CONTACT_LIMITS)
            if Category.CONTACT_LIMITS in self.level_categories
            else min(1, self.n_levels - 1)
        )
        for slot in layout.contacts:
            c = self._contacts[slot.name]
            owner = self._owner(c)
            if c.mode is ContactMode.INACTIVE and owner is None:
                A = np.zeros((slot.size, n))
                A[:, slot.slice] = np.eye(slot.size)
                per_level[0].append((f"{c.name}/released", Rows(A=A, b=np.zeros(slot.size)),
                                     1.0, 1.0, True))
            elif c.mode is ContactMode.UNLOADING and owner is None:
                normal = np.array(model.frame_placement(slot.frame).rotation[:, 2])
                C = np.zeros((1, n))
                C[0, slot.start:slot.start + 3] = normal
                s = self._unload_fraction(c, t)
                fmax = (1.0 - s) * (0.0 if c.f_start is None else c.f_start)
                per_level[limits].append(
                    (f"{c.name}/unload", Rows(C=C, lower=np.array([-np.inf]),
                                              upper=np.array([fmax])), 1.0, 1.0 - s, True)
                )


def _ramp_goal(task: Task, model: RobotModel, duration: float, t: float) -> None:
    """Start a tracking task's goal at its current value, min-jerk to its goal over ``duration``.

    Applies to tasks with a fixed goal and ``move_to(state, goal, duration, t0)`` (the tracking
    primitives of :mod:`hqp.tasks`); a task following its own trajectory is left alone.
    """
    move_to = getattr(task, "move_to", None)
    goal_at = getattr(task, "goal_at", None)
    if move_to is None or goal_at is None or getattr(task, "trajectory", None) is not None:
        return
    try:
        goal = goal_at(t).position
    except HQPError:
        return  # no goal set: nothing to ramp
    if isinstance(task, TrackingTask):
        duration = max(duration, _saturation_time(task, model, t))
    move_to(model, goal, duration, t)


def _saturation_time(task: TrackingTask, model: RobotModel, t: float) -> float:
    """Shortest minimum-jerk duration [s] from the task's value to its goal within its PD law.

    A goal ramp's feed-forward is not limited by the task's PD law (seed 003 eq. 27-28 saturates
    the feedback only), so a far goal ramped over a short ``ramp_time`` would ask for more than
    the task itself would. The ramp is lengthened so that its peak velocity ``1.875 d / T`` and
    peak acceleration ``5.77 d / T^2`` stay within what the PD law asks for the same error ``d``
    (the norm of the task's error; a pose task's translation and rotation separately): the
    corrective velocity ``min(max_velocity, kp d / kv)`` and the feedback acceleration
    ``min(max_acceleration, kp d)``.
    """
    try:
        error = task.kinematics(model, t).error
    except HQPError:
        return 0.0
    parts = [(error, task.reference)]
    angular = getattr(task, "angular_reference", None)  # pose tasks: the rotation's own law
    if angular is not None and error.size == 6:
        parts = [(error[:3], task.reference), (error[3:], angular)]
    duration = 0.0
    for part, ref in parts:
        d = float(np.linalg.norm(part))
        if d == 0.0:
            continue
        vmax = min(ref.max_velocity, ref.kp * d / ref.kv if ref.kv > 0.0 else math.inf)
        amax = min(ref.max_acceleration, ref.kp * d)
        if math.isfinite(vmax) and vmax > 0.0:
            duration = max(duration, MIN_JERK_PEAK_VELOCITY * d / vmax)
        if math.isfinite(amax) and amax > 0.0:
            duration = max(duration, math.sqrt(MIN_JERK_PEAK_ACCELERATION * d / amax))
    return duration


def _check_columns(rows: Rows, n: int, where: str) -> None:
    for label, M in (("A", rows.A), ("C", rows.C)):
        if M is not None and (M.ndim != 2 or M.shape[1] != n):
            raise InvalidInput(f"{where}: rows {label} has shape {M.shape}, expected (*, {n})")


Offsets = tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]


def _ramp_offsets(rows: Rows, x_prev: np.ndarray | None) -> Offsets:
    """Offsets ``(d_eq, d_lower, d_upper)`` of a task's rows at ``x_prev`` (zeros if ``None``).

    ``d_eq = A x_prev - b``; ``d_lower = min(0, C x_prev - lower)`` and
    ``d_upper = max(0, C x_prev - upper)`` on finite bounds (0 elsewhere).
    """
    n = rows.A.shape[1] if rows.A is not None else rows.C.shape[1]  # type: ignore[union-attr]
    x = np.zeros(n) if x_prev is None else x_prev
    d_eq = None if rows.A is None or rows.b is None else rows.A @ x - rows.b
    d_lo = d_up = None
    if rows.C is not None:
        cx = rows.C @ x
        if rows.lower is not None:
            d_lo = np.where(np.isfinite(rows.lower), np.minimum(cx - rows.lower, 0.0), 0.0)
        if rows.upper is not None:
            d_up = np.where(np.isfinite(rows.upper), np.maximum(cx - rows.upper, 0.0), 0.0)
    return d_eq, d_lo, d_up


def _offsets_fit(offsets: Offsets, rows: Rows) -> bool:
    """Whether recorded offsets still match the task's row counts (tasks may change them).

    An offset for a part the rows lack (e.g. a lower-bound offset the native step recorded
    for a one-sided Python row) is not used and does not matter.
    """
    return all(part is None or (d is not None and d.shape == part.shape)
               for d, part in zip(offsets, (rows.b, rows.lower, rows.upper)))


def _ramp(rows: Rows, s: float, offsets: Offsets) -> Rows:
    """Rows of a task ramping in: ``b + (1 - s) d_eq``, bounds widened by ``(1 - s)`` offsets."""
    d_eq, d_lo, d_up = offsets
    b, lower, upper = rows.b, rows.lower, rows.upper
    if b is not None and d_eq is not None:
        b = b + (1.0 - s) * d_eq
    if lower is not None and d_lo is not None:
        lower = lower + (1.0 - s) * d_lo
    if upper is not None and d_up is not None:
        upper = upper + (1.0 - s) * d_up
    return Rows(rows.A, b, rows.C, lower, upper)
