"""The feasibility report of a control step: one :class:`TaskStatus` per task.

A task is SATISFIED when the norm of its unweighted residual (equality residual ``A x - b``
and inequality violations ``dist(C x, [lower, upper])`` stacked) is at most ``tolerance``; in
CONFLICT otherwise, with the level it yields to; SINGULAR when satisfied but its rows,
projected on what the levels above leave free, are (nearly) rank deficient. For the HQP
solution the projection is the basis ``Z_k`` of the optimal set above; for the null-space
law, the eigenvalues of ``Lambda_k|prec(k)^-1`` (seed 003 eq. 16, 22).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

from hqp.control.command import Feasibility, TaskStatus

if TYPE_CHECKING:
    from hqp.control.nullspace.law import LawSolution
    from hqp.control.nullspace.multicontact import LawProblem
    from hqp.solver import Level, Solution
    from hqp.stack import BuiltStack, TaskSpan
    from hqp.tasks.base import Rows

MODES = ("full", "residuals")
"""Diagnostics modes: ``"full"`` (projected singular values or eigenvalues per task and the
level each conflicting task yields to: a few small SVDs per step) or ``"residuals"``
(per-task residuals only, the level's ``sigma_min``, no ``yields_to``)."""


def violation(C: np.ndarray, lower: np.ndarray | None, upper: np.ndarray | None,
              x: np.ndarray) -> np.ndarray:
    """Signed distance of ``C x`` outside ``[lower, upper]`` (0 inside)."""
    cx = C @ x
    out = np.zeros_like(cx)
    if upper is not None:
        out = np.where(cx > upper, cx - upper, out)
    if lower is not None:
        out = np.where(cx < lower, cx - lower, out)
    return out


def level_cost(level: Level, x: np.ndarray) -> float:
    """Return ``||A x - b||^2 + ||dist(C x, [lower, upper])||^2`` of a solver level at ``x``."""
    cost = 0.0
    if level.A is not None:
        cost += float(np.sum((np.asarray(level.A) @ x - np.asarray(level.b)) ** 2))
    if level.C is not None:
        cost += float(np.sum(violation(np.asarray(level.C), level.lower, level.upper, x) ** 2))
    return cost


def null_basis(M: np.ndarray, rank_tol: float) -> np.ndarray:
    """Orthonormal basis ``(r, r - rank)`` of the null space of ``M`` ``(m, r)``.

    Pivoted QR of ``M^T`` (``M^T P = Q R``): the last ``r - rank`` columns of ``Q`` span the
    null space, the rank read on ``|diag R|`` against ``rank_tol`` times its largest entry.
    """
    m, r = M.shape
    if m == 0 or r == 0:
        return np.eye(r)
    Q, R, _ = scipy.linalg.qr(M.T, pivoting=True, mode="full", check_finite=False)
    d = np.abs(np.diag(R))
    if d.size == 0 or d[0] == 0.0:
        return np.eye(r)
    rank = int(np.sum(d > rank_tol * d[0]))
    return Q[:, rank:]


def reachable(A: np.ndarray, r0: np.ndarray, Z: np.ndarray, scale: float) -> float:
    """``min_y ||r0 + A Z y||``: the residual left once moved within ``x + Z y``.

    The part of ``r0`` in the range of ``A Z`` is removed, the rank decided against ``scale``
    (that of ``A``, not of ``A Z``, which vanishes where the task is blocked).
    """
    if Z.shape[1] == 0:
        return float(np.linalg.norm(r0))
    U, sv, _ = np.linalg.svd(A @ Z, full_matrices=False)
    U = U[:, sv > 1e-9 * scale]
    return float(np.linalg.norm(r0 - U @ (U.T @ r0)))


def bisect_blocked(blocked: Callable[[int], bool], k: int) -> int:
    """First ``j`` in ``[-1, k)`` with ``blocked(j)`` (monotone), or ``k`` when none."""
    lo, hi = -1, k  # answer in [lo, hi]
    while lo < hi:
        mid = (lo + hi) // 2
        if blocked(mid):
            hi = mid
        else:
            lo = mid + 1
    return lo


class Diagnostics:
    """Per-task feasibility of a step, from the unweighted rows of each task at the solution.

    Args:
        tolerance: A task whose unweighted residual norm exceeds this is in conflict.
        singular_tolerance: Threshold of the SINGULAR status (absolute on the HQP's projected
            singular values; relative to the task's unprojected largest eigenvalue for the law).
        mode: One of :data:`MODES`.

    """

    def __init__(self, tolerance: float, singular_tolerance: float, mode: str) -> None:
        self.tolerance = float(tolerance)
        self.singular_tolerance = float(singular_tolerance)
        self.mode = mode
        self._yield_guess: dict[str, int] = {}

    @property
    def full(self) -> bool:
        """Whether per-task projections and ``yields_to`` are computed."""
        return self.mode == "full"

    # -- the HQP solution -------------------------------------------------------------------

    def hqp_statuses(self, built: BuiltStack, solution: Solution) -> tuple[TaskStatus, ...]:
        """Per-task feasibility of a solution of the strict hierarchy.

        ``Z_k`` is an orthonormal basis of the directions left free by levels ``0..k``: the
        null space of their equality rows and of their active (or violated) inequality rows,
        i.e. the face of the optimal set on which the solution lies. A task's ``sigma_min`` is
        the ``m``-th singular value of its ``m`` rows (equalities and active inequalities)
        times the basis of the levels above (0 when ``m`` exceeds the free dimension); only
        tasks with equality rows can be reported singular.
        """
        x = solution.x
        full = self.full
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
                out.append(self._hqp_status(built, span, x, Z, bases, rep.sigma_min, active_rows,
                                            rep.weak_directions))
            if full and k < len(built.levels) - 1:
                mats = []
                if level.A is not None:
                    mats.append(np.asarray(level.A))
                if level.C is not None and rep.active.size:
                    mats.append(np.asarray(level.C)[rep.active])
                if mats:
                    Z = Z @ null_basis(np.vstack(mats) @ Z, rank_tol)
                bases.append(Z)
        return tuple(out)

    def _hqp_status(self, built: BuiltStack, span: TaskSpan, x: np.ndarray, Z: np.ndarray,
                    bases: list[np.ndarray], level_sigma: float,
                    active_rows: set[int], weak: int = 0) -> TaskStatus:
        """Status of one task: its residual at ``x``, its rows projected on ``Z`` (levels above)."""
        rows = built.rows[span.name]
        parts = []
        mats = []
        if rows.A is not None:
            parts.append(rows.A @ x - rows.b)
            mats.append(rows.A)
        if rows.C is not None:
            viol = violation(rows.C, rows.lower, rows.upper, x)
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
        elif self.full:
            P = np.vstack(mats) @ Z
            m_rows = P.shape[0]
            if m_rows > P.shape[1]:
                sigma = 0.0
            else:
                sv = np.linalg.svd(P, compute_uv=False)
                sigma = float(sv[m_rows - 1]) if sv.size >= m_rows else 0.0
        else:
            sigma = float(level_sigma)
        status = self.classify(residual, sigma, rows.A is not None)
        yields_to = None
        if status is Feasibility.CONFLICT and self.full:
            yields_to = self._yields_to(rows, r, bases, built, span)
        return TaskStatus(span.name, span.level, status, residual, yields_to, sigma, weak)

    def classify(self, residual: float, sigma: float, equalities: bool) -> Feasibility:
        """Return the status of a task from its unweighted residual norm and ``sigma_min``.

        Args:
            residual: Norm of the task's residual at the solution.
            sigma: Its projected smallest singular value (``nan``: not computed).
            equalities: Whether it has equality rows (only those can be singular).

        """
        if residual > self.tolerance:
            return Feasibility.CONFLICT
        if equalities and np.isfinite(sigma) and sigma < self.singular_tolerance:
            return Feasibility.SINGULAR
        return Feasibility.SATISFIED

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

        # The reachable residual grows with j: check the last answer and its neighbour first
        # (one or two evaluations at steady state), then bisect.
        k = span.built_level
        tol = self.tolerance

        def blocked(j: int) -> bool:  # j = -1: the whole space
            Z = np.eye(A.shape[1]) if j < 0 else bases[j]
            return reachable(A, r0, Z, scale) > tol

        guess = self._yield_guess.get(span.name)
        if guess is not None and -1 <= guess < k:
            if blocked(guess) and (guess == -1 or not blocked(guess - 1)):
                first = guess
            elif guess + 1 < k and not blocked(guess) and blocked(guess + 1):
                first = guess + 1
            else:
                first = bisect_blocked(blocked, k)
        else:
            first = bisect_blocked(blocked, k)
        self._yield_guess[span.name] = first
        if first == -1:
            return None
        if first < k:
            return built.level_index[first]
        return span.level

    # -- the null-space law -----------------------------------------------------------------

    def law_statuses(self, built: BuiltStack, problem: LawProblem, law: LawSolution,
                     x: np.ndarray) -> tuple[TaskStatus, ...]:
        """Per-task feasibility of the law: residuals at ``x``, eigenvalues of ``Lambda^-1``.

        A task's ``sigma_min`` is the smallest eigenvalue of its own
        ``Lambda_task|prec(level)^-1`` (eq. 16, 22); it is SINGULAR when that eigenvalue is
        below ``singular_tolerance`` times the largest eigenvalue of its unprojected
        ``Lambda^-1``.
        """
        full = self.full
        out = []
        for span in built.spans:
            rows = built.rows[span.name]
            parts = []
            if rows.A is not None:
                parts.append(rows.A @ x - rows.b)
            if rows.C is not None:
                parts.append(violation(rows.C, rows.lower, rows.upper, x))
            residual = float(np.linalg.norm(np.concatenate(parts))) if parts else 0.0
            eig_min = float("nan")
            singular = False
            entry = problem.task_rows.get(span.name)
            if entry is not None and full:
                k, J, _ = entry
                Jh = J @ law.whiten
                ref = float(np.linalg.norm(Jh, 2)) ** 2
                eig = np.linalg.eigvalsh(law.inverse_inertia(J, k))  # ascending, (m,)
                eig_min = float(max(eig[0], 0.0))
                singular = eig_min < self.singular_tolerance * ref
            elif entry is not None:
                k = entry[0]
                eig_min = law.levels[k].eig_min
            yields_to = None
            if residual > self.tolerance:
                status = Feasibility.CONFLICT
                if entry is not None and full:
                    yields_to = self._law_yields_to(entry, law, problem, built, span.level)
            elif singular:
                status = Feasibility.SINGULAR
            else:
                status = Feasibility.SATISFIED
            out.append(TaskStatus(span.name, span.level, status, residual, yields_to, eig_min))
        return tuple(out)

    def _law_yields_to(
        self,
        entry: tuple[int, np.ndarray, np.ndarray],
        law: LawSolution,
        problem: LawProblem,
        built: BuiltStack,
        own_level: int,
    ) -> int | None:
        """Highest level whose null space leaves the task's residual above the tolerance.

        The residual reachable from the law's ``qdd`` by torques the levels ``0..j`` leave free
        is ``min_y ||r + J W Z_{j+1} y||`` (whitened bases of eq. 19); the first ``j`` where it
        exceeds the tolerance is the level the task yields to (the physics level when the
        support alone blocks it), its own level when only tasks of its level block it, and
        ``None`` when no torque at all can meet it.
        """
        k, J, a = entry
        if not law.bases:  # method="literal" keeps projectors, not bases
            return None
        r0 = J @ law.qdd - a
        Jh = J @ law.whiten
        scale = max(1.0, float(np.abs(Jh).max(initial=0.0)))
        if reachable(Jh, r0, law.bases[0], scale) > self.tolerance:
            if problem.support is not None:
                r_free = np.linalg.lstsq(J, -r0, rcond=None)[0]
                if np.linalg.norm(r0 + J @ r_free) <= self.tolerance:
                    return built.level_index[0]
            return None
        for j in range(k):
            if reachable(Jh, r0, law.bases[j + 1], scale) > self.tolerance:
                return built.level_index[problem.built_levels[j]]
        return own_level
