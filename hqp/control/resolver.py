"""Resolvers: what turns the built levels of a step into ``x = [qdd | f]`` and torques.

The servo (:class:`~hqp.control.servo.WholeBodyController`) builds the levels, calls its
resolver, and does the rest of the step (safe command, torque blending, clipping, report)
itself. :class:`HQPResolver` solves the strict hierarchy of QPs;
:class:`~hqp.control.nullspace.resolver.NullSpaceResolver` applies the papers' null-space law
to the same levels. Torques follow from ``x`` through the actuated rows of
``M qdd + h = S^T tau + J_c^T f``.
"""

from __future__ import annotations

import copy
import logging
from typing import TYPE_CHECKING, Protocol

import numpy as np

from hqp.errors import HQPError
from hqp.solver import HierarchicalSolver, available_backends
from hqp.tasks.dynamics import joint_torques

if TYPE_CHECKING:
    from hqp.control.command import TaskStatus
    from hqp.control.diagnostics import Diagnostics
    from hqp.model import RobotModel
    from hqp.model.layout import Layout
    from hqp.solver import Level, Solution
    from hqp.stack import BuiltStack, Stack

logger = logging.getLogger(__name__)


class Resolver(Protocol):
    """What a servo calls once per step (and once more for the hierarchy of a blend)."""

    backend: str
    algorithm: str

    def solve(self, model: RobotModel, layout: Layout, stack: Stack, built: BuiltStack,
              t: float, notes: list[str]) -> tuple[np.ndarray, np.ndarray] | None:
        """``(x (n,), tau (na,))`` of the built levels, or ``None`` (reason in ``notes``)."""

    def report(self, built: BuiltStack, x: np.ndarray | None, notes: list[str],
               diagnostics: Diagnostics) -> tuple[tuple[TaskStatus, ...], tuple[float, ...]]:
        """Per-task statuses and per-level costs of the last solve (``x`` None: safe mode)."""

    def reset(self) -> None:
        """Forget warm starts (the layout changed)."""

    def twin(self) -> Resolver:
        """Return a resolver of the same kind with its own warm starts (for a blend)."""


def finite_level(level: Level) -> bool:
    """Whether a stack-built level's matrices and bounds are free of NaN (bounds may be inf)."""
    for value in (level.A, level.b, level.C):
        if value is not None and not np.isfinite(np.sum(value)):
            return False
    for value in (level.lower, level.upper):
        if value is not None and np.isnan(value).any():
            return False
    return True


class HQPResolver:
    """The strict hierarchy of QPs, with retries on fallback backends (:meth:`fallbacks`).

    Args:
        backend: QP backend of the solver (``"proxsuite"``, ``"osqp"``, ``"daqp"``,
            ``"quadprog"``, ``"native"``).
        algorithm: Hierarchical algorithm (``"basis"`` or ``"cascade"``).
        final_metric: Metric ``(n, n)`` of the final tie-break (``None``: identity).
        final_target: Target ``(n,)`` of the final tie-break (``None``: zero).

    Raises:
        UnknownBackend: Unknown backend.

    """

    def __init__(self, backend: str = "proxsuite", algorithm: str = "basis", *,
                 final_metric: np.ndarray | None = None,
                 final_target: np.ndarray | None = None) -> None:
        self.backend = backend
        self.algorithm = algorithm
        self.solver = HierarchicalSolver(backend, algorithm)
        self.final_metric = final_metric
        self.final_target = final_target
        self.last_solution: Solution | None = None
        self._fallbacks: list[HierarchicalSolver] = []  # shared with twins (filled in place)

    def twin(self) -> HQPResolver:
        """Return a resolver of the same backend and tie-break with its own solver."""
        other = copy.copy(self)
        other.solver = HierarchicalSolver(self.backend, self.algorithm)
        other.last_solution = None
        return other

    def reset(self) -> None:
        """Reset the primary solver's warm starts."""
        if hasattr(self.solver, "reset"):
            self.solver.reset()

    def fallback(self) -> HierarchicalSolver | None:
        """Return the first fallback solver (see :meth:`fallbacks`), or ``None`` if none."""
        chain = self.fallbacks()
        return chain[0] if chain else None

    def fallbacks(self) -> list[HierarchicalSolver]:
        """Return the solvers tried in turn where the primary fails (created once).

        DAQP (an exact active-set method) backs up the other backends, quadprog backs up
        DAQP. The native solver is backed up by DAQP, quadprog, then the cascade algorithm on
        DAQP, found on the thin feasible sets of conflicts (issue 17): in ``hqp compare
        box-grab`` on the native step, quadprog's dual method solved levels where the
        native solver and DAQP both failed; at a screwgun step (t = 1.878 s) the basis
        algorithm failed on every backend but ProxQP while the cascade solved it on DAQP and
        on quadprog (``tests/data/thin_set_levels.npz``). A step none of them solves gets
        the safe command.
        """
        if not self._fallbacks:
            chain = {"daqp": (("quadprog", self.algorithm),),
                     "native": (("daqp", "basis"), ("quadprog", "basis"), ("daqp", "cascade"))
                     }.get(self.backend, (("daqp", self.algorithm),))
            self._fallbacks.extend(HierarchicalSolver(name, algorithm)
                                   for name, algorithm in chain if name in available_backends())
        return self._fallbacks

    def solve(self, model: RobotModel, layout: Layout, stack: Stack, built: BuiltStack,
              t: float, notes: list[str], *,
              failed: str | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """Solve the built levels: ``(x, tau)``, or ``None`` (reason in ``notes``) for safe mode.

        The primary solver first, then :meth:`fallbacks` in turn, each failure noted.
        ``failed``: why the native step's solve of these same levels failed (the controller's
        native step, whose rows are the Python rows to rounding). With the ``"native"``
        backend the fallbacks are then tried first and this resolver's own native solver
        (the same C++ solver, warm started from another memory) only after them: a failed
        native solve has already spent its retries (its QP's iterations are capped), and
        DAQP solves such levels quickly (tests/data/thin_set_levels.npz).
        """
        self.last_solution = None
        failure = ""
        chain = [self.solver, *self.fallbacks()]
        if failed is not None and self.backend == "native":
            chain, failure = chain[1:] + chain[:1], f"native step: {failed}"
        for solver in chain:
            if failure:
                notes.append(f"{failure}; solved again with backend {solver.backend_name!r}")
                logger.info("t=%.4f: %s; retrying with %s", t, failure, solver.backend_name)
            try:
                # the stack builds float arrays of consistent shapes: only finiteness is
                # left to check (one reduction per level), not the user-input validation
                if not all(finite_level(level) for level in built.levels):
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
        tau = joint_torques(model, layout, x)
        if not np.all(np.isfinite(tau)):
            notes.append("non-finite torques")
            return None
        return x, tau

    def report(self, built: BuiltStack, x: np.ndarray | None, notes: list[str],
               diagnostics: Diagnostics) -> tuple[tuple[TaskStatus, ...], tuple[float, ...]]:
        """Statuses from the projections of the optimal sets; the solver's level costs."""
        solution = self.last_solution
        if solution is None:
            return (), ()
        statuses = () if x is None else diagnostics.hqp_statuses(built, solution)
        return statuses, tuple(lv.cost for lv in solution.levels)
