"""The execution layer (the seed's servo): robot state -> levels -> resolver -> torques.

One control step of :class:`WholeBodyController`:

1. ``model.update(q, v)``, once, shared by every task;
2. ``Stack.advance`` (ramps, contact switching), then ``Stack.build``: the rows of every task
   stacked into levels, apart from the solve;
3. the resolver: one solve of the strict hierarchy (:class:`~hqp.control.resolver.HQPResolver`)
   or the papers' null-space law (:class:`~hqp.control.nullspace.NullSpaceResolver`), giving
   ``x = [qdd | f_1 | ... | f_k]`` and the torques of ``M qdd + h = S^T tau + J_c^T f``;
4. torque blending after changes that cannot be ramped, the torque-limit check;
5. a :class:`~hqp.control.command.FeasibilityReport` (:mod:`hqp.control.diagnostics`).

The torque-rate level (HQP only: ``max_torque_rate``; off in this class by default, on at
:data:`MAX_TORQUE_RATE` in every preset, :mod:`hqp.control.presets`):
after the physics and the contact and torque limits the servo adds one level of its own,
``|tau - tau_prev| <= max_torque_rate * dt`` over the actuated joints (``tau_prev``: the
hierarchy's torques of the previous step), reported as the task ``torque_rate``: an actuator
limit, above the joint limits, the collision distances and the tasks. A level below in
conflict (a joint-limit level that the contact limits do not let brake in time, a
centre-of-mass goal faster than the support allows, an unreachable hand) then cannot turn the
switches of its active set (acceleration bounds entering and leaving) into torque steps: every
such switch is spread over several steps; the physics and the contact and torque limits above
still win over it.

The controller never returns NaN torques: if the resolver fails, it sends a defined safe
command (gravity and contact-force compensation with joint damping on the current contacts)
and says so in the report (``Command.safe_mode``).
"""

from __future__ import annotations

import abc
import dataclasses
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from hqp.control.command import Command, FeasibilityReport
from hqp.control.diagnostics import MODES, Diagnostics
from hqp.control.native import RATE_TASK, NativeEngine, NativeStepMirror
from hqp.control.resolver import HQPResolver, Resolver
from hqp.errors import InvalidInput
from hqp.model.layout import Layout
from hqp.solver import Level
from hqp.stack import BlendEvent, BuiltStack, Stack, TaskSpan
from hqp.tasks.base import Category, Rows
from hqp.tasks.dynamics import joint_torques, torque_map
from hqp.tasks.reference import min_jerk

QUATERNION_TOLERANCE = 1e-3
"""Largest deviation of the base quaternion's norm from 1 that a step normalises; beyond it
the state is refused."""

if TYPE_CHECKING:
    from hqp.model import RobotModel, RobotState
    from hqp.solver import HierarchicalSolver, Solution
    from hqp.tasks.base import Task

WORK_BUDGET = 0
"""Default work budget of the native step's solve (``WholeBodyController(work_budget=...)``),
in the level QPs' work units (a DAQP iteration 1, a primal active-set iteration 25); 0: none.
Where a step's solve spends a budget, the levels already solved stay exact, each level whose QP
it cuts keeps the best feasible point reached, and the report's notes say which levels were
cut. Off by default: the budgets measured so far either leave the worst steps at several
milliseconds or change the closed loops of the library (docs/concepts/engine.md, "The work
budget")."""

MAX_TORQUE_RATE = 4000.0
"""Measured choice of the bound on the rate of the hierarchy's torques [N m/s]: 4 N m per 1 ms
step, under the 5 N m per step the closed-loop conflict tests hold (a torque an actuator with
a few ms of torque rise time follows)."""

RATE_AFTER = (Category.PHYSICS, Category.CONTACT_LIMITS)
"""The constraint sub-levels the torque-rate level is placed after: the actuator's torque-rate
bound sits with its torque limits, above the joint limits and the collision distances (a
joint-limit level in conflict below it cannot turn into a torque step; docs/design/control.md)."""


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


class WholeBodyController(Controller):
    """Whole-body torque controller: the servo around a resolver (HQP by default).

    Args:
        robot_model: The controller's robot model (pinocchio).
        contacts: Contacts to declare in the stack (``hqp.tasks.contact.Contact`` tasks, their
            physics rows at the PHYSICS level and their limits at CONTACT_LIMITS); contacts
            already declared in ``stack`` need not be repeated.
        stack: The levels of tasks (default: an empty :class:`~hqp.stack.Stack` with the
            default levels).
        dt: Control period [s].
        backend: QP backend of the Python step's solver (``"proxsuite"``, ``"osqp"``,
            ``"daqp"``, ``"quadprog"``, ``"native"``); ``None``: the native step where it
            applies (``native``) and the native solver for the other steps, or
            ``"proxsuite"`` without the native step.
        algorithm: Hierarchical algorithm (``"basis"`` or ``"cascade"``).
        final_metric: Metric ``(n, n)`` of the final tie-break (``None``: identity, i.e. the
            minimum-norm optimum).
        final_target: Target ``(n,)`` of the final tie-break (``None``: zero).
        tolerance: A task whose unweighted residual norm exceeds this is in conflict.
        singular_tolerance: A satisfied task whose projected smallest singular value is below
            this is reported singular.
        diagnostics: ``"full"``: per-task projected singular values and the level each
            conflicting task yields to (a few small SVDs per step); ``"residuals"``: per-task
            residuals only, the level's ``sigma_min`` from the solver, no ``yields_to``.
        damping: Joint damping of the safe command [N m s/rad].
        resolver: What solves the built levels (default: an :class:`HQPResolver` of
            ``backend``, ``algorithm``, ``final_metric``, ``final_target``).
        native: Run steady steps on the native step (``hqp.control.native``: one call into
            the C++ core for the model pass, the rows, the solve and the torques; the
            Python step runs the steps it does not: ramps, contact unloading, blends,
            tasks without a kernel, a final metric). ``None`` (default): when the model
            comes from a bundled robot, the resolver is the default HQP one with the basis
            algorithm and ``backend`` is ``None`` or ``"native"``; an explicit other backend
            means the Python step on that backend.
        max_torque_rate: Bound on the rate of the hierarchy's torques [N m/s], a scalar or
            ``(na,)`` (module docstring; HQP resolvers only; :data:`MAX_TORQUE_RATE` is the
            measured choice); ``None`` (default): no torque-rate level. The native step
            mirrors it (a torque-rate kernel at a level of its own).
        work_budget: Work budget of the native step's solve, in the level QPs' work units
            (:data:`WORK_BUDGET`); ``None`` or 0: unbounded. It bounds the worst step: where
            it is spent, the levels already solved stay exact and the level whose QP it cuts
            keeps the best feasible point reached (the report's notes name it).

    Raises:
        InvalidInput: Bad period, tolerance or diagnostics mode; a contact frame not in the
            model.
        UnknownBackend: Unknown backend.

    """

    def __init__(
        self,
        robot_model: RobotModel,
        contacts: Sequence[Task] = (),
        stack: Stack | None = None,
        dt: float = 0.001,
        backend: str | None = None,
        algorithm: str = "basis",
        *,
        final_metric: np.ndarray | None = None,
        final_target: np.ndarray | None = None,
        tolerance: float = 1e-5,
        singular_tolerance: float = 1e-4,
        diagnostics: str = "full",
        damping: float = 2.0,
        resolver: Resolver | None = None,
        native: bool | None = None,
        max_torque_rate: float | np.ndarray | None = None,
        work_budget: int | None = WORK_BUDGET,
    ) -> None:
        if not np.isfinite(dt) or dt <= 0.0:
            raise InvalidInput(f"WholeBodyController: dt must be positive, got {dt}")
        if diagnostics not in MODES:
            raise InvalidInput(
                "WholeBodyController: diagnostics must be 'full' or 'residuals', "
                f"got {diagnostics!r}"
            )
        for label, value in (("tolerance", tolerance), ("singular_tolerance", singular_tolerance),
                             ("damping", damping)):
            if not np.isfinite(value) or value < 0.0:
                raise InvalidInput(f"WholeBodyController: {label} must be >= 0, got {value}")
        self.model = robot_model
        self.stack = Stack() if stack is None else stack
        for contact in contacts:
            if contact.name not in self.stack.contacts:
                self.stack.add_contact(contact)
        for name, frame, _ in self.stack.layout_contacts():
            robot_model.frame_id(frame, f"WholeBodyController: contact {name!r}")
        self.layout = Layout.build(robot_model.nv, self.stack.layout_contacts())
        self.dt = float(dt)
        if native is None:
            native = (resolver is None and algorithm == "basis"
                      and backend in (None, "native") and robot_model.source is not None)
        if native and robot_model.source is None:
            raise InvalidInput("WholeBodyController: native=True needs a model built by "
                               "Robot.model() (the native step loads the robot's URDF)")
        self.native: NativeEngine | None = (
            NativeEngine(robot_model.source) if native else None)
        if backend is None:  # the steps the native step leaves run on the same solver
            backend = "native" if native else "proxsuite"
        self.resolver: Resolver = resolver if resolver is not None else HQPResolver(
            backend, algorithm, final_metric=final_metric, final_target=final_target)
        self.feasibility = Diagnostics(tolerance, singular_tolerance, diagnostics)
        self.diagnostics = diagnostics
        self.damping = float(damping)
        if work_budget is not None and (int(work_budget) != work_budget or work_budget < 0):
            raise InvalidInput(f"WholeBodyController: work_budget must be a whole number >= 0 "
                               f"or None, got {work_budget}")
        self.work_budget = None if not work_budget else int(work_budget)
        self.max_torque_rate: np.ndarray | None = None
        if max_torque_rate is not None:
            rate = np.broadcast_to(np.asarray(max_torque_rate, dtype=float), (robot_model.na,))
            if not np.all(rate > 0.0):
                raise InvalidInput(f"WholeBodyController: max_torque_rate must be > 0, got "
                                   f"{max_torque_rate}")
            self.max_torque_rate = rate.copy()
        self._rate_after = max((k for k, c in enumerate(self.stack.level_categories)
                                if c in RATE_AFTER), default=-1)
        self._rate_ref: np.ndarray | None = None  # the hierarchy's torques of the last step
        self.last_t = 0.0
        self.last_x: np.ndarray | None = None
        self.last_tau: np.ndarray | None = None
        self._last_built: BuiltStack | None = None
        self._native_levels: NativeStepMirror | None = None  # last step native: built on demand
        self._native_failure: str | None = None  # why this step's native solve failed
        self._slots: tuple[Any, list[tuple[str, int, int]]] | None = None  # _split's
        self.step_serial = 0
        """Steps made so far (a native step's task errors are fetched while it is the last)."""
        self._blend_start: float | None = None
        self._blend_delta: np.ndarray | None = None
        self._blend_notes: tuple[str, ...] = ()
        self._blend_contact: str | None = None
        self._blend_resolver: Resolver | None = None
        self._was_safe = False

    @property
    def backend(self) -> str:
        """The resolver's backend (``"nullspace"`` for the law)."""
        return self.resolver.backend

    @property
    def algorithm(self) -> str:
        """The resolver's algorithm (``"nullspace"`` for the law)."""
        return self.resolver.algorithm

    @property
    def tolerance(self) -> float:
        """Residual norm above which a task is in conflict."""
        return self.feasibility.tolerance

    @property
    def singular_tolerance(self) -> float:
        """Threshold of the SINGULAR status."""
        return self.feasibility.singular_tolerance

    @property
    def solver(self) -> HierarchicalSolver | None:
        """The HQP resolver's primary solver (``None`` for a resolver without one)."""
        return getattr(self.resolver, "solver", None)

    @solver.setter
    def solver(self, solver: HierarchicalSolver) -> None:
        self.resolver.solver = solver  # type: ignore[attr-defined]

    @property
    def final_metric(self) -> np.ndarray | None:
        """The HQP resolver's final tie-break metric ``(n, n)`` (settable)."""
        return getattr(self.resolver, "final_metric", None)

    @final_metric.setter
    def final_metric(self, value: np.ndarray | None) -> None:
        self.resolver.final_metric = value  # type: ignore[attr-defined]

    @property
    def final_target(self) -> np.ndarray | None:
        """The HQP resolver's final tie-break target ``(n,)`` (settable)."""
        return getattr(self.resolver, "final_target", None)

    @final_target.setter
    def final_target(self, value: np.ndarray | None) -> None:
        self.resolver.final_target = value  # type: ignore[attr-defined]

    @property
    def last_built(self) -> BuiltStack | None:
        """The levels of the last step (``None`` before the first).

        A native step's levels are copied out of the core when first asked for.
        """
        if self._native_levels is not None:
            self._last_built = self._native_levels.built()[0]
            self._native_levels = None
        return self._last_built

    @property
    def last_solution(self) -> Solution | None:
        """The solver's solution of the last step (``None``: safe mode, or not an HQP)."""
        return getattr(self.resolver, "last_solution", None)

    # -- one step ---------------------------------------------------------------------------

    def _checked_q(self, q: np.ndarray, t: float) -> np.ndarray:
        """``q`` with its base quaternion normalised (see :meth:`step`'s errors)."""
        if not np.isfinite(t):
            raise InvalidInput(f"WholeBodyController.step: t must be a finite time [s], got {t}")
        if not self.model.floating_base:
            return q
        q = np.asarray(q, dtype=float)
        if q.shape != (self.model.nq,):
            return q  # the model's update names the shapes
        norm = float(np.sqrt(q[3:7].dot(q[3:7])))
        if abs(norm - 1.0) <= 1e-12:  # unit to rounding (a simulator's): left bit for bit
            return q
        if not abs(norm - 1.0) <= QUATERNION_TOLERANCE:
            raise InvalidInput(f"WholeBodyController.step: the base quaternion q[3:7] has norm "
                               f"{norm:.6g}; expected a unit quaternion (within "
                               f"{QUATERNION_TOLERANCE:g}, normalised)")
        q = q.copy()
        q[3:7] /= norm
        return q

    def step(self, state: RobotState, t: float) -> Command:
        """One control step: update, rows, solve, torques, feasibility report.

        Args:
            state: Measured state (``q`` ``(nq,)``, ``v`` ``(nv,)`` in pinocchio's convention).
            t: Control time [s].

        Returns:
            The command; ``safe_mode`` when the solve failed or returned non-finite values.

        Raises:
            InvalidInput: ``t`` is not finite; the state has the wrong shape, holds NaN or
                inf, or its base quaternion's norm is more than
                :data:`QUATERNION_TOLERANCE` from 1 (within it, the quaternion is
                normalised).

        """
        clock = time.perf_counter
        t0 = clock()
        self.step_serial += 1
        q = self._checked_q(state.q, t)
        # a blend between two hierarchies (a contact made) solves both: the Python step; the
        # decaying-offset blend only needs this step's torques (the native step's too)
        native = self.native is not None and (self._blend_start is None
                                               or self._blend_contact is None)
        # a native step runs its own pinocchio pass: the Python model's waits for a reader
        self.model.update(q, state.v, defer=native)
        t1 = clock()
        if native:
            command = self._native_step(q, state.v, t, t0, t1)
            if command is not None:
                return command
        x_prev = self.last_x
        declared = self.stack.layout_contacts()
        if [(c.name, c.frame, c.kind) for c in self.layout.contacts] != declared:
            self._relayout()
            x_prev = None
        self.stack.advance(self.model, self.layout, self.dt, t, x_prev)
        built = self._with_rate_level(self.stack.build(self.model, self.layout, self.dt, t))
        self._start_blend(t)
        before = self._build_before_contact(t)
        t2 = clock()
        notes: list[str] = []
        tau_before = None if before is None else self._solve_before(before, t)
        failed, self._native_failure = self._native_failure, None
        # only the HQP resolver runs a native step whose failure it can be told of
        extra = {"failed": failed} if failed is not None and isinstance(
            self.resolver, HQPResolver) else {}
        result = self.resolver.solve(self.model, self.layout, self.stack, built, t, notes,
                                     **extra)
        t3 = clock()
        safe = result is None
        if result is None:
            tau, qdd, wrenches = self.safe_command()
            notes.append("safe mode: gravity and contact compensation with joint damping")
            self.last_x = None
        else:
            x, tau = result
            qdd, wrenches = self._split(x)
            self.last_x = x.copy()
        self._rate_ref = tau.copy()
        if safe != self._was_safe:
            self._start_safe_blend(t, safe)
            tau_before = None
        self._was_safe = safe
        tau, suspended = self._blend(tau, t, notes, tau_before)
        tau = self._clip(tau, notes)
        t4 = clock()
        statuses, costs = self.resolver.report(built, None if result is None else result[0],
                                               notes, self.feasibility)
        report = FeasibilityReport(
            tasks=statuses,
            safe_mode=safe,
            strictness_suspended=suspended,
            notes=tuple(notes),
            level_costs=costs,
        )
        t5 = clock()
        self.last_t = float(t)
        self.last_tau = tau
        self._last_built = built
        self._native_levels = None
        timings = {"update": t1 - t0, "rows": t2 - t1, "solve": t3 - t2, "torques": t4 - t3,
                   "report": t5 - t4, "total": t5 - t0}
        return Command(tau=tau, qdd=qdd, wrenches=wrenches, report=report, safe_mode=safe,
                       timings=timings, t=float(t))

    def _native_step(self, q: np.ndarray, v: np.ndarray, t: float, t0: float,
                     t1: float) -> Command | None:
        """Run a steady step on the native step (``None``: the Python step runs this one).

        The model pass, the rows, the solve and the torques run in one call (GIL released);
        the report's statuses come from :class:`Diagnostics` on the native levels. A failed
        native solve leaves the step to the Python path (its fallback backends, then the
        safe command).
        """
        engine = self.native
        assert engine is not None
        mirror = engine.ready(self, t)
        if mirror is None:
            return None
        if not engine.steady and self.stack.events():  # a task or contact added or removed
            if self._blends_hierarchies():  # a contact made: the Python step solves both
                engine.forget()
                return None
            self._start_blend(t)  # a decaying offset, applied after the native solve
        if not engine.steady:  # tasks ramping in, goal ramps, contacts unloading
            ramping = self.stack.advance_native(self.model, self.layout, t, self.last_x)
            mirror.push_parameters()
            mirror.sync_ramps(ramping, t, self.last_x)
        elif mirror._ramped:  # the ramps that ended: their kernels' own rows again
            mirror.sync_ramps([], t, self.last_x)
        clock = time.perf_counter
        if mirror._rate_handle is not None:  # the torque-rate level
            assert self.max_torque_rate is not None
            mirror.set_torque_rate(self._rate_ref, self.max_torque_rate * self.dt)
        try:
            x, tau = mirror.step(q, v, t)
        except RuntimeError as exc:  # the Python step solves it on the fallback backend
            self._native_failure = str(exc).splitlines()[0] if str(exc) else "failed"
            return None
        if mirror._recording:
            mirror.collect_ramps()
        cut = mirror.step_core.cut_levels() if self.work_budget else ()
        mirror.record_errors(self)
        self.model.provide(mirror.quantity)  # the core's pass at this state, for readers
        t3 = clock()
        self.native.steps += 1
        self._rate_ref = tau.copy()
        self._was_safe = False
        notes: list[str] = []
        if cut:
            notes.append(f"work budget ({self.work_budget} units) spent: the QP of level(s) "
                         f"{', '.join(str(mirror.stack_level(k)) for k in cut)} stopped at its "
                         "best feasible point; the levels above are exact")
        suspended = False
        if self._blend_start is not None:  # a decaying-offset blend runs
            tau, suspended = self._blend(tau, t, notes)
        tau = self._clip(tau, notes)
        qdd, wrenches = self._split(x)
        t4 = clock()
        statuses, costs, built = mirror.report(self.feasibility)
        if callable(statuses):  # made when first read, from the step's data
            report = FeasibilityReport(notes=notes, level_costs=costs, statuses=statuses,
                                       strictness_suspended=suspended)
        else:
            report = FeasibilityReport(tasks=statuses, notes=notes, level_costs=costs,
                                       strictness_suspended=suspended)
        t5 = clock()
        self.last_x = x
        self.last_t = float(t)
        self.last_tau = tau
        self._last_built = built
        self._native_levels = mirror if built is None else None
        if isinstance(self.resolver, HQPResolver):
            self.resolver.last_solution = None  # the native step's levels are its own
        timings = {"update": t1 - t0, "rows": 0.0, "solve": t3 - t1, "torques": t4 - t3,
                   "report": t5 - t4, "total": t5 - t0}
        return Command(tau=tau, qdd=qdd, wrenches=wrenches, report=report, safe_mode=False,
                       timings=timings, t=float(t))

    def _split(self, x: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """``qdd`` and the wrench of each contact slot of a solution ``x`` (copies)."""
        layout = self.layout
        slots = self._slots
        if slots is None or slots[0] is not layout:
            slots = self._slots = (layout, [(c.name, c.start, c.start + c.size)
                                            for c in layout.contacts])
        wrenches = {}
        for name, a, b in slots[1]:
            wrenches[name] = x[a:b].copy()
        return x[: layout.nv].copy(), wrenches

    def _clip(self, tau: np.ndarray, notes: list[str]) -> np.ndarray:
        """Torques within the model's limits; a clip beyond rounding is noted."""
        excess = np.abs(tau)
        excess -= self.model.tau_max
        worst = np.maximum.reduce(excess, initial=0.0)  # (ufunc methods: no Python calls)
        if worst > 0.0:
            # The solver meets the torque-limit rows to its tolerance: entries beyond by less
            # than 1e-6 relative (or 1e-6 N m) are rounding; larger ones are reported.
            limit = self.model.tau_max
            tau = np.minimum(np.maximum(tau, -limit), limit)
            if np.logical_or.reduce(excess > 1e-6 * np.maximum(1.0, limit)):
                notes.append(f"command clipped to the model's torque limits (by up to "
                             f"{worst:.3g} N m)")
        return tau

    def _with_rate_level(self, built: BuiltStack) -> BuiltStack:
        """Insert the torque-rate level after the constraint levels (module docstring).

        ``tau_ref - d <= T x + t0 <= tau_ref + d`` with ``d = max_torque_rate * dt`` and
        ``tau = T x + t0`` (:func:`~hqp.tasks.dynamics.torque_map`); unbounded at the first
        step (as the native step's level); none for a resolver other than HQP's or with
        ``max_torque_rate=None``.
        """
        if self.max_torque_rate is None or not isinstance(self.resolver, HQPResolver):
            return built
        T, t0 = torque_map(self.model, self.layout, "WholeBodyController: torque rate")
        if self._rate_ref is None:
            lower, upper = np.full(T.shape[0], -np.inf), np.full(T.shape[0], np.inf)
        else:
            d = self.max_torque_rate * self.dt
            lower = self._rate_ref - d - t0
            upper = self._rate_ref + d - t0
        k = sum(1 for index in built.level_index if index <= self._rate_after)
        index = max(self._rate_after, 0)
        levels = list(built.levels)
        levels.insert(k, Level(C=T, lower=lower, upper=upper, name=RATE_TASK))
        level_index = built.level_index[:k] + (index,) + built.level_index[k:]
        spans = [s if s.built_level < k else dataclasses.replace(s, built_level=s.built_level + 1)
                 for s in built.spans]
        spans.insert(sum(1 for s in built.spans if s.built_level < k),
                     TaskSpan(RATE_TASK, index, k, slice(0, 0), slice(0, T.shape[0]), 1.0, 1.0,
                              True))
        rows = dict(built.rows)
        rows[RATE_TASK] = Rows(C=T, lower=lower, upper=upper)
        return BuiltStack(levels, level_index, tuple(spans), rows, built.n)

    def _relayout(self) -> None:
        self.layout = Layout.build(self.model.nv, self.stack.layout_contacts())
        self.last_x = None
        self.resolver.reset()

    # -- torques ----------------------------------------------------------------------------

    def torques(self, x: np.ndarray) -> np.ndarray:
        """Actuated torques of a solution: ``tau = S (M qdd + h - sum_c J_c^T f_c)`` ``(na,)``.

        The model must be updated at the state the solution was computed for.
        """
        return joint_torques(self.model, self.layout, x)

    def safe_command(self) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Compute the safe command: gravity and contact compensation with joint damping.

        The contact wrenches ``f`` are the least-norm solution of the floating-base rows of the
        static equilibrium ``g_u = sum_c J_{c,u}^T f_c`` over the active contacts; then
        ``tau = g_a - sum_c J_{c,a}^T f_c - D v_a`` with ``D = damping * I``, clipped to the
        torque limits.

        Returns:
            ``(tau (na,), qdd (nv,) zeros, wrenches by contact name)``.

        """
        m = self.model
        act = m.actuated
        g = m.gravity
        active = [s for s in self.layout.contacts if s.name in self.stack.active_contacts]
        wrenches = {s.name: np.zeros(s.size) for s in self.layout.contacts}
        tau = g[act] - self.damping * m.v[act]
        if active and m.nv_base:
            Js = [m.frame_jacobian(s.frame)[: s.size] for s in active]
            JT = np.hstack([J.T for J in Js])  # (nv, sum sizes)
            f, *_ = np.linalg.lstsq(JT[: m.nv_base], g[: m.nv_base], rcond=None)
            tau = tau - JT[act] @ f
            start = 0
            for s in active:
                wrenches[s.name] = f[start:start + s.size]
                start += s.size
        tau = np.clip(np.nan_to_num(tau), -m.tau_max, m.tau_max)
        return tau, np.zeros(m.nv), wrenches

    def _start_blend(self, t: float) -> None:
        """Start a torque blend on the stack's blend events of this step (if any).

        A contact made alone is blended between two hierarchies (see :meth:`_blend`); any
        other change (or several at once) by a decaying offset.
        """
        events = self.stack.pop_events()
        if not events or self.last_tau is None or self.stack.blend_time <= 0.0:
            return
        self._blend_start = float(t)
        self._blend_delta = None  # set by _blend at this step (needs the new torques)
        self._blend_notes = tuple(e.note for e in events)
        self._blend_contact = _contact_made(events)

    def _blends_hierarchies(self) -> bool:
        """Whether the blend events waiting start a blend between two hierarchies.

        A contact made alone, with torques sent before it (:meth:`_start_blend`).
        """
        return (_contact_made(self.stack.events()) is not None
                and self.last_tau is not None and self.stack.blend_time > 0.0)

    def _start_safe_blend(self, t: float, safe: bool) -> None:
        """Blend into (or out of) the safe command: the offset from the last torques decays.

        The safe command (gravity and contact compensation, joint damping) differs from the
        hierarchy's last torques by tens of N m; sent at once it is a torque step. Entering and
        leaving safe mode start the decaying-offset blend of :meth:`_blend` over the stack's
        ``blend_time`` instead (a blend already running restarts from the torques sent last).
        """
        if self.last_tau is None or self.stack.blend_time <= 0.0:
            return
        self._blend_start = float(t)
        self._blend_delta = None
        self._blend_contact = None
        self._blend_notes = ("safe mode entered",) if safe else ("safe mode left",)

    def _build_before_contact(self, t: float) -> BuiltStack | None:
        """Levels of the hierarchy without the contact being blended in (``None``: no blend)."""
        name = self._blend_contact
        if self._blend_start is None or name is None or name not in self.stack.active_contacts:
            self._blend_contact = None
            return None
        with self.stack.contact_released(name):
            return self.stack.build(self.model, self.layout, self.dt, t)

    def _solve_before(self, before: BuiltStack, t: float) -> np.ndarray | None:
        """Torques of the hierarchy without the contact being blended in (own resolver).

        Solved before the current hierarchy, with a twin of the resolver created once (its own
        warm starts), so that what the resolver keeps of the step is the current hierarchy's.
        """
        if self._blend_resolver is None:
            self._blend_resolver = self.resolver.twin()
        result = self._blend_resolver.solve(self.model, self.layout, self.stack, before, t, [])
        return None if result is None else result[1]

    def _blend(
        self, tau: np.ndarray, t: float, notes: list[str], tau_before: np.ndarray | None = None
    ) -> tuple[np.ndarray, bool]:
        """Interpolate torques over ``blend_time`` after a change that cannot be ramped.

        With ``tau_before`` (a contact just made: the torques of the hierarchy without it, at
        the current state), ``tau = (1 - s) tau_before + s tau`` for a minimum-jerk fraction
        ``s`` rising from 0 to 1: the new contact's wrench is phased in and both hierarchies
        keep their feedback; a step change of the new hierarchy early in the blend reaches the
        torques scaled by ``s``. Otherwise (a task or contact removed, or the hierarchy
        without the contact failed) the offset between the last torques and the new ones at
        the change decays: ``tau + (1 - s) (tau_last - tau_0)``.
        """
        if self._blend_start is None:
            return tau, False
        s = min_jerk((t - self._blend_start) / self.stack.blend_time)
        if s >= 1.0:
            self._blend_start = None
            self._blend_contact = None
            return tau, False
        notes.append(
            f"strictness suspended: torques interpolated over {self.stack.blend_time:g} s after "
            + "; ".join(self._blend_notes)
        )
        if tau_before is not None:
            self._blend_delta = None
            return (1.0 - s) * tau_before + s * tau, True
        if self._blend_delta is None:
            last = self.last_tau if self.last_tau is not None else tau
            self._blend_delta = last - tau
        return tau + (1.0 - s) * self._blend_delta, True


def _contact_made(events: Sequence[BlendEvent]) -> str | None:
    """Return the contact made when it is the only blend event (else ``None``)."""
    return events[0].contact if len(events) == 1 else None
