"""The front of the strict lexicographic solver: validation, final levels, dispatch.

Both algorithms return the contract's solution (docs/reference/contracts.md, "Contract:
the solver"): level ``k`` minimises

    ||A_k x - b_k||^2 + ||dist(C_k x, [lower_k, upper_k])||^2

over the optimal set of levels ``0..k-1``; after the last level the solver
minimises ``(x - t)^T M (x - t)`` and then ``||x||^2`` over the final optimal
set. These two final steps are run as two extra internal levels with
``A = M^{1/2}``, ``b = M^{1/2} t`` and ``A = I``, ``b = 0``
(:class:`~hqp.solver.level.Internal`).

The algorithms live in :mod:`hqp.solver.basis` (null-space basis of the optimal set,
the default) and :mod:`hqp.solver.cascade` (the baseline); the per-level QP and its
retries in :mod:`hqp.solver.qp`; the reports in :mod:`hqp.solver.report`; the
``native`` backend runs the whole basis algorithm in the C++ core.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from hqp.errors import InvalidInput, InvalidLevel, SolverFailure, UnknownName, check_array
from hqp.solver.backends import QPBackend, make_backend
from hqp.solver.backends import native as native_
from hqp.solver.basis import BasisAlgorithm
from hqp.solver.cascade import CascadeAlgorithm
from hqp.solver.level import (
    CheckedLevel,
    Internal,
    Level,
    beyond_range,
    check_level,
    trusted_level,
)
from hqp.solver.qp import forget_relaxations
from hqp.solver.report import level_report, sigma_recursion
from hqp.solver.solution import Solution

ALGORITHMS = ("basis", "cascade")
"""Names of the lexicographic algorithms."""


def _check_rank_tol(rank_tol: float) -> float:
    try:
        tol = float(rank_tol)
    except (TypeError, ValueError):
        raise InvalidInput(f"rank_tol: expected a float, got {rank_tol!r}") from None
    if not np.isfinite(tol) or tol <= 0.0 or tol >= 1.0:
        raise InvalidInput(f"rank_tol: expected 0 < rank_tol < 1, got {rank_tol!r}")
    return tol


def _check_levels(levels: Sequence[Level], n_hint: int | None) -> tuple[list[CheckedLevel], int]:
    if isinstance(levels, Level):
        raise InvalidLevel("levels: expected a sequence of Level, got a single Level")
    try:
        levels = list(levels)
    except TypeError:
        raise InvalidLevel(
            f"levels: expected a sequence of Level, got {type(levels).__name__}"
        ) from None
    n = None
    checked: list[CheckedLevel] = []
    for k, level in enumerate(levels):
        lv = check_level(level, k, n)
        if lv.A.shape[1] or lv.C.shape[1] or lv.m_eq or lv.m_in:
            n = lv.A.shape[1]
        checked.append(lv)
    if n is None:
        n = n_hint
    if n is None:
        raise InvalidLevel(
            "levels: cannot infer the number of variables n (no level holds A or C, "
            "and no final_metric or final_target was given)"
        )
    # Resize the empty levels seen before n was known.
    for k, lv in enumerate(checked):
        if lv.A.shape[1] != n and lv.m_eq == 0 and lv.m_in == 0:
            checked[k] = CheckedLevel(
                np.zeros((0, n)), lv.b, np.zeros((0, n)), lv.lower, lv.upper, lv.name
            )
    return checked, n


def _trusted_levels(levels: Sequence[Level], n_hint: int | None) -> tuple[list[CheckedLevel], int]:
    """Convert levels without checking them (``validate=False``)."""
    n = n_hint
    for lv in levels:
        for M in (lv.A, lv.C):
            if M is not None:
                n = np.shape(M)[-1]
                break
        else:
            continue
        break
    if n is None:
        return _check_levels(levels, n_hint)  # let the checks explain
    return [trusted_level(lv, n) for lv in levels], n


def _metric_sqrt(M: np.ndarray) -> np.ndarray:
    """Return ``R`` with ``R^T R = M`` for a symmetric PSD ``M`` (zero-weight rows dropped)."""
    try:
        return np.linalg.cholesky(M).T
    except np.linalg.LinAlgError:
        pass
    d, V = np.linalg.eigh(M)
    keep = d > 1e-14 * max(1.0, float(d[-1]))
    return np.sqrt(d[keep])[:, None] * V[:, keep].T


def _final_levels(
    n: int, final_metric: Any, final_target: Any
) -> list[tuple[CheckedLevel, int]]:
    """Build the internal levels of the final metric and the minimum norm."""
    target = None
    if final_target is not None:
        target = check_array(final_target, (n,), "final_target")
    eye = np.eye(n)
    empty = np.zeros((0, n))
    none = np.zeros(0)
    out: list[tuple[CheckedLevel, int]] = []
    if final_metric is None:
        if target is not None:
            out.append((CheckedLevel(eye, target, empty, none, none, "final", a_scale=1.0),
                        Internal.NORM))
    else:
        M = check_array(final_metric, (n, n), "final_metric")
        scale = max(1.0, float(np.abs(M).max()))
        if np.abs(M - M.T).max() > 1e-9 * scale:
            raise InvalidInput("final_metric: not symmetric")
        if n and np.linalg.eigvalsh(M)[0] < -1e-9 * scale:
            raise InvalidInput("final_metric: not positive semidefinite")
        R = _metric_sqrt(0.5 * (M + M.T))
        t = np.zeros(n) if target is None else target
        out.append((CheckedLevel(R, R @ t, empty, none, none, "final",
                                 a_scale=float(np.abs(R).max()) if R.size else 0.0),
                    Internal.METRIC))
    out.append((CheckedLevel(eye, np.zeros(n), empty, none, none, "norm", a_scale=1.0),
                Internal.NORM))
    return out


class HierarchicalSolver:
    """A persistent lexicographic solver (keep one per control loop).

    The backend keeps one persistent QP per level (``proxsuite``: updated and
    warm started while its dimensions hold), so repeated solves of hierarchies
    of the same shapes reuse their factorisations and active sets.

    Args:
        backend: QP backend name (see :func:`hqp.solver.available_backends`).
        algorithm: ``"basis"`` (default) or ``"cascade"`` (the baseline).
        rank_tol: Relative rank threshold for the null-space bases, ``0 < rank_tol < 1``.
        compute_sigma: Compute ``sigma_min`` in the reports (``nan`` otherwise). The
            basis algorithm reuses its projections (one small factorisation per
            level with active rows); the cascade recomputes the projections.
        warm_start: Before a level's QP, try the active set of the previous solve of
            that level (or, cold, of the least-squares point) and accept it only if
            the optimality conditions hold (:mod:`hqp.solver.active_set`); after a
            backend's QP, re-solve exactly on its active set when that verifies.
            Both algorithms use it alike. ``None`` (default): on, except for
            backends that warm start their own persistent QPs (``proxsuite``),
            whose warm-started solves cost no more than the interpreted
            active-set solve on hierarchies of a few dozen variables.

    Raises:
        UnknownBackend: Unknown or uninstalled backend.
        UnknownName: Unknown algorithm.
        InvalidInput: ``rank_tol`` out of range.

    """

    def __init__(
        self,
        backend: str = "proxsuite",
        algorithm: str = "basis",
        rank_tol: float = 1e-9,
        compute_sigma: bool = True,
        warm_start: bool | None = None,
    ) -> None:
        if algorithm not in ALGORITHMS:
            raise UnknownName("algorithm", str(algorithm), ALGORITHMS)
        if backend == "native" and algorithm != "basis":
            raise InvalidInput(
                f"algorithm {algorithm!r}: the native backend runs the basis algorithm only "
                "(the cascade is a Python baseline; use a QP backend for it)")
        self.rank_tol = _check_rank_tol(rank_tol)
        self.backend_name = backend
        self.algorithm = algorithm
        self.compute_sigma = compute_sigma
        self._backend: QPBackend = make_backend(backend)
        if warm_start is None:
            warm_start = not getattr(self._backend, "warm_started", False)
        self.warm_start = bool(warm_start)
        self._norm_levels: dict[int, list[tuple[CheckedLevel, int]]] = {}
        self._algorithm: BasisAlgorithm | CascadeAlgorithm
        if algorithm == "basis":
            self._algorithm = BasisAlgorithm(self._backend, self.rank_tol, self.warm_start,
                                             bool(compute_sigma))
        else:
            self._algorithm = CascadeAlgorithm(self._backend, self.rank_tol, self.warm_start)
        self._native = None
        if backend == "native":
            self._native = native_.load_core().Solver(
                self.rank_tol, self.warm_start, bool(compute_sigma))

    def reset(self) -> None:
        """Forget the persistent QPs (the next solve starts cold)."""
        if self._native is not None:
            self._native.reset()
        self._backend.reset()
        forget_relaxations(self._backend)
        self._algorithm.reset()

    def solve(
        self,
        levels: Sequence[Level],
        final_metric: Any = None,
        final_target: Any = None,
        *,
        validate: bool = True,
    ) -> Solution:
        """Solve the hierarchy.

        Args:
            levels: Levels, highest priority first.
            final_metric: Symmetric positive semidefinite ``(n, n)`` or ``None`` (identity).
            final_target: ``(n,)`` or ``None`` (zero).
            validate: Check every level (shapes, NaN/inf, ``lower <= upper``; the
                default). ``False`` is for levels built by code that guarantees
                them (the controller's stack): float arrays of consistent shapes
                (``None`` fields allowed), finite ``A``, ``b``, ``C``; a violation
                then gives undefined results instead of an ``HQPError``.

        Returns:
            The lexicographic optimum with one report per level.

        Raises:
            InvalidLevel: A malformed level (the message names the level and the field).
            InvalidInput: A malformed final metric or target.
            SolverFailure: A backend returned NaN or inf on a well-formed problem.

        """
        t_start = time.perf_counter()
        n_hint = None
        for value in (final_target, final_metric):
            if value is not None:
                shape = np.shape(value)
                n_hint = int(shape[0]) if len(shape) else None
        if self._native is not None:
            return self._solve_native(levels, final_metric, final_target, validate, n_hint,
                                      t_start)
        if validate:
            checked, n = _check_levels(levels, n_hint)
        else:
            checked, n = _trusted_levels(levels, n_hint)
        if final_metric is None and final_target is None:
            internal = self._norm_levels.get(n)
            if internal is None:
                internal = self._norm_levels[n] = _final_levels(n, None, None)
        else:
            internal = _final_levels(n, final_metric, final_target)
        all_levels = [(lv, Internal.NONE) for lv in checked] + internal
        sigmas: list[float] | None = None
        if isinstance(self._algorithm, BasisAlgorithm):
            x, sigmas, qp_count, times, weak = self._algorithm.solve(all_levels, n)
        else:
            x, qp_count, times, weak = self._algorithm.solve(all_levels, n)
        if not np.all(np.isfinite(x)):
            raise SolverFailure(
                f"backend {self.backend_name!r} returned a non-finite solution "
                f"({self.algorithm} algorithm)"
            )
        if sigmas is None and self.compute_sigma:
            sigmas = sigma_recursion(checked, x, self.rank_tol)
        reports = tuple(
            level_report(lv, x, np.nan if sigmas is None else sigmas[k], weak[k])
            for k, lv in enumerate(checked)
        )
        L = len(checked)
        timings = {f"level_{k}": times[k] for k in range(L)}
        timings["final"] = float(sum(times[L:]))
        timings["total"] = time.perf_counter() - t_start
        return Solution(
            x=x,
            levels=reports,
            timings=timings,
            backend=self.backend_name,
            algorithm=self.algorithm,
            qp_count=qp_count,
        )

    def _solve_native(self, levels: Sequence[Level], final_metric: Any, final_target: Any,
                      validate: bool, n_hint: int | None, t_start: float) -> Solution:
        """Solve on the C++ core; levels already in float64 arrays pass without a copy."""
        fast = native_.fast_rows(levels, n_hint)
        if fast is not None and validate and beyond_range(levels):
            fast = None  # bounds beyond BOUND_INF, entries beyond MAX_ENTRY: Python's checks
        if fast is None:
            checked, n = (_check_levels if validate else _trusted_levels)(levels, n_hint)
            rows, names = native_.checked_rows(checked), checked
            core_validate = False
        else:
            rows, n = fast
            names = levels
            core_validate = validate
        final = None
        if final_metric is not None or final_target is not None:
            internal = _final_levels(n, final_metric, final_target)
            if len(internal) == 2:
                lv, kind = internal[0]
                final = (lv.A, lv.b, kind, lv.a_scale)
        out = self._native.solve(rows, n, final, core_validate)
        if isinstance(out, int):
            native_.explain_invalid(levels, out, n)
        if isinstance(out, str):
            raise SolverFailure(f"backend 'native': {out}")
        return native_.make_solution(out, names, time.perf_counter() - t_start)

def solve(
    levels: Sequence[Level],
    backend: str = "proxsuite",
    final_metric: Any = None,
    final_target: Any = None,
    rank_tol: float = 1e-9,
    algorithm: str = "basis",
) -> Solution:
    """Solve a strict lexicographic hierarchy (docs/reference/contracts.md, "The solver").

    Level ``k`` minimises ``||A_k x - b_k||^2 + ||dist(C_k x, [lower_k, upper_k])||^2``
    over the minimisers of levels ``0..k-1``; then ``(x - final_target)^T
    final_metric (x - final_target)`` over the final optimal set, ties broken
    by minimum norm. With the defaults the result is the minimum-norm
    lexicographic optimum. An unsatisfied level is reported, not raised.

    Args:
        levels: Levels, highest priority (0) first.
        backend: QP backend: ``"proxsuite"`` (default), ``"osqp"``, ``"daqp"``, ``"quadprog"``,
            or ``"native"`` (the whole basis algorithm in the C++ core).
        final_metric: Symmetric positive semidefinite ``(n, n)``; ``None`` = identity.
        final_target: ``(n,)``; ``None`` = zero.
        rank_tol: Rank threshold relative to the largest singular value of a
            projected level matrix (or the level's largest entry, if larger).
        algorithm: ``"basis"`` (null-space basis of the optimal set, default) or
            ``"cascade"`` (one QP per level over the full ``x``, the baseline).

    Returns:
        The lexicographic optimum (``x`` of shape ``(n,)``, one report per level, timings).

    Raises:
        InvalidLevel: Malformed level (message names the level and the field).
        InvalidInput: Malformed ``final_metric``, ``final_target`` or ``rank_tol``.
        UnknownBackend: Unknown or uninstalled backend.

    """
    return HierarchicalSolver(backend=backend, algorithm=algorithm, rank_tol=rank_tol).solve(
        levels, final_metric=final_metric, final_target=final_target
    )
