"""The papers' null-space law as a resolver of the servo, and the controller that holds it.

:class:`NullSpaceResolver` turns the built levels of a step into the law's matrices
(:func:`~hqp.control.nullspace.multicontact.law_problem`), applies
:func:`~hqp.control.nullspace.law.prioritized_torques` (optionally again with the activation
zones of :mod:`hqp.control.nullspace.zones`) and returns ``x = [qdd | f]`` and the torques.
:class:`NullSpaceController` is the servo (:class:`~hqp.control.servo.WholeBodyController`)
holding one: same step, stack handling, torque blending, safe command and report format.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from hqp.control.command import Command, FeasibilityReport
from hqp.control.diagnostics import level_cost
from hqp.control.nullspace.law import EIG_TOL, LawSolution, prioritized_torques
from hqp.control.nullspace.multicontact import (
    LawProblem,
    decision_vector,
    law_problem,
    utilization_weights,
)
from hqp.control.nullspace.native import NativeLawEngine, NativeLawMirror
from hqp.control.nullspace.zones import ZoneSettings, ZoneState, constraint_zones
from hqp.control.servo import WholeBodyController
from hqp.errors import HQPError, InvalidInput
from hqp.stack import Stack
from hqp.tasks.base import Category

if TYPE_CHECKING:
    from hqp.control.command import TaskStatus
    from hqp.control.diagnostics import Diagnostics
    from hqp.model import RobotModel
    from hqp.model.layout import Layout
    from hqp.stack import BuiltStack
    from hqp.tasks.base import Task

logger = logging.getLogger(__name__)

INTERNAL_FORCES = ("none", "min-norm", "balanced")
"""Choices of the law's internal forces (:class:`NullSpaceResolver`)."""


class NullSpaceResolver:
    """The prioritised torque law on the levels of a built stack.

    Args:
        eig_tol: Relative eigenvalue threshold of eq. 22 (:data:`EIG_TOL`).
        internal_forces: ``"balanced"`` (least load-weighted use of every contact's centre of
            pressure and friction, :func:`utilization_weights`), ``"min-norm"`` (least-norm
            contact wrenches) or ``"none"`` (the plain law).
        method: ``"whitened"`` or ``"literal"`` (see :func:`prioritized_torques`).
        zones: The activation zones of the contact and actuation limits (default: none).

    Raises:
        InvalidInput: Bad ``eig_tol``, ``internal_forces``, ``method`` or zones.

    """

    backend = "nullspace"
    algorithm = "nullspace"

    def __init__(self, *, eig_tol: float = EIG_TOL, internal_forces: str = "min-norm",
                 method: str = "whitened", zones: ZoneSettings = ZoneSettings()) -> None:
        if not (np.isfinite(eig_tol) and 0.0 < eig_tol < 1.0):
            raise InvalidInput(f"NullSpaceController: eig_tol must be in (0, 1), got {eig_tol}")
        if internal_forces not in INTERNAL_FORCES:
            raise InvalidInput(
                "NullSpaceController: internal_forces must be 'none', 'min-norm' or "
                f"'balanced', got {internal_forces!r}"
            )
        if method not in ("whitened", "literal"):
            raise InvalidInput(
                f"NullSpaceController: method must be 'whitened' or 'literal', got {method!r}"
            )
        support, torque = zones.support, zones.torque
        if support is not None and not (np.isfinite(support) and support > 0.0):
            raise InvalidInput(
                f"NullSpaceController: support_zone must be > 0 or None, got {support}"
            )
        if torque is not None and not (np.isfinite(torque) and 0.0 < torque <= 1.0):
            raise InvalidInput(
                f"NullSpaceController: torque_zone must be in (0, 1] or None, got {torque}"
            )
        if int(zones.passes) < 1:
            raise InvalidInput(f"NullSpaceController: zone_passes must be >= 1, got {zones.passes}")
        self.eig_tol = float(eig_tol)
        self.internal_forces = internal_forces
        self.method = method
        self.zones = ZoneSettings(None if support is None else float(support),
                                  None if torque is None else float(torque), int(zones.passes))
        self.zone_state = ZoneState()
        self.last_law: LawSolution | None = None
        self.last_problem: LawProblem | None = None
        self.native_result: NativeLawMirror | None = None  # the last step's, when native

    def twin(self) -> NullSpaceResolver:
        """Return a resolver of the same settings (the law keeps no warm start)."""
        return NullSpaceResolver(eig_tol=self.eig_tol, internal_forces=self.internal_forces,
                                 method=self.method, zones=self.zones)

    def reset(self) -> None:
        """Nothing to reset: the law keeps no warm start."""

    def solve(self, model: RobotModel, layout: Layout, stack: Stack, built: BuiltStack,
              t: float, notes: list[str]) -> tuple[np.ndarray, np.ndarray] | None:
        """Apply the law to the built stack: ``(x, tau)``, or ``None`` for the safe command."""
        self.native_result = None
        self.last_law = None
        self.zone_state = ZoneState()
        self.last_problem = problem = law_problem(built, stack, model.nv)

        def apply(p: LawProblem) -> LawSolution:
            return self._law(model, stack, p)

        contacts = []
        if self.zones.support is not None and problem.support is not None:
            contacts = [task for task in (stack.task(n) for n in stack.active_contacts)
                        if hasattr(task, "frame")]
        try:
            law = apply(problem)
            law, problem = constraint_zones(law, problem, model, contacts,  # type: ignore[arg-type]
                                            self.zones, self.zone_state, apply, notes)
            self.last_problem = problem
        except (HQPError, np.linalg.LinAlgError) as exc:
            notes.append(f"law failed: {exc}")
            logger.warning("t=%.4f: null-space law failed (%s); safe command sent", t, exc)
            return None
        self.last_law = law
        if not (np.all(np.isfinite(law.tau)) and np.all(np.isfinite(law.qdd))):
            notes.append("law returned non-finite values")
            return None
        return decision_vector(model, layout, stack, law, problem), law.tau.copy()

    def _law(self, model: RobotModel, stack: Stack, problem: LawProblem) -> LawSolution:
        """Apply :func:`prioritized_torques` to the law's view of the stack."""
        m = model
        return prioritized_torques(
            m.M, m.h, problem.levels,
            S=m.selection() if m.nv_base else None,
            support=problem.support, names=problem.names, eig_tol=self.eig_tol,
            internal_forces="none" if self.internal_forces == "none" else "min-norm",
            method=self.method,
            support_weights=(utilization_weights(m, stack, problem)
                             if self.internal_forces == "balanced" else None),
        )

    def native(self, mirror: NativeLawMirror) -> None:
        """Record a native step of the law (its solution and matrices copied out on demand)."""
        self.native_result = mirror
        self.last_law = self.last_problem = None
        self.zone_state = ZoneState()

    def fetch(self) -> None:
        """Copy the last native step's law and matrices out of the core (once)."""
        mirror = self.native_result
        if mirror is not None:
            self.last_law, self.last_problem = mirror.law_solution(), mirror.law_problem()
            self.native_result = None

    def report(self, built: BuiltStack, x: np.ndarray | None, notes: list[str],
               diagnostics: Diagnostics) -> tuple[tuple[TaskStatus, ...], tuple[float, ...]]:
        """Statuses from the law's eigenvalues (eq. 22) and level costs at the law's ``x``."""
        law, problem = self.last_law, self.last_problem
        if x is None or law is None or problem is None:
            return (), ()
        statuses = diagnostics.law_statuses(built, problem, law, x)
        notes.extend(problem.skipped)
        return statuses, tuple(level_cost(level, x) for level in built.levels)


class NullSpaceController(WholeBodyController):
    """The papers' null-space torque law behind the HQP controller's interface.

    The servo of :class:`~hqp.control.servo.WholeBodyController` with a
    :class:`NullSpaceResolver`: the task rows of the stack become the law's levels, solved by
    :func:`prioritized_torques`. A task's ``TaskStatus.sigma_min`` holds the smallest
    eigenvalue of its own ``Lambda_task|prec(level)^-1`` (eq. 16, 22); inequality rows
    (friction, torque and viable joint limits) are not enforced by the law, only reported. The
    per-level eigenvalues of the last step are in ``last_law.levels``.

    Args:
        robot_model: The controller's robot model.
        contacts: Contacts to declare (as for the HQP controller; their limit rows are added
            only when the stack has a CONTACT_LIMITS level, they are reported, not enforced).
        stack: The levels of tasks (joint limits the papers' way: put a
            :class:`~hqp.tasks.joint_limit_zone.JointLimitZone` at the top task level).
        dt: Control period [s].
        backend: Accepted for call compatibility with the HQP controller; unused.
        algorithm: Accepted for call compatibility; unused.
        eig_tol: Relative eigenvalue threshold of eq. 22 (:data:`EIG_TOL`).
        internal_forces: ``"balanced"``, ``"min-norm"`` (default) or ``"none"``
            (:class:`NullSpaceResolver`).
        method: ``"whitened"`` or ``"literal"`` (see :func:`prioritized_torques`).
        tolerance: A task whose unweighted residual norm exceeds this is in conflict.
        singular_tolerance: Relative eigenvalue threshold of the SINGULAR status.
        damping: Joint damping of the safe command [N m s/rad].
        final_metric: Accepted for call compatibility; unused (the law's tie-break is fixed:
            least ``tau^T Phi tau``, docs/design/nullspace.md).
        final_target: Accepted for call compatibility; unused.
        diagnostics: ``"full"`` (per-task eigenvalues and ``yields_to``) or ``"residuals"``.
        support_zone: Fraction of each contact's centre-of-pressure box that bounds the
            support's centre of pressure, as an activation zone at the top of the task
            hierarchy (``None``, the default: the plain law; :mod:`hqp.control.nullspace.zones`).
        torque_zone: Fraction of the torque limits that bounds each joint's torque, as an
            activation zone at the same level (``None``, the default: the plain law).
        zone_passes: Largest number of re-applications of the law per step for the zones.
        native: Run steady steps on the law's native step
            (:mod:`hqp.control.nullspace.native`: the model pass, the rows, the law and the
            report's numbers in one call into the C++ core, the same torques as the Python law
            to rounding; the Python law runs the steps and settings it does not). ``None``
            (default): when the model comes from a bundled robot (``Robot.model()``).

    Raises:
        InvalidInput: Bad period, tolerances, ``eig_tol``, ``internal_forces``, ``method``,
            ``support_zone``, ``torque_zone`` or ``zone_passes``; ``native=True`` with a model
            that does not come from a bundled robot.

    """

    resolver: NullSpaceResolver

    def __init__(
        self,
        robot_model: RobotModel,
        contacts: Sequence[Task] = (),
        stack: Stack | None = None,
        dt: float = 0.001,
        backend: str | None = None,
        algorithm: str | None = None,
        *,
        eig_tol: float = EIG_TOL,
        internal_forces: str = "min-norm",
        method: str = "whitened",
        tolerance: float = 1e-5,
        singular_tolerance: float = 1e-6,
        damping: float = 2.0,
        final_metric: np.ndarray | None = None,
        final_target: np.ndarray | None = None,
        diagnostics: str = "full",
        support_zone: float | None = None,
        torque_zone: float | None = None,
        zone_passes: int = 4,
        native: bool | None = None,
    ) -> None:
        stack = Stack() if stack is None else stack
        # The law enforces no contact limits: declare them only where the stack has their level.
        limits = Category.CONTACT_LIMITS in stack.level_categories
        for contact in contacts:
            if contact.name not in stack.contacts:
                stack.add_contact(contact, limits=limits)
        resolver = NullSpaceResolver(eig_tol=eig_tol, internal_forces=internal_forces,
                                     method=method,
                                     zones=ZoneSettings(support_zone, torque_zone, zone_passes))
        super().__init__(robot_model, (), stack, dt, tolerance=tolerance,
                         singular_tolerance=singular_tolerance, diagnostics=diagnostics,
                         damping=damping, resolver=resolver)
        if native is None:
            native = robot_model.source is not None
        if native and robot_model.source is None:
            raise InvalidInput("NullSpaceController: native=True needs a model built by "
                               "Robot.model() (the native step loads the robot's URDF)")
        self.native = NativeLawEngine(robot_model.source) if native else None

    def _native_step(self, q: np.ndarray, v: np.ndarray, t: float, t0: float,
                     t1: float) -> Command | None:
        """Run a steady step on the law's native step (``None``: the Python law runs it).

        The servo's native hook (:meth:`WholeBodyController.step`): the model pass, the rows,
        the law and the report's numbers in one call (GIL released), the report's statuses
        from :class:`~hqp.control.diagnostics.Diagnostics`'s tolerances. The step after the
        safe command, and a step the native law cannot run, are the Python law's (the
        first blends out of the safe command; the second gets the Python law's notes).
        """
        engine = self.native
        if not isinstance(engine, NativeLawEngine) or self._was_safe:
            return None
        declared = self.stack.layout_contacts()
        if [(c.name, c.frame, c.kind) for c in self.layout.contacts] != declared:
            return None
        mirror = engine.ready(self, t)
        if mirror is None:
            return None
        # steady (ready() checked it): advancing tells contact-aware tasks the active contacts
        self.stack.advance_steady()
        if mirror.step(q, v, t):  # the Python law runs it (and notes why it fails)
            return None
        mirror.record_errors(self)
        self.model.provide(mirror.kernels.quantity)  # the core's pass at this state
        clock = time.perf_counter
        t3 = clock()
        engine.steps += 1
        x, tau = mirror.x, mirror.tau
        self._rate_ref = tau.copy()
        notes: list[str] = []
        tau, suspended = self._blend(tau, t, notes)  # a decaying-offset blend (if one runs)
        tau = self._clip(tau, notes)
        qdd, wrenches = self._split(x)
        t4 = clock()
        statuses, costs = mirror.report(self.feasibility, notes)
        if callable(statuses):  # made when first read, from the step's data
            report = FeasibilityReport(notes=notes, level_costs=costs, statuses=statuses,
                                       strictness_suspended=suspended)
        else:
            report = FeasibilityReport(tasks=statuses, notes=notes, level_costs=costs,
                                       strictness_suspended=suspended)
        t5 = clock()
        self.resolver.native(mirror)
        self.last_x = x
        self.last_t = float(t)
        self.last_tau = tau
        self._last_built = None
        self._native_levels = mirror  # type: ignore[assignment]  # built on demand
        timings = {"update": t1 - t0, "rows": 0.0, "solve": t3 - t1, "torques": t4 - t3,
                   "report": t5 - t4, "total": t5 - t0}
        return Command(tau=tau, qdd=qdd, wrenches=wrenches, report=report, safe_mode=False,
                       timings=timings, t=float(t))

    @property
    def last_law(self) -> LawSolution | None:
        """The law's solution at the last step (``None`` in safe mode)."""
        self.resolver.fetch()
        return self.resolver.last_law

    @property
    def last_problem(self) -> LawProblem | None:
        """The law's view of the last step's stack (zone rows included)."""
        self.resolver.fetch()
        return self.resolver.last_problem

    @property
    def torques_held(self) -> tuple[int, ...]:
        """Actuated joints whose torque was held at its zone's border at the last step."""
        return self.resolver.zone_state.torques_held

    @property
    def support_active(self) -> bool:
        """Whether the support zone was active at the last step."""
        return self.resolver.zone_state.support_active

    @property
    def last_cop(self) -> np.ndarray | None:
        """Centre of pressure ``(2,)`` [m] the plain law asked for at the last step."""
        return self.resolver.zone_state.cop

    @property
    def eig_tol(self) -> float:
        """Relative eigenvalue threshold of eq. 22 (settable)."""
        return self.resolver.eig_tol

    @eig_tol.setter
    def eig_tol(self, value: float) -> None:
        self.resolver.eig_tol = float(value)

    @property
    def internal_forces(self) -> str:
        """The law's internal forces (settable)."""
        return self.resolver.internal_forces

    @internal_forces.setter
    def internal_forces(self, value: str) -> None:
        self.resolver.internal_forces = value

    @property
    def method(self) -> str:
        """``"whitened"`` or ``"literal"`` (settable)."""
        return self.resolver.method

    @method.setter
    def method(self, value: str) -> None:
        self.resolver.method = value

    @property
    def support_zone(self) -> float | None:
        """Support activation zone (``None``: off; settable)."""
        return self.resolver.zones.support

    @support_zone.setter
    def support_zone(self, value: float | None) -> None:
        self.resolver.zones = replace(self.resolver.zones, support=value)

    @property
    def torque_zone(self) -> float | None:
        """Torque activation zone (``None``: off; settable)."""
        return self.resolver.zones.torque

    @torque_zone.setter
    def torque_zone(self, value: float | None) -> None:
        self.resolver.zones = replace(self.resolver.zones, torque=value)

    @property
    def zone_passes(self) -> int:
        """Largest number of re-applications of the law per step (settable)."""
        return self.resolver.zones.passes

    @zone_passes.setter
    def zone_passes(self, value: int) -> None:
        self.resolver.zones = replace(self.resolver.zones, passes=int(value))
