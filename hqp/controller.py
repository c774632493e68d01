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
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from hqp.tasks.dynamics import joint_torques
from hqp.tasks.reference import min_jerk

if TYPE_CHECKING:
    from hqp.model import RobotModel, RobotState
    from hqp.robots import Robot
    from hqp.solver import HierarchicalSolver, Level, Solution
    from hqp.stack import BuiltStack, Stack, TaskSpan
    from hqp.tasks.base import Category, Rows, Task

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


# ------------------------------------------------------------------------------------------------
# The HQP whole-body controller
# ------------------------------------------------------------------------------------------------


def _violation(C: np.ndarray, lower: np.ndarray | None, upper: np.ndarray | None,
               x: np.ndarray) -> np.ndarray:
    """Signed distance of ``C x`` outside ``[lower, upper]`` (0 inside)."""
    cx = C @ x
    out = np.zeros_like(cx)
    if upper is not None:
        out = np.where(cx > upper, cx - upper, out)
    if lower is not None:
        out = np.where(cx < lower, cx - lower, out)
    return out


def _null_basis(M: np.ndarray, rank_tol: float) -> np.ndarray:
    """Orthonormal basis ``(r, r - rank)`` of the null space of ``M`` ``(m, r)``.

    Pivoted QR of ``M^T`` (``M^T P = Q R``): the last ``r - rank`` columns of ``Q`` span the
    null space, the rank read on ``|diag R|`` against ``rank_tol`` times its largest entry.
    """
    import scipy.linalg

    m, r = M.shape
    if m == 0 or r == 0:
        return np.eye(r)
    Q, R, _ = scipy.linalg.qr(M.T, pivoting=True, mode="full", check_finite=False)
    d = np.abs(np.diag(R))
    if d.size == 0 or d[0] == 0.0:
        return np.eye(r)
    rank = int(np.sum(d > rank_tol * d[0]))
    return Q[:, rank:]


class WholeBodyController(Controller):
    """Whole-body torque controller over a strict hierarchy of QPs (the seed's servo).

    Args:
        robot_model: The controller's robot model (pinocchio).
        contacts: Contacts to declare in the stack (``hqp.tasks.contact.Contact`` tasks, their
            physics rows at the PHYSICS level and their limits at CONTACT_LIMITS); contacts
            already declared in ``stack`` need not be repeated.
        stack: The levels of tasks (default: an empty :class:`~hqp.stack.Stack` with the
            default levels).
        dt: Control period [s].
        backend: QP backend of the solver (``"proxsuite"``, ``"osqp"``, ``"daqp"``,
            ``"quadprog"``).
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
        backend: str = "proxsuite",
        algorithm: str = "basis",
        *,
        final_metric: np.ndarray | None = None,
        final_target: np.ndarray | None = None,
        tolerance: float = 1e-5,
        singular_tolerance: float = 1e-4,
        diagnostics: str = "full",
        damping: float = 2.0,
    ) -> None:
        from hqp.errors import InvalidInput
        from hqp.layout import Layout
        from hqp.solver import HierarchicalSolver
        from hqp.stack import Stack

        if not np.isfinite(dt) or dt <= 0.0:
            raise InvalidInput(f"WholeBodyController: dt must be positive, got {dt}")
        if diagnostics not in ("full", "residuals"):
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
        self.backend = backend
        self.algorithm = algorithm
        self.solver = HierarchicalSolver(backend, algorithm)
        self.final_metric = final_metric
        self.final_target = final_target
        self.tolerance = float(tolerance)
        self.singular_tolerance = float(singular_tolerance)
        self.diagnostics = diagnostics
        self.damping = float(damping)
        self.last_t = 0.0
        self.last_x: np.ndarray | None = None
        self.last_tau: np.ndarray | None = None
        self.last_built: BuiltStack | None = None
        self.last_solution: Solution | None = None
        self._blend_start: float | None = None
        self._blend_delta: np.ndarray | None = None
        self._blend_notes: tuple[str, ...] = ()
        self._blend_contact: str | None = None
        self._blend_solver: HierarchicalSolver | None = None
        self._yield_guess: dict[str, int] = {}
        self._fallback_solver: HierarchicalSolver | None = None

    # -- one step ---------------------------------------------------------------------------

    def step(self, state: RobotState, t: float) -> Command:
        """One control step: update, rows, solve, torques, feasibility report.

        Args:
            state: Measured state (``q`` ``(nq,)``, ``v`` ``(nv,)`` in pinocchio's convention).
            t: Control time [s].

        Returns:
            The command; ``safe_mode`` when the solve failed or returned non-finite values.

        Raises:
            InvalidInput: The state has the wrong shape or holds NaN or inf.

        """
        clock = time.perf_counter
        t0 = clock()
        self.model.update(state.q, state.v)
        t1 = clock()
        x_prev = self.last_x
        declared = self.stack.layout_contacts()
        if [(c.name, c.frame, c.kind) for c in self.layout.contacts] != declared:
            self._relayout()
            x_prev = None
        built = self.stack.build(self.model, self.layout, self.dt, t, x_prev)
        self._start_blend(t)
        before = self._build_before_contact(t, x_prev)
        t2 = clock()
        notes: list[str] = []
        tau_before = None if before is None else self._solve_before(before, t)
        result = self._solve_built(built, t, notes)
        t3 = clock()
        safe = result is None
        if result is None:
            tau, qdd, wrenches = self.safe_command()
            notes.append("safe mode: gravity and contact compensation with joint damping")
            self.last_x = None
        else:
            x, tau = result
            qdd = x[: self.layout.nv].copy()
            wrenches = {c.name: x[c.slice].copy() for c in self.layout.contacts}
            self.last_x = x.copy()
        tau, suspended = self._blend(tau, t, notes, tau_before)
        excess = np.abs(tau) - self.model.tau_max
        if np.any(excess > 0.0):
            # The solver meets the torque-limit rows to its tolerance: entries beyond by less
            # than 1e-6 relative (or 1e-6 N m) are rounding; larger ones are reported.
            worst = float(excess.max())
            tau = np.clip(tau, -self.model.tau_max, self.model.tau_max)
            if np.any(excess > 1e-6 * np.maximum(1.0, self.model.tau_max)):
                notes.append(f"command clipped to the model's torque limits (by up to "
                             f"{worst:.3g} N m)")
        t4 = clock()
        statuses, costs = self._feasibility(built, None if result is None else result[0], notes)
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
        self.last_built = built
        timings = {"update": t1 - t0, "rows": t2 - t1, "solve": t3 - t2, "torques": t4 - t3,
                   "report": t5 - t4, "total": t5 - t0}
        return Command(tau=tau, qdd=qdd, wrenches=wrenches, report=report, safe_mode=safe,
                       timings=timings, t=float(t))

    def _solve_built(
        self, built: BuiltStack, t: float, notes: list[str]
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Solve the built levels: ``(x, tau)``, or ``None`` (reason in ``notes``) for safe mode.

        The step skeleton of :meth:`step` is shared by every controller; this hook and
        :meth:`_feasibility` are what a controller (HQP here, the null-space law in
        :mod:`hqp.nullspace`) changes.
        """
        from hqp.errors import HQPError

        self.last_solution = None
        failure = ""
        for solver in (self.solver, None):
            if solver is None:  # the primary backend failed: one retry on the fallback
                solver = self._fallback()
                if solver is None:
                    break
                notes.append(f"{failure}; solved again with backend {solver.backend_name!r}")
                logger.info("t=%.4f: %s; retrying with %s", t, failure, solver.backend_name)
            try:
                # the stack builds float arrays of consistent shapes: only finiteness is
                # left to check (one reduction per level), not the user-input validation
                if not all(_finite_level(level) for level in built.levels):
                    failure = "non-finite task rows"
                    break
                solution = solver.solve(
                    built.levels, final_metric=self.final_metric,
                    final_target=self.final_target, validate=False,
                )
            except HQPError as exc:
                failure = f"solve failed: {exc}"
                continue
            if not np.all(np.isfinite(solution.x)):
                failure = "solver returned non-finite values"
                continue
            self.last_solution = solution
            break
        if self.last_solution is None:
            notes.append(failure)
            logger.warning("t=%.4f: %s; safe command sent", t, failure)
            return None
        x = self.last_solution.x
        tau = self.torques(x)
        if not np.all(np.isfinite(tau)):
            notes.append("non-finite torques")
            return None
        return x, tau

    def _fallback(self) -> HierarchicalSolver | None:
        """Return the solver of the fallback backend (created once), or ``None`` if none.

        DAQP (an exact active-set method) backs up the other backends, quadprog backs up DAQP.
        """
        from hqp.solver import HierarchicalSolver, available_backends  # noqa: F811

        if self._fallback_solver is None:
            name = "daqp" if self.backend != "daqp" else "quadprog"
            if name not in available_backends():
                return None
            self._fallback_solver = HierarchicalSolver(name, self.algorithm)
        return self._fallback_solver

    def _feasibility(
        self, built: BuiltStack, x: np.ndarray | None, notes: list[str]
    ) -> tuple[tuple[TaskStatus, ...], tuple[float, ...]]:
        """Per-task statuses and per-level costs of the step (``x`` is ``None`` in safe mode)."""
        solution = self.last_solution
        if solution is None:
            return (), ()
        statuses = () if x is None else self._statuses(built, solution)
        return statuses, tuple(lv.cost for lv in solution.levels)

    def _relayout(self) -> None:
        from hqp.layout import Layout

        self.layout = Layout.build(self.model.nv, self.stack.layout_contacts())
        self.last_x = None
        if hasattr(self.solver, "reset"):
            self.solver.reset()

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
        contacts = {e.contact for e in events}
        self._blend_contact = contacts.pop() if len(events) == 1 and None not in contacts else None

    def _build_before_contact(self, t: float, x_prev: np.ndarray | None) -> BuiltStack | None:
        """Levels of the hierarchy without the contact being blended in (``None``: no blend)."""
        name = self._blend_contact
        if self._blend_start is None or name is None or name not in self.stack.active_contacts:
            self._blend_contact = None
            return None
        with self.stack.contact_released(name):
            return self.stack.build(self.model, self.layout, self.dt, t, x_prev)

    def _solve_before(self, before: BuiltStack, t: float) -> np.ndarray | None:
        """Torques of the hierarchy without the contact being blended in (own solver).

        Solved before the current hierarchy, so that what :meth:`_solve_built` leaves behind
        (``last_solution``, a subclass's law) is the current hierarchy's.
        """
        from hqp.solver import HierarchicalSolver

        if self._blend_solver is None:
            self._blend_solver = HierarchicalSolver(self.backend, self.algorithm)
        solver, self.solver = self.solver, self._blend_solver
        try:
            result = self._solve_built(before, t, [])
        finally:
            self.solver = solver
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

    # -- report -----------------------------------------------------------------------------

    def _statuses(self, built: BuiltStack, solution: Solution) -> tuple[TaskStatus, ...]:
        """Per-task feasibility from the unweighted rows of each task at the solution.

        ``Z_k`` is an orthonormal basis of the directions left free by levels ``0..k``: the
        null space of their equality rows and of their active (or violated) inequality rows,
        i.e. the face of the optimal set on which the solution lies. A task's ``sigma_min`` is
        the ``m``-th singular value of its ``m`` rows (equalities and active inequalities)
        times the basis of the levels above (0 when ``m`` exceeds the free dimension); only
        tasks with equality rows can be reported singular.
        """
        x = solution.x
        full = self.diagnostics == "full"
        n = built.n
        rank_tol = 1e-9
        Z = np.eye(n)
        bases: list[np.ndarray] = []  # Z after each built level
        out: list[TaskStatus] = []
        by_level: dict[int, list] = {}
        for span in built.spans:
            by_level.setdefault(span.built_level, []).append(span)
        for k, level in enumerate(built.levels):
            rep = solution.levels[k]
            active_rows = set(int(i) for i in rep.active)
            for span in by_level.get(k, []):
                rows = built.rows[span.name]
                parts = []
                mats = []
                if rows.A is not None:
                    parts.append(rows.A @ x - rows.b)
                    mats.append(rows.A)
                if rows.C is not None:
                    viol = _violation(rows.C, rows.lower, rows.upper, x)
                    parts.append(viol)
                    idx = [i - span.ineq.start for i in range(span.ineq.start, span.ineq.stop)
                           if i in active_rows]
                    if idx:
                        mats.append(rows.C[idx])
                r = np.concatenate(parts) if parts else np.zeros(0)
                residual = float(np.linalg.norm(r))
                sigma = float("nan")
                if rows.A is None:
                    pass  # inequality rows only: satisfied or in conflict, never singular
                elif full:
                    P = np.vstack(mats) @ Z
                    m_rows = P.shape[0]
                    if m_rows > P.shape[1]:
                        sigma = 0.0
                    else:
                        sv = np.linalg.svd(P, compute_uv=False)
                        sigma = float(sv[m_rows - 1]) if sv.size >= m_rows else 0.0
                else:
                    sigma = float(rep.sigma_min)
                yields_to = None
                if residual > self.tolerance:
                    status = Feasibility.CONFLICT
                    if full:
                        yields_to = self._yields_to(rows, r, bases, built, span)
                elif rows.A is not None and np.isfinite(sigma) and sigma < self.singular_tolerance:
                    status = Feasibility.SINGULAR
                else:
                    status = Feasibility.SATISFIED
                out.append(TaskStatus(span.name, span.level, status, residual, yields_to, sigma))
            if full and k < len(built.levels) - 1:
                mats = []
                if level.A is not None:
                    mats.append(np.asarray(level.A))
                if level.C is not None and rep.active.size:
                    mats.append(np.asarray(level.C)[rep.active])
                if mats:
                    Z = Z @ _null_basis(np.vstack(mats) @ Z, rank_tol)
                bases.append(Z)
        return tuple(out)

    @staticmethod
    def _bisect_blocked(blocked: Callable[[int], bool], k: int) -> int:
        """First ``j`` in ``[-1, k)`` with ``blocked(j)`` (monotone), or ``k`` when none."""
        lo, hi = -1, k  # answer in [lo, hi]
        while lo < hi:
            mid = (lo + hi) // 2
            if blocked(mid):
                hi = mid
            else:
                lo = mid + 1
        return lo

    def _yields_to(self, rows: Rows, r: np.ndarray, bases: list[np.ndarray],
                   built: BuiltStack, span: TaskSpan) -> int | None:
        """Highest level whose optimal set (affine part) leaves the task's residual above tolerance.

        The residual reachable from ``x`` within ``x + Z_j y`` (``Z_j``: basis left free by
        levels ``0..j``) is ``min_y ||r + A Z_j y||``; it grows with ``j``. The first ``j`` where
        it exceeds the tolerance is the level the task yields to; if none above, the task is
        traded within its own level; if even the whole space cannot meet it, the task is
        infeasible on its own (``None``).
        """
        mats = []
        target = []
        n_eq = 0 if rows.A is None else rows.A.shape[0]
        if rows.A is not None:
            mats.append(rows.A)
            target.append(r[:n_eq])
        if rows.C is not None:
            bad = np.flatnonzero(np.abs(r[n_eq:]) > 0.0)
            mats.append(rows.C[bad])
            target.append(r[n_eq:][bad])
        A = np.vstack(mats)
        r0 = np.concatenate(target)

        scale = max(1.0, float(np.abs(A).max(initial=0.0)))

        def reachable(Z: np.ndarray) -> float:
            # min_y ||r0 + A Z y||: remove the part of r0 in the range of A Z (rank decided
            # against the scale of A, not of A Z, which vanishes where the task is blocked).
            if Z.shape[1] == 0:
                return float(np.linalg.norm(r0))
            U, sv, _ = np.linalg.svd(A @ Z, full_matrices=False)
            U = U[:, sv > 1e-9 * scale]
            return float(np.linalg.norm(r0 - U @ (U.T @ r0)))

        # The reachable residual grows with j: check the last answer and its neighbour first
        # (one or two evaluations at steady state), then bisect.
        k = span.built_level
        tol = self.tolerance

        def blocked(j: int) -> bool:  # j = -1: the whole space
            Z = np.eye(A.shape[1]) if j < 0 else bases[j]
            return reachable(Z) > tol

        guess = self._yield_guess.get(span.name)
        if guess is not None and -1 <= guess < k:
            if blocked(guess) and (guess == -1 or not blocked(guess - 1)):
                first = guess
            elif guess + 1 < k and not blocked(guess) and blocked(guess + 1):
                first = guess + 1
            else:
                first = self._bisect_blocked(blocked, k)
        else:
            first = self._bisect_blocked(blocked, k)
        self._yield_guess[span.name] = first
        if first == -1:
            return None
        if first < k:
            return built.level_index[first]
        return span.level


def standing_stack(
    robot: Robot,
    model: RobotModel,
    *,
    com_kp: float = 100.0,
    orientation_kp: float = 100.0,
    posture_kp: float = 50.0,
    friction: float | None = None,
    sole_margin: float = 0.9,
    torque_scale: float = 1.0,
    contact_kd: float = 0.0,
    angular_momentum_weight: float = 1e-3,
    angular_momentum_gain: float = 10.0,
    ramp_time: float = 0.6,
    max_joint_acceleration: float = 50.0,
) -> tuple[Stack, list[Task]]:
    """Build the stack of a humanoid standing on both feet, and its contacts.

    Levels (default categories): physics (floating-base dynamics, both soles as rigid surface
    contacts); contact and actuation limits (friction pyramids, unilateral forces, centre of
    pressure in the soles, yaw torques, torque limits); viable joint limits (acceleration bound:
    the fixed-base torque estimate clipped to [5, 50] rad/s^2 by default; braking: what the
    supports allow, see the comments below); balance (centre of mass over the centre of the
    feet at its standing height, and, weighted in the same level, damping of the centroidal
    angular momentum); operational (trunk orientation upright as in the standing
    configuration); posture (the standing configuration).

    The angular-momentum damping matters when the centre-of-mass task asks for more than the
    support gives (a goal moved faster than the centre of pressure can follow): the centre of
    mass can then still be accelerated by turning the body (arms, trunk), which a level holding
    the centre of mass alone does without bound, flailing the arms at their velocity limits and
    switching their acceleration bounds from step to step. With a small weight the trade only
    happens in that case: when both are feasible both are met exactly.

    Args:
        robot: The bundled robot (feet, contact surfaces, ``q_standing``, ``trunk`` frame).
        model: Its controller model.
        com_kp: Stiffness of the centre-of-mass task [1/s^2] (critical damping).
        orientation_kp: Stiffness of the trunk orientation task [1/s^2].
        posture_kp: Stiffness of the posture task [1/s^2].
        friction: Friction coefficient of the contact model (default: 0.8 x the sole's).
        sole_margin: Fraction of the sole's half-length and half-width given to the centre
            of pressure (a margin against tipping on the edge).
        torque_scale: Fraction of the torque limits the controller may use.
        contact_kd: Damping of the contacts' drift stabilisation [1/s].
        angular_momentum_weight: Weight of the angular-momentum damping in the balance level
            (the centre-of-mass task has weight 1; rows in [N m] against [m/s^2]); 0 leaves
            it out.
        angular_momentum_gain: Its damping [1/s].
        ramp_time: Default ramp of tasks added at runtime [s] (goal ramps from zero error; a
            min-jerk goal move of ``d`` over ``T`` asks for a peak feed-forward acceleration
            of ``5.8 d / T^2``).
        max_joint_acceleration: Upper clip of the joint-acceleration bound [rad/s^2] (>= 5;
            the bound is the fixed-base torque estimate clipped to ``[5, this]``; the
            braking assumption is half of it, or what the active supports allow).

    Returns:
        ``(stack, contacts)``; pass both to :class:`WholeBodyController`.

    """
    from hqp.errors import InvalidGain
    from hqp.layout import ContactType
    from hqp.stack import Stack
    from hqp.tasks.base import Category
    from hqp.tasks.centroidal import CentroidalMomentumTask
    from hqp.tasks.com import CoMTask, support_center
    from hqp.tasks.contact import Contact
    from hqp.tasks.dynamics import FloatingBaseDynamics
    from hqp.tasks.joint_limits import (
        JointLimits,
        SupportBraking,
        max_acceleration_from_torques,
    )
    from hqp.tasks.orientation import OrientationTask
    from hqp.tasks.posture import PostureTask
    from hqp.tasks.torque_limits import TorqueLimits

    if not (np.isfinite(max_joint_acceleration) and max_joint_acceleration >= 5.0):
        raise InvalidGain(f"standing_stack: max_joint_acceleration must be finite and >= 5 "
                          f"rad/s^2, got {max_joint_acceleration}")
    model.update(robot.q_standing, np.zeros(model.nv))
    stack = Stack(ramp_time=ramp_time)
    stack.add(FloatingBaseDynamics())
    contacts: list[Task] = []
    for foot in robot.feet:
        surface = robot.contact(foot)
        mu = 0.8 * surface.friction if friction is None else friction
        contacts.append(Contact(
            foot, surface.frame, ContactType.SURFACE, mu=mu,
            half_length=sole_margin * surface.half_length,
            half_width=sole_margin * surface.half_width, kd=contact_kd, model=model,
        ))
    stack.add(TorqueLimits(scale=torque_scale), Category.CONTACT_LIMITS)
    # Viable joint limits. Bound on |qdd|: the fixed-base torque estimate, kept within
    # [5, 50] rad/s^2. Braking assumption A of the viability bound: the smaller of half that
    # bound (a reserve: braking on the curve of the full bound overshoots as soon as the
    # realised deceleration falls short of the commanded one, e.g. on soft contacts) and the
    # support-aware estimate (a leg joint moves the rest of the body about the soles: about
    # 1 rad/s^2 at the ankles of paper-humanoid), so that a joint whose braking needs the
    # contacts approaches its limit slowly enough to be stopped within them. As a bound on
    # |qdd| the support-aware value would lock the ankles that balance needs; as the braking
    # assumption it only caps the velocity toward a limit at sqrt(2 A d). Where the estimate
    # is zero (g1's ankle roll: its torque limit cannot hold the whole body on one ankle, a
    # case the rigid side-about-the-axis model does not describe in double support), half the
    # bound is kept. With no contact at all (a jump's flight) the legs brake themselves, not
    # the body (paper-humanoid's knee: 5.8 rad/s^2 standing, 25 in the air): SupportBraking,
    # all-or-none. Per contact, a swing leg would get its free-limb value too; measured on
    # `walk`, that made the swing legs approach their limits faster and the walk worse (a
    # 198 N m torque step, a safe-mode step, torques clipped by 0.01 N m): not kept.
    qdd_max = np.clip(max_acceleration_from_torques(model, margin=0.5), 5.0,
                      max_joint_acceleration)
    braking = SupportBraking(model, [robot.contact(foot).frame for foot in robot.feet],
                             0.5 * qdd_max, margin=0.5, per_contact=False)
    # Velocity bounds approached over 20 ms rather than in one step (no torque step when a
    # joint reaches its velocity limit).
    stack.add(JointLimits(qdd_max=qdd_max, braking=braking, reserve=2.0, velocity_time=0.02))
    com = CoMTask(model, kp=com_kp)
    centre = support_center(model, list(robot.feet))
    com.set_goal(np.array([centre[0], centre[1], model.com[2]]))
    stack.add(com)
    if angular_momentum_weight > 0.0:
        stack.add(CentroidalMomentumTask(model, "angular", name="angular_momentum",
                                         weight=angular_momentum_weight,
                                         gain=angular_momentum_gain))
    trunk = OrientationTask(model, "trunk", kp=orientation_kp)
    trunk.set_goal(model.frame_placement("trunk").rotation.copy())
    stack.add(trunk)
    posture = PostureTask(model, kp=posture_kp)
    posture.set_configuration(robot.q_standing, model)
    stack.add(posture)
    return stack, contacts


def standing_controller(
    robot: Robot,
    *,
    dt: float = 0.001,
    backend: str = "proxsuite",
    algorithm: str = "basis",
    diagnostics: str = "full",
    **gains: float,
) -> WholeBodyController:
    """Build a :class:`WholeBodyController` holding a humanoid standing on both feet.

    See :func:`standing_stack` for the levels and ``gains``.

    Args:
        robot: The bundled robot (``hqp.robots.load(name)``).
        dt: Control period [s].
        backend: QP backend.
        algorithm: ``"basis"`` or ``"cascade"``.
        diagnostics: ``"full"`` or ``"residuals"`` (see :class:`WholeBodyController`).
        **gains: Keyword arguments of :func:`standing_stack`.

    """
    model = robot.model()
    stack, contacts = standing_stack(robot, model, **gains)
    return WholeBodyController(model, contacts, stack, dt=dt, backend=backend,
                               algorithm=algorithm, diagnostics=diagnostics)


def _finite_level(level: Level) -> bool:
    """Whether a stack-built level's matrices and bounds are free of NaN (bounds may be inf)."""
    for value in (level.A, level.b, level.C):
        if value is not None and not np.isfinite(np.sum(value)):
            return False
    for value in (level.lower, level.upper):
        if value is not None and np.isnan(value).any():
            return False
    return True
