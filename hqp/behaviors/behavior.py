"""Behaviors: state machines over action primitives (the seed's whole-body behaviors).

A :class:`Behavior` drives a controller (:class:`hqp.controller.Controller`,
HQP or null-space alike). Each control step, after the controller has
computed its command at the measured state, :meth:`Behavior.update`

1. reads the sensed state: simulated time, sensed contacts, centre of
   gravity, frame positions, joint positions, task errors, and the servo's
   feasibility flags (seed 001: "the servo module sends a flag to the active
   behavior indicating infeasibility of the movement");
2. enters the phase's safety phase when a watched task is flagged in conflict
   with a higher level (the seed's infeasibility flag, Figure 13), else fires the
   first transition whose condition holds;
3. on a phase change, writes the new active task set (the seed's "active task
   set" register): tasks that stay keep running untouched, new tasks are ramped
   in from zero effect by the stack, removed tasks are blended out, released
   contacts are first unloaded, so the motion does not jerk;
4. evaluates the goals of the active tasks (constants, runtime inputs,
   planner outputs, or expressions of the sensed state) and sets them.

Transitions read simulated time (``t``, ``phase_time``), never the wall clock.
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from hqp.behaviors.expressions import ExpressionError, Namespace
from hqp.behaviors.factory import TaskFactory
from hqp.behaviors.inputs import InputStream
from hqp.behaviors.spec import BehaviorSpec, PhaseSpec
from hqp.control.native import error_norms
from hqp.errors import BehaviorFileError

if TYPE_CHECKING:
    from hqp.controller import Command, Controller, FeasibilityReport, TaskStatus
    from hqp.model import RobotState

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class FeasibilityEvent:
    """A change of a task's feasibility flag, or a safety transition.

    Attributes:
        t: Simulated time [s].
        phase: Active phase.
        task: Task name.
        status: The words of the feasibility report (docs/concepts/report.md): ``"conflict"``
            (flagged: in conflict with level ``yields_to``, or with a higher level when the
            controller does not say which), ``"infeasible"`` (the task's own rows cannot
            hold, whatever the levels above do: only with ``diagnostics="full"``),
            ``"satisfied"`` (the flag cleared), or ``"safety"`` (the behavior entered its
            safety phase because of this task).
        level: The task's level.
        yields_to: The higher level it yields to (``None`` when not in conflict).
        residual: Norm of its residual [task units / s^2].

    """

    t: float
    phase: str
    task: str
    status: str
    level: int
    yields_to: int | None
    residual: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "t": round(self.t, 4), "phase": self.phase, "task": self.task, "status": self.status,
            "level": self.level, "yields_to": self.yields_to, "residual": float(self.residual),
        }


class Behavior:
    """A running behavior: the state machine of a :class:`BehaviorSpec` on a controller.

    Args:
        spec: The behavior description.
        controller: The controller whose active task set the behavior writes.
        factory: Builds the tasks of the spec for the controller's robot.
        inputs: Runtime inputs (default: the spec's defaults).
        planner: Trajectory generator providing ``plan.*`` through ``output(name, t)`` and
            ``output_names`` (required when the spec declares one; see
            :mod:`hqp.behaviors.planners`).
        standing: Standing configuration ``(nq,)`` (``standing`` in goal expressions).
        robot_values: The robot's dimensions (``robot.<name>`` in expressions:
            :meth:`hqp.robots.Robot.dimensions`).
        safety_steps: Consecutive control steps a task's raw flag must hold before its
            feasibility flag changes (filters single-step flags).
        infeasible_residual: Residual below which a conflict is not flagged [task units /
            s^2]. A task is flagged when it is in conflict with a higher level (or, when
            the controller does not say which level it yields to, in conflict) with a
            residual above this.

    Attributes:
        Phase: The :class:`enum.Enum` of the phases.
        phase: The active phase (a member of ``Phase``).
        visited: Phases entered, in order (with repetitions).
        events: Feasibility events and safety transitions.

    """

    def __init__(
        self,
        spec: BehaviorSpec,
        controller: Controller,
        factory: TaskFactory,
        *,
        inputs: InputStream | None = None,
        planner: Any = None,
        standing: np.ndarray | None = None,
        robot_values: Mapping[str, Any] | None = None,
        safety_steps: int = 5,
        infeasible_residual: float = 1e-3,
    ) -> None:
        if spec.planner is not None and planner is None:
            raise BehaviorFileError(f"{spec.path}: behavior {spec.name!r} needs a planner "
                                    f"of type {spec.planner.type!r}")
        self.spec = spec
        self.controller = controller
        self._default_blend_time = float(controller.stack.blend_time)
        self.factory = factory
        self.inputs = inputs if inputs is not None else InputStream(spec.inputs)
        self.planner = planner
        self.standing = standing
        self.robot_values = dict(robot_values or {})
        self.safety_steps = int(safety_steps)
        self.infeasible_residual = float(infeasible_residual)
        self.Phase: type[enum.Enum] = spec.phase_enum()
        self.tasks = {name: factory.build(ts) for name, ts in spec.tasks.items()}
        self.phase: enum.Enum = self.Phase(spec.initial)
        self.visited: list[str] = []
        self.events: list[FeasibilityEvent] = []
        self.phase_start = 0.0
        self.t0 = 0.0
        self.com0 = np.zeros(3)
        self.feet_center = np.zeros(3)
        self._initial: dict[str, Any] = {}
        self._goals_set: dict[str, dict[str, Any]] = {}
        # a pose reads the standing configuration, or the current one without it
        self._fixed_names = _FIXED_IN_PHASE if standing is not None else (
            _FIXED_IN_PHASE - {"pose"})
        self._goals_fixed: set[str] = set()
        """Tasks of this phase whose goals read only what a phase holds fixed, already set."""
        self._goal_plans: dict[str, list[tuple[Any, dict[str, Any], bool]]] = {}
        self._levels: dict[str, int] = {}
        self._flags: dict[str, bool] = {}
        self._bad_steps: dict[str, int] = {}
        self._flagging = False
        """A flag is set or counting towards a change (else a report without conflict
        changes nothing)."""
        self._started = False
        self._errors: dict[str, dict[str, dict[str, float]]] = {}
        self._record: _ErrorRecord | None = None
        self._entered: list[tuple[str, float]] = []
        self._makers: dict[str, Callable[[], Any]] | None = None
        self._env_state: RobotState | None = None
        self._env_t = 0.0

    # -- public -----------------------------------------------------------------------------

    @property
    def phase_spec(self) -> PhaseSpec:
        """Description of the active phase."""
        return self.spec.phases[self.phase.value]

    def metrics(self) -> dict[str, Any]:
        """Per phase: when it was entered, and each task's smallest and last error norm.

        Errors are in task units (m for positions, rad for orientations, ...), measured at
        the control steps of the phase (``error()`` of the task after its rows were built).
        """
        if self._record is not None:
            self._record.flush()
        return {
            "phase_times": [{"phase": p, "t": round(t, 4)} for p, t in self._entered],
            "task_errors": {
                p: {k: {m: round(v, 5) for m, v in d.items()} for k, d in tasks.items()}
                for p, tasks in self._errors.items()
            },
        }

    def task_errors(self) -> dict[str, float]:
        """Error norm of each active task at its last rows (task units: m, rad, ...)."""
        errors = {name: self._error(name) for name in self._levels}
        return {name: e for name, e in errors.items() if np.isfinite(e)}

    def start(self, state: RobotState, t: float) -> None:
        """Enter the initial phase at time ``t`` [s] (the controller's model is updated here)."""
        model = self.controller.model
        model.update(state.q, state.v)
        self.t0 = float(t)
        self.com0 = model.com.copy()
        self.feet_center = self.factory.feet_center(model)
        if self.planner is not None:
            self.planner.start(model, t)
        self._started = True
        self._enter(self.spec.initial, state, t)
        self._set_goals(state, t)

    def update(self, state: RobotState, t: float, report: FeasibilityReport | None) -> None:
        """One step of the state machine, after the controller's step at ``state``.

        Args:
            state: Measured state of this step (its ``contacts`` are the sensed contacts).
            t: Simulated time [s].
            report: The controller's feasibility report of this step.

        """
        if not self._started:
            self.start(state, t)
            return
        record = self._record
        if record is None:  # the first step of this phase
            record = self._record = _ErrorRecord(
                self._errors.setdefault(self.phase.value, {}), list(self._levels),
                [self.tasks[n] for n in self._levels])
        record.add(error_norms(record.tasks))
        safety_task = self._feasibility(report, t)
        phase = self.phase_spec
        target = None
        env: _LazyEnv | None = None
        if safety_task is not None and phase.safety is not None:
            status = report[safety_task] if report is not None else None
            self.events.append(FeasibilityEvent(
                t, phase.name, safety_task, "safety", self._levels.get(safety_task, -1),
                None if status is None else status.yields_to,
                0.0 if status is None else status.residual))
            target = phase.safety
        else:
            env = self._env(state, t)
            for tr in phase.transitions:
                try:
                    fire = bool(tr.when.evaluate(env))
                except ExpressionError as exc:
                    raise BehaviorFileError(
                        f"{self.spec.path}: phases.{phase.name}.transitions: {exc}") from None
                if fire:
                    target = tr.to
                    break
        if target is not None:
            self._enter(target, state, t)
            env = None  # the phase and its phase_time changed
        self._set_goals(state, t, env)

    def step(self, state: RobotState, t: float) -> Command:
        """One control step: the controller's command at ``state``, then :meth:`update`.

        A behavior is driven like a controller (e.g. by :func:`hqp.sim.closed_loop`).
        """
        command = self.controller.step(state, t)
        self.update(state, t, command.report)
        return command

    # -- internals --------------------------------------------------------------------------

    def _feasibility(self, report: FeasibilityReport | None, t: float) -> str | None:
        """Update the infeasibility flags; return a watched task that calls for safety."""
        if report is None:
            return None
        if not self._flagging and not report.any_conflict:
            return None  # no flag set or changing, and none starts to: nothing to update
        phase = self.phase_spec
        trigger = None
        conflicts = {s.name: s for s in report.conflicts()}  # (only these statuses made)
        for name in report.names:
            if name not in self.tasks:
                continue
            status = conflicts.get(name)
            raw = (
                status is not None
                and (status.yields_to is None or status.yields_to < status.level)
                and status.residual > self.infeasible_residual
            )
            # debounce: a flag changes after ``safety_steps`` consecutive steps
            count = self._bad_steps.get(name, 0)
            count = count + 1 if raw != self._flags.get(name, False) else 0
            self._bad_steps[name] = count
            if count >= self.safety_steps:
                bad = raw
                self._flags[name] = bad
                self._bad_steps[name] = 0
                if status is None:
                    status = report[name]
                self.events.append(FeasibilityEvent(
                    t, phase.name, name, self._word(status) if bad else "satisfied",
                    status.level, status.yields_to, status.residual))
            if name in phase.watch and trigger is None and self._flags.get(name, False):
                trigger = name
        self._flagging = any(self._flags.values()) or any(self._bad_steps.values())
        return trigger

    def _word(self, status: TaskStatus) -> str:
        """Event word of a flagged task: ``"infeasible"`` only where its own rows cannot hold."""
        full = getattr(self.controller, "diagnostics", None) == "full"
        return "infeasible" if full and status.yields_to is None else "conflict"

    def _enter(self, name: str, state: RobotState, t: float) -> None:
        """Write the active task set and contacts of phase ``name``."""
        ctrl = self.controller
        new = self.spec.phases[name]
        if self._record is not None:  # the errors of the phase left
            self._record.flush()
            self._record = None
        ramp = new.ramp_time if new.ramp_time is not None else self.spec.ramp_time
        # contacts: make the new ones, unload the released ones
        active = set(ctrl.active_contacts)
        for c in new.contacts:
            if c not in active:
                ctrl.activate_contact(c, t=t)
        ctrl.stack.blend_time = (new.blend_time if new.blend_time is not None
                                 else self._default_blend_time)
        for task in ctrl.stack.tasks:
            if hasattr(task, "set_airborne_braking"):
                task.set_airborne_braking(new.joint_braking == "airborne")
        unload = new.unload_time if new.unload_time is not None else self.spec.unload_time
        for c in sorted(active - set(new.contacts)):
            ctrl.deactivate_contact(c, t=t, unload_time=unload)
        # tasks: keep, move, remove, add
        wanted = {ts.name: ts for ts in new.action.tasks}
        for tname in list(self._levels):
            if tname not in wanted:
                ctrl.remove_task(tname, t=t)
                del self._levels[tname]
        for tname, ts in wanted.items():
            level = ctrl.stack.level_of(ts.level, self.tasks[tname])
            if tname in self._levels:
                if self._levels[tname] != level:
                    ctrl.stack.move(tname, level, t=t)
                    self._levels[tname] = level
            else:
                ctrl.add_task(self.tasks[tname], level, t=t, ramp_time=ramp)
                self._levels[tname] = level
        # goals' ``initial``: each task's value when the phase begins
        model = ctrl.model
        self._initial = {tname: self.factory.current(self.tasks[tname], self.spec.tasks[tname],
                                                      model) for tname in wanted}
        self._goals_fixed = set()
        self.phase = self.Phase(name)
        self.phase_start = float(t)
        self.visited.append(name)
        self._entered.append((name, float(t) - self.t0))
        logger.info("t=%.3f s: phase %s", t, name)

    def _env(self, state: RobotState, t: float) -> _LazyEnv:
        """Return this step's expression environment (each name computed when first read).

        The functions that compute the names are made once; they read the step's state and
        time from the behavior, so the environment of a step is one empty dictionary.
        """
        self._env_state, self._env_t = state, t
        makers = self._makers
        if makers is None:
            makers = self._makers = self._env_makers()
        return _LazyEnv(makers)

    def _env_makers(self) -> dict[str, Callable[[], Any]]:
        """Return each name of the expression environment and the function computing it."""
        model = self.controller.model
        factory = self.factory

        def contact_flags() -> dict[str, bool]:
            state = self._env_state
            sensed = (state.contacts if state is not None else None) or {}
            return {c: bool(sensed.get(c, False)) for c in factory.contact_names}

        makers: dict[str, Callable[[], Any]] = {
            "t": lambda: float(self._env_t) - self.t0,
            "phase_time": lambda: float(self._env_t) - self.phase_start,
            "com": lambda: model.com.copy(),
            "com_velocity": lambda: model.com_velocity.copy(),
            "com0": lambda: self.com0,
            "feet_center": lambda: self.feet_center,
            "contact": lambda: Namespace(contact_flags(), "contact"),
            "contacts": lambda: sum(contact_flags().values()),
            "error": lambda: _LazyNamespace(lambda n: self._error(n), self.tasks, "error"),
            "infeasible": lambda: Namespace({n: self._flags.get(n, False) for n in self.tasks},
                                            "infeasible"),
            "conflict": lambda: Namespace({n: self._flags.get(n, False) for n in self.tasks},
                                          "conflict"),
            "joint": lambda: _LazyNamespace(lambda n: factory.joint(model, n),
                                            factory.joint_names, "joint"),
            "joint_margin": lambda: _LazyNamespace(lambda n: factory.joint_margin(model, n),
                                                   factory.joint_names, "joint_margin"),
            "input": lambda: self._input(float(self._env_t)),
            "frame": lambda: _LazyNamespace(lambda n: factory.frame_position(model, n),
                                            model.frame_names, "frame"),
            "plan": lambda: self._plan(self._env_t),
            "pose": lambda: _LazyNamespace(self.pose, self.spec.poses, "pose"),
            "robot": lambda: Namespace(self.robot_values, "robot"),
        }
        if self.standing is not None:
            standing = self.standing
            makers["standing"] = lambda: standing
        return makers

    def _input(self, t: float) -> Namespace:
        """Return the runtime inputs at time ``t`` [s] (each read when first used)."""
        return _LazyNamespace(lambda n: self.inputs.value(n, t - self.t0), self.spec.inputs,
                              "input")

    def _plan(self, t: float) -> Namespace:
        """Return the planner's values at ``t`` (each computed when first read, if it can)."""
        planner = self.planner
        if planner is None:
            return Namespace({}, "plan")
        return _LazyNamespace(lambda n: planner.output(n, t), planner.output_names, "plan")

    def pose(self, name: str) -> np.ndarray:
        """Return the configuration ``(nq,)``: the standing one with the captured pose's joints."""
        model = self.controller.model
        q = (self.standing if self.standing is not None else model.q).copy()
        for joint, value in self.spec.poses[name].items():
            q[model.actuated_q.start + model.joint_index(joint)] = value
        return q

    def _error(self, name: str) -> float:
        """Norm of a task's error at its last rows (``inf`` before its rows were built)."""
        return float(error_norms([self.tasks[name]])[0])

    def _phase_goals(self, phase: PhaseSpec) -> list[tuple[Any, dict[str, Any], bool]]:
        """Return each task of a phase that has goals, made once per phase.

        Its spec, its goals (the task's, then the phase's) and whether they read only what
        the phase holds fixed.
        """
        plan = self._goal_plans.get(phase.name)
        if plan is None:
            plan = []
            for ts in phase.action.tasks:
                goals = dict(ts.goals)
                goals.update(phase.goals.get(ts.name, {}))
                if goals:
                    plan.append((ts, goals, all(expr.names <= self._fixed_names
                                                for expr in goals.values())))
            self._goal_plans[phase.name] = plan
        return plan

    def _set_goals(self, state: RobotState, t: float,
                   base_env: _LazyEnv | None = None) -> None:
        """Evaluate and set the phase's goals.

        ``base_env``: this step's expression environment if the caller built it in this
        phase (built here otherwise).
        """
        phase = self.phase_spec
        fixed = self._goals_fixed
        for ts, goals, fixed_only in self._phase_goals(phase):
            if ts.name in fixed:
                continue  # its goals read nothing that changed since the phase began
            if base_env is None:
                base_env = self._env(state, t)
            env = base_env.with_value("initial", self._initial.get(ts.name))
            values: dict[str, Any] = {}
            for gname, expr in goals.items():
                try:
                    values[gname] = expr.evaluate(env)
                except ExpressionError as exc:
                    raise BehaviorFileError(
                        f"{self.spec.path}: phase {phase.name!r}, task {ts.name!r}, "
                        f"{gname}: {exc}") from None
            if fixed_only:
                fixed.add(ts.name)
            if _same_values(values, self._goals_set.get(ts.name)):
                # unchanged: setting it again would replace the trajectory of a task that is
                # ramping in (its goal starts at its current value, see hqp.stack) by a step
                continue
            self.factory.set_goals(self.tasks[ts.name], ts, values)
            # copies: a value may be an array its producer updates in place
            self._goals_set[ts.name] = {k: np.array(v, copy=True) if isinstance(v, np.ndarray)
                                        else v for k, v in values.items()}


class _ErrorRecord:
    """Smallest and last finite error norm of each task over the steps of one phase.

    Kept in arrays over the phase's tasks and merged into the phase's record (task name ->
    ``{"min", "final"}``, a task entered when its error is first finite, as a step-by-step
    record would enter it) by :meth:`flush`.

    Args:
        record: The phase's record, merged into.
        names: The phase's task names ...
        tasks: ... and tasks.

    """

    def __init__(self, record: dict[str, dict[str, float]], names: list[str],
                 tasks: list[Any]) -> None:
        self.record, self.names, self.tasks = record, names, tasks
        n = len(names)
        self.mins = np.full(n, np.inf)
        self.finals = np.full(n, np.nan)
        self.seen = np.zeros(n, dtype=bool)
        self.first = np.zeros(n, dtype=np.int64)  # step at which each was first finite
        self.all_seen = n == 0
        self.k = 0

    def add(self, norms: np.ndarray) -> None:
        """Add one step's error norms ``(n,)`` (``inf`` or ``nan``: not recorded)."""
        finite = np.isfinite(norms)
        np.fmin(self.mins, np.where(finite, norms, np.inf), out=self.mins)
        np.copyto(self.finals, norms, where=finite)
        if not self.all_seen:
            new = finite & ~self.seen
            if new.any():
                self.first[new] = self.k
                self.seen |= new
                self.all_seen = bool(self.seen.all())
        self.k += 1

    def flush(self) -> None:
        """Merge the steps added so far into the record, and start again."""
        index = np.flatnonzero(self.seen).tolist()
        first = self.first.tolist()
        mins, finals = self.mins.tolist(), self.finals.tolist()
        for i in sorted(index, key=lambda i: (first[i], i)):
            d = self.record.get(self.names[i])
            if d is None:
                self.record[self.names[i]] = {"min": mins[i], "final": finals[i]}
            else:
                d["min"] = min(d["min"], mins[i])
                d["final"] = finals[i]
        self.mins.fill(np.inf)
        self.seen.fill(False)
        self.all_seen = not self.names
        self.k = 0


_FIXED_IN_PHASE = frozenset({"com0", "feet_center", "standing", "pose", "initial", "robot"})
"""Names of the expression environment whose values do not change within a phase."""


def _same_values(values: dict[str, Any], previous: dict[str, Any] | None) -> bool:
    """Whether two goal dictionaries hold the same names and equal values."""
    if previous is None or values.keys() != previous.keys():
        return False
    for name, value in values.items():
        old = previous[name]
        if isinstance(value, np.ndarray) and isinstance(old, np.ndarray):  # the common case
            if value.shape != old.shape or not (value == old).all():
                return False
            continue
        try:
            if not np.array_equal(np.asarray(value, dtype=float), np.asarray(old, dtype=float)):
                return False
        except (TypeError, ValueError):
            if value != old:
                return False
    return True


class _LazyEnv(Mapping[str, Any]):
    """An expression environment whose values are computed on first read, then kept.

    Args:
        makers: Each name and the function that computes its value.

    """

    def __init__(self, makers: dict[str, Callable[[], Any]]) -> None:
        self._makers = makers
        self._values: dict[str, Any] = {}

    def __getitem__(self, name: str) -> Any:
        try:
            return self._values[name]
        except KeyError:
            value = self._makers[name]()  # an unknown name: KeyError, as a dict
            self._values[name] = value
            return value

    def __iter__(self) -> Iterator[str]:
        return iter(self._makers)

    def __len__(self) -> int:
        return len(self._makers)

    def with_value(self, name: str, value: Any) -> _WithValue:
        """Return the environment (its computed values shared) with ``name`` set to ``value``."""
        return _WithValue(self, name, value)


class _WithValue(Mapping[str, Any]):
    """An environment with one more name (or one name replaced)."""

    __slots__ = ("_env", "_name", "_value")

    def __init__(self, env: Mapping[str, Any], name: str, value: Any) -> None:
        self._env, self._name, self._value = env, name, value

    def __getitem__(self, name: str) -> Any:
        if name == self._name:
            return self._value
        return self._env[name]

    def __iter__(self) -> Iterator[str]:
        return iter({self._name: None, **dict.fromkeys(self._env)})

    def __len__(self) -> int:
        return len({self._name, *self._env})


class _LazyNamespace(Namespace):
    """A :class:`Namespace` whose values are computed on first use."""

    def __init__(self, getter: Any, names: Any, kind: str) -> None:
        super().__init__({}, kind)
        self._getter = getter
        self._known = set(names)
        self._cache: dict[str, Any] = {}

    def get(self, name: str) -> Any:
        if name not in self._known:
            raise ExpressionError(f"unknown name {self._kind}.{name}; known: "
                                  f"{', '.join(sorted(self._known))}")
        if name not in self._cache:
            self._cache[name] = self._getter(name)
        return self._cache[name]

    def names(self) -> list[str]:
        return sorted(self._known)

