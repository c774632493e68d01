"""The strict lexicographic solver: basis algorithm and plain cascade.

Both algorithms return the contract's solution (docs/architecture.md, "Contract:
the solver"): level ``k`` minimises

    ||A_k x - b_k||^2 + ||dist(C_k x, [lower_k, upper_k])||^2

over the optimal set of levels ``0..k-1``; after the last level the solver
minimises ``(x - t)^T M (x - t)`` and then ``||x||^2`` over the final optimal
set. These two final steps are run as two extra internal levels with
``A = M^{1/2}``, ``b = M^{1/2} t`` and ``A = I``, ``b = 0``.

**Basis algorithm** (Escande, Mansard, Wieber, IJRR 2014; Kanoun et al. 2011).
The optimal set of the levels solved so far is kept as
``{x0 + Z y : gl <= G (x0 + Z y) <= gu}`` with ``Z`` ``(n, r)`` orthonormal.
For level ``k`` with ``A_k Z``, ``C_k Z``:

1. Least squares: ``y = (A_k Z)^+ (b_k - A_k x0)`` by SVD (rank decided by
   ``rank_tol`` times the level's scale).
2. If ``x0 + Z y`` satisfies the level's and the carried inequalities, the
   level is solved: no QP.
3. Otherwise a QP in the reduced coordinates and one slack per inequality row,

       min_{y, w} ||A_k Z y - (b_k - A_k x0)||^2 + ||w||^2
       s.t.       lower_k - C_k x0 <= C_k Z y - w <= upper_k - C_k x0,
                  gl - G x0 <= G Z y <= gu - G x0,

   which is exact: for fixed ``y`` the best ``w`` is the distance of
   ``C_k x`` to its interval, so the optimal cost is the level's cost.
4. The cost is strictly convex in ``(A_k x, w)``, so the equality residual and
   every row's violation are the same at every optimum. The equality rows and
   the violated rows become equalities: ``Z`` shrinks to ``Z N`` with ``N`` the
   null space of ``[A_k Z; C_k[violated] Z]`` and ``x0`` moves to the optimum.
   Satisfied inequality rows are carried as inequalities, their bounds widened
   to contain the optimum (which only absorbs the QP tolerance).

**Cascade** (the baseline): each level is one QP over the full ``x`` and the
level's slacks, earlier levels held as constraints: equality rows at their
values at the current point (which lies in their optimal set, so redundant
rows stay consistent under the QP tolerance) and inequality rows with bounds
widened to contain their optimal violation (``C x - w* in [l, u]``). Only
linearly independent equality rows are held (active-set backends need it, and
redundant rows mislead ProxQP's infeasibility detection).
Same backend, same persistent per-level QPs and warm starts.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.linalg import lapack

from hqp.errors import (
    InvalidInput,
    InvalidLevel,
    SolverFailure,
    UnknownBackend,
    UnknownName,
    check_array,
)
from hqp.solver.backends import native as native_
from hqp.solver.active_set import Guess, guess_from_point, solve_guess
from hqp.solver.backends import QPBackend, make_backend
from hqp.solver.level import CheckedLevel, Level, check_level, trusted_level
from hqp.solver.linalg import PivotedQR as _PivotedQR
from hqp.solver.linalg import singular_values as _singular_values
from hqp.solver.solution import ROW_TOL, SATISFIED_COST, LevelReport, Solution

logger = logging.getLogger(__name__)

_dgeqp3 = lapack.dgeqp3
_dorgqr = lapack.dorgqr
_ZERO = np.zeros(0)
_NO_ROWS = np.zeros(0, dtype=int)

FIX_TOL = 1e-6
"""A row violated by more than this (times ``max(1, |bound|)``) after a level's
QP becomes an equality (shrinking the basis). Rows violated by less stay
carried inequalities with their bound widened to the optimum, which is just as
exact (a lower level cannot reduce a violation without contradicting the
level's optimality) but never pins a row that the QP's tolerance made look
violated."""

CARRY_MARGIN = 1e-9
"""Margin (times ``max(1, |bound|)``) added to the bounds of inequality rows
carried to lower levels, and kept when a carried bound is widened to contain
a later optimum. Rows active at a level's optimum, and above all rows left
slightly violated (below :data:`FIX_TOL`), whose violation is unique over the
optimal set, are implicit equalities: with a zero-width (or 1e-9-wide) slab
the lower levels' feasible sets are flat in those directions, ProxQP then
stalls for its whole iteration budget and DAQP reports them infeasible (real
whole-body stacks: friction-cone, torque and joint-limit rows). A lower level
can move such a row by at most this margin, i.e. raise the level's cost by at
most ``2 v m + m^2`` per row with ``v < FIX_TOL`` its violation, far inside the
contract's ``1e-6`` tolerance."""

ACTIVE_TOL = 1e-7
"""A carried row within this (times ``max(1, |bound|)``) of a bound at a
backend's QP point is held at that bound in the polishing solve."""

POLISH_ITER = 2
"""Active-set updates tried when polishing a backend's QP point."""

WARM_SKIP = 50
"""Solves of a level slot that go straight to the backend after neither the
warm-start guess nor the active set of the backend's QP point verified. On
the nearly degenerate levels of real whole-body stacks (more carried rows
held than free directions, some nearly dependent) the active-set solve is
too ill-conditioned to pass the checks, and each failed attempt costs
several factorisations; such a level usually stays so for a while."""

ALGORITHMS = ("basis", "cascade")
"""Names of the lexicographic algorithms."""

FEAS_TOL = 1e-9
"""Feasibility tolerance (times ``max(1, |bound|)``) when checking whether a
least-squares point satisfies inequalities."""



class _Internal:
    """Marker of the internal final levels (metric, minimum norm)."""

    NONE = 0
    METRIC = 1
    NORM = 2


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
                        _Internal.NORM))
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
                    _Internal.METRIC))
    out.append((CheckedLevel(eye, np.zeros(n), empty, none, none, "norm", a_scale=1.0),
                _Internal.NORM))
    return out


def _dist(cx: np.ndarray, lo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Signed distance of ``cx`` outside ``[lo, up]`` (0 inside)."""
    return np.where(cx > up, cx - up, np.where(cx < lo, cx - lo, 0.0))


def _within(
    cx: np.ndarray, lo: np.ndarray, up: np.ndarray, lo_s: np.ndarray, up_s: np.ndarray
) -> bool:
    """Whether ``lo - tol <= cx <= up + tol`` with ``tol = FEAS_TOL * scale``."""
    return bool((cx >= lo - FEAS_TOL * lo_s).all() and (cx <= up + FEAS_TOL * up_s).all())


def _widen(
    gl: np.ndarray, gu: np.ndarray, gx: np.ndarray, gls: np.ndarray, gus: np.ndarray
) -> None:
    """Widen carried bounds in place to contain ``gx``, keeping :data:`CARRY_MARGIN`.

    A bound that ``gx`` crosses (by the QP's tolerance) moves to ``gx`` plus the
    margin, so no carried row is left with a zero-width side.
    """
    below = gx < gl
    if below.any():
        gl[below] = gx[below] - CARRY_MARGIN * gls[below]
    above = gx > gu
    if above.any():
        gu[above] = gx[above] + CARRY_MARGIN * gus[above]


def _mth_singular(s: np.ndarray, m: int, r: int, thr: float) -> float:
    """Return the ``m``-th singular value of an ``(m, r)`` matrix with singular values ``s``."""
    if m == 0:
        return float("inf")
    if m > r or m > s.size:
        return 0.0
    v = float(s[m - 1])
    return v if v > thr else 0.0


def _inequality_offsets(all_levels: Sequence[tuple[CheckedLevel, Any]]) -> tuple[list[int], int]:
    """Index of each level's first inequality row among all of the hierarchy's, and their count."""
    offsets = []
    total_in = 0
    for lv, _kind in all_levels:
        offsets.append(total_in)
        total_in += lv.m_in
    return offsets, total_in


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
        self._guesses: dict[Any, tuple[np.ndarray, np.ndarray]] = {}
        self._points: dict[Any, np.ndarray] = {}
        self._warm_skip: dict[Any, int] = {}
        self._needed_qp: dict[Any, tuple[int, int, int]] = {}
        self._norm_levels: dict[int, list[tuple[CheckedLevel, int]]] = {}
        self._bufs: dict[Any, tuple[tuple[int, int, int, int], tuple[np.ndarray, ...]]] = {}
        self._native = None
        if backend == "native":
            self._native = native_.load_core().Solver(
                self.rank_tol, self.warm_start, bool(compute_sigma))

    def reset(self) -> None:
        """Forget the persistent QPs (the next solve starts cold)."""
        if self._native is not None:
            self._native.reset()
        self._backend.reset()
        self._backend.__dict__.pop("_hqp_relaxed", None)
        self._guesses.clear()
        self._points.clear()
        self._warm_skip.clear()
        self._needed_qp.clear()

    def _guess(self, slot: Any, mi: int, gid: np.ndarray, total_in: int) -> Guess | None:
        """Return the active set of the slot's previous solve, if the hierarchy's shapes held."""
        memo = self._guesses.get(slot)
        if memo is None or memo[0].size != mi or memo[1].size != total_in:
            return None
        point = self._points.get(slot)
        if point is None or point.shape != (self._n,):
            return None
        return Guess(memo[0], memo[1][gid])

    def _buffers(
        self, slot: Any, r: int, mi: int, p: int, q: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Preallocated matrices of a level QP over ``(v, w)``, ``v`` ``(r,)``, ``w`` ``(mi,)``.

        ``H`` ``(r+mi, r+mi)`` with its slack block ``I`` set, ``g`` ``(r+mi,)``,
        inequality rows ``(p+mi, r+mi)`` with the slack block ``-I`` in the last
        ``mi`` rows (the basis algorithm stacks the level's rows first: they are
        then given as ``p = 0`` rows after ``mi`` carried ones, see the caller),
        and equality rows ``(q, r+mi)``. The caller overwrites the ``v`` blocks;
        the slack blocks are never written, so the buffers are reused while the
        shapes hold (kept per slot).
        """
        key = (r, mi, p, q)
        entry = self._bufs.get(slot)
        if entry is not None and entry[0] == key:
            return entry[1]
        nv = r + mi
        H = np.zeros((nv, nv))
        H[r:, r:] = np.eye(mi)
        g = np.zeros(nv)
        Cq = np.zeros((p + mi, nv))
        if self.algorithm == "basis":
            Cq[:mi, r:] = -np.eye(mi)  # level rows first, carried rows after
        else:
            Cq[p:, r:] = -np.eye(mi)  # held rows first, level rows after
        Eq = np.zeros((q, nv))
        bufs = (H, g, Cq, Eq)
        self._bufs[slot] = (key, bufs)
        return bufs

    def _warm_slot(self, slot: Any) -> bool:
        """Whether the slot uses the warm start in this solve (see :data:`WARM_SKIP`)."""
        skip = self._warm_skip.get(slot)
        if not skip:
            return True
        if skip <= 1:
            del self._warm_skip[slot]
        else:
            self._warm_skip[slot] = skip - 1
        return False

    def _warm_failed(self, slot: Any) -> None:
        """Neither the guess nor the QP point's active set verified: rest the slot."""
        self._warm_skip[slot] = WARM_SKIP
        self._guesses.pop(slot, None)

    def _remember(self, slot: Any, guess: Guess, gid: np.ndarray, total_in: int) -> None:
        """Keep the slot's active set (carried rows by their index in the hierarchy)."""
        wmap = np.zeros(total_in, dtype=np.int8)
        if gid.size:
            wmap[gid] = guess.w
        self._guesses[slot] = (guess.s, wmap)

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
        all_levels = [(lv, _Internal.NONE) for lv in checked] + internal
        self._n = n
        if self.algorithm == "basis":
            x, sigmas, qp_count, times = self._solve_basis(all_levels, n)
        else:
            x, qp_count, times = self._solve_cascade(all_levels, n)
            sigmas = None
        if not np.all(np.isfinite(x)):
            raise SolverFailure(
                f"backend {self.backend_name!r} returned a non-finite solution "
                f"({self.algorithm} algorithm)"
            )
        if sigmas is None and self.compute_sigma:
            sigmas = _sigma_recursion(checked, x, self.rank_tol)
        reports = tuple(
            _report(lv, x, np.nan if sigmas is None else sigmas[k])
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

    # ----------------------------------------------------------------- native
    def _solve_native(self, levels: Sequence[Level], final_metric: Any, final_target: Any,
                      validate: bool, n_hint: int | None, t_start: float) -> Solution:
        """Solve on the C++ core; levels already in float64 arrays pass without a copy."""
        fast = native_.fast_rows(levels, n_hint)
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

    # ------------------------------------------------------------------ basis
    def _solve_basis(
        self, all_levels: list[tuple[CheckedLevel, int]], n: int
    ) -> tuple[np.ndarray, list[float], int, list[float]]:
        rank_tol = self.rank_tol
        backend = self._backend
        x = np.zeros(n)
        Z: np.ndarray | None = None  # None: identity
        r = n
        G = np.zeros((0, n))  # carried inequality rows
        gl = np.zeros(0)
        gu = np.zeros(0)
        gls = np.zeros(0)  # their tolerance scales
        gus = np.zeros(0)
        gid = _NO_ROWS  # their index among all inequality rows of the hierarchy
        offsets, total_in = _inequality_offsets(all_levels)
        pending: list[tuple[CheckedLevel, Any, Any, Any]] = []
        times: list[float] = []
        qp_count = 0
        clock = time.perf_counter
        for k, (lv, kind) in enumerate(all_levels):
            t0 = clock()
            A, b, C = lv.A, lv.b, lv.C
            me, mi = A.shape[0], C.shape[0]
            if r == 0 or me + mi == 0:
                if kind == _Internal.NONE:
                    pending.append((lv, None, None, None))
                times.append(clock() - t0)
                continue
            Zb = Z
            carried = G.shape[0] > 0
            Ak = A if Z is None else A @ Z
            bk = b - A @ x
            # 1. least squares on the equality rows (pivoted QR of the projected matrix)
            fact = None
            ws = self.warm_start and self._warm_slot(k)
            warm = self._guess(k, mi, gid, total_in) if ws and (
                mi or carried) else None
            if ws:
                deferred = warm is not None and (warm.s.any() or warm.w.any())
            else:
                deferred = (mi > 0 or carried) and self._needed_qp.get(k) == (mi, r, G.shape[0])
            if deferred:
                # the previous solve needed this level's inequalities: go straight
                # to its active set (3a) or its QP (3b), skipping the least-squares
                # point that was infeasible then; the null space is computed in 4.
                y = None
                null = None
            elif kind == _Internal.NORM:
                # A = I and Z orthonormal: (I Z)^+ = Z^T; nothing is left free afterwards.
                y = bk if Z is None else Z.T @ bk
                null = np.zeros((r, 0))
            elif me:
                fact = _PivotedQR(Ak, rank_tol, lv.a_scale)
                y = fact.lstsq(bk)
                null = fact.null()
            else:
                y = None  # zero
                null = None
            xl = x.copy() if y is None else x + (y if Z is None else Z @ y)
            # 2. does the least-squares point satisfy the inequalities?
            feasible = not deferred
            if mi and feasible:
                cx = C @ xl
                feasible = _within(cx, lv.lower, lv.upper, lv.lo_scale, lv.up_scale)
            if feasible and carried:
                feasible = _within(G @ xl, gl, gu, gls, gus)
            violated = None
            qp_point = False
            if not feasible:
                Gk = G if Z is None else G @ Z
                gx = G @ x
                Ck = C if Z is None else C @ Z
                cx0 = C @ x
                lo_r = lv.lower - cx0
                up_r = lv.upper - cx0
                glr = gl - gx
                gur = gu - gx
                scale = max(lv.a_scale, lv.c_scale)
                # 3a. the previous solve's active set (or the least-squares point's),
                # verified by the optimality conditions
                y = None
                if ws:
                    guess = warm
                    if guess is None:
                        # cold: the least-squares point's violated rows
                        ref = xl - x if Z is None else Z.T @ (xl - x)
                        guess = guess_from_point(Ck @ ref if mi else None, lo_r, up_r,
                                                 lv.lo_scale, lv.up_scale,
                                                 Gk @ ref if carried else None, glr, gur,
                                                 gls, gus, -FEAS_TOL)
                    else:
                        # warm: closest to the previous solve's point of this level
                        dx = self._points[k] - x
                        ref = dx if Z is None else Z.T @ dx
                    y, guess, _its = solve_guess(
                        Ak, bk, Ck, lo_r, up_r, lv.lo_scale, lv.up_scale, None, None,
                        Gk if carried else None, glr, gur, gls, gus, guess, rank_tol, scale,
                        ref=ref)
                ok = True
                if y is None:
                    # 3b. QP in the reduced coordinates (and the level's slacks)
                    qp_count += 1
                    qp_point = True
                    H11 = Ak.T @ Ak
                    g1 = Ak.T @ bk
                    np.negative(g1, out=g1)
                    if mi == 0:
                        y, ok = _qp(backend, k, H11, g1, None, None,
                                    Gk if carried else None,
                                    glr if carried else None,
                                    gur if carried else None)
                    else:
                        H, g, Cq = self._buffers(k, r, mi, G.shape[0], 0)[:3]
                        H[:r, :r] = H11
                        g[:r] = g1
                        Cq[:mi, :r] = Ck
                        if carried:
                            Cq[mi:, :r] = Gk
                        lo = np.concatenate((lo_r, glr))
                        up = np.concatenate((up_r, gur))
                        v, ok = _qp(backend, k, H, g, None, None, Cq, lo, up)
                        y = v[:r]
                    if ws and np.isfinite(y).all():
                        # polish: the QP point's active set, solved exactly if it verifies
                        guess = guess_from_point(Ck @ y if mi else None, lo_r, up_r,
                                                 lv.lo_scale, lv.up_scale,
                                                 Gk @ y if carried else None, glr, gur,
                                                 gls, gus, ACTIVE_TOL)
                        yp, guess2, _its = solve_guess(
                            Ak, bk, Ck, lo_r, up_r, lv.lo_scale, lv.up_scale, None, None,
                            Gk if carried else None, glr, gur, gls, gus, guess, rank_tol,
                            scale, max_iter=POLISH_ITER, ref=y)
                        if yp is not None:
                            y, guess, ok = yp, guess2, True
                        else:
                            self._warm_failed(k)
                if ws:
                    self._remember(k, guess, gid, total_in)
                    self._points[k] = x + (y if Z is None else Z @ y)
                if not ok:
                    logger.debug("level %d: backend %s did not converge", k, backend.name)
                if not np.isfinite(y).all():
                    raise SolverFailure(
                        f"level {k}: backend {backend.name!r} returned a non-finite solution"
                    )
                xl = x + (y if Z is None else Z @ y)
                if mi:
                    cx = C @ xl
                    viol = (cx > lv.upper + FIX_TOL * lv.up_scale) | (
                        cx < lv.lower - FIX_TOL * lv.lo_scale)
                    if viol.any():
                        violated = viol
            if qp_point:
                self._needed_qp[k] = (mi, r, G.shape[0])
            else:
                self._needed_qp.pop(k, None)
            # 4. shrink the basis: equality rows and violated rows become equalities
            if violated is not None:
                Cv = C[violated]
                E = np.concatenate((Ak, Cv if Z is None else Cv @ Z)) if me else (
                    Cv if Z is None else Cv @ Z)
                scale = max(lv.a_scale, float(np.abs(Cv).max()))
                null = _PivotedQR(E, rank_tol, scale).null()
            elif deferred:
                if kind == _Internal.NORM:
                    null = np.zeros((r, 0))
                elif me:
                    fact = _PivotedQR(Ak, rank_tol, lv.a_scale)
                    null = fact.null()
            x = xl
            if null is not None:
                Z = null if Z is None else Z @ null
                r = Z.shape[1]
            # carried rows: widen to contain x (absorbs the QP tolerance); add this level's
            if carried and qp_point:
                # (a verified active-set point is within FEAS_TOL of the carried bounds)
                _widen(gl, gu, G @ x, gls, gus)
            if mi:
                keep = lv.bounded if violated is None else lv.bounded & ~violated
                if keep.any():
                    ck = cx[keep]
                    ls = lv.lo_scale[keep]
                    us = lv.up_scale[keep]
                    G = np.concatenate((G, C[keep]))
                    gl = np.concatenate((gl, np.minimum(lv.lower[keep], ck) - CARRY_MARGIN * ls))
                    gu = np.concatenate((gu, np.maximum(lv.upper[keep], ck) + CARRY_MARGIN * us))
                    gls = np.concatenate((gls, ls))
                    gus = np.concatenate((gus, us))
                    gid = np.concatenate((gid, offsets[k] + np.flatnonzero(keep)))
            if kind == _Internal.NONE:
                pending.append((lv, Ak, Zb, fact))
            times.append(clock() - t0)
        # sigma_min at the solution (its active rows), from the projections above
        if self.compute_sigma:
            sigmas = [_sigma_level(lv, Ak, Zb, x, fact, rank_tol) for lv, Ak, Zb, fact in pending]
        else:
            sigmas = [float("nan")] * len(pending)
        return x, sigmas, qp_count, times

    # ---------------------------------------------------------------- cascade
    def _solve_cascade(
        self, all_levels: list[tuple[CheckedLevel, int]], n: int
    ) -> tuple[np.ndarray, int, list[float]]:
        backend = self._backend
        x = np.zeros(n)
        E = np.zeros((0, n))  # held equality rows of earlier levels (independent)
        Q = np.zeros((n, 0))  # orthonormal basis of their span
        G = np.zeros((0, n))  # held inequality rows of earlier levels
        gl = np.zeros(0)
        gu = np.zeros(0)
        gls = np.zeros(0)  # their tolerance scales
        gus = np.zeros(0)
        gid = _NO_ROWS  # their index among all inequality rows of the hierarchy
        offsets, total_in = _inequality_offsets(all_levels)
        rank_tol = self.rank_tol
        times: list[float] = []
        qp_count = 0
        for k, (lv, _kind) in enumerate(all_levels):
            t0 = time.perf_counter()
            A, b, C = lv.A, lv.b, lv.C
            me, mi = A.shape[0], C.shape[0]
            if me + mi == 0:
                times.append(time.perf_counter() - t0)
                continue
            p = G.shape[0]
            q = E.shape[0]
            slot = ("cascade", k)
            v = None
            ws = self.warm_start and self._warm_slot(slot)
            if ws:
                # the same active-set warm start as the basis algorithm (full x)
                guess = self._guess(slot, mi, gid, total_in)
                if guess is None:
                    guess = Guess(np.zeros(mi, dtype=np.int8), np.zeros(p, dtype=np.int8))
                    ref = x
                else:
                    ref = self._points[slot]
                xv, guess, _its = solve_guess(
                    A, b, C, lv.lower, lv.upper, lv.lo_scale, lv.up_scale,
                    E if q else None, E @ x if q else None, G if p else None, gl, gu, gls, gus,
                    guess, rank_tol, max(lv.a_scale, lv.c_scale), ref=ref)
                if xv is not None:
                    v = xv
                    ok = True
            if v is None:
                v, ok = self._cascade_qp(slot, lv, n, E, x, G, gl, gu)
                qp_count += 1
                if ws and np.isfinite(v).all():
                    xq = v[:n]
                    guess = guess_from_point(C @ xq if mi else None, lv.lower, lv.upper,
                                             lv.lo_scale, lv.up_scale, G @ xq if p else None,
                                             gl, gu, gls, gus, ACTIVE_TOL)
                    xp, guess2, _its = solve_guess(
                        A, b, C, lv.lower, lv.upper, lv.lo_scale, lv.up_scale,
                        E if q else None, E @ x if q else None, G if p else None, gl, gu,
                        gls, gus, guess, rank_tol, max(lv.a_scale, lv.c_scale),
                        max_iter=POLISH_ITER, ref=xq)
                    if xp is not None:
                        v, guess, ok = xp, guess2, True
                    else:
                        self._warm_failed(slot)
            if ws:
                self._remember(slot, guess, gid, total_in)
                self._points[slot] = v[:n].copy()
            if not ok:
                logger.debug("level %d: backend %s did not converge", k, backend.name)
            if not np.all(np.isfinite(v)):
                raise SolverFailure(
                    f"level {k}: backend {backend.name!r} returned a non-finite solution"
                )
            x = v[:n].copy()
            if p:
                gx = G @ x
                np.minimum(gl, gx, out=gl)
                np.maximum(gu, gx, out=gu)
            if me:
                E, Q = _append_independent(E, Q, A)
            if mi:
                keep = lv.bounded
                cx = C[keep] @ x
                G = np.concatenate([G, C[keep]])
                gl = np.concatenate(
                    [gl, np.minimum(lv.lower[keep], cx) - CARRY_MARGIN * lv.lo_scale[keep]])
                gu = np.concatenate(
                    [gu, np.maximum(lv.upper[keep], cx) + CARRY_MARGIN * lv.up_scale[keep]])
                gls = np.concatenate((gls, lv.lo_scale[keep]))
                gus = np.concatenate((gus, lv.up_scale[keep]))
                gid = np.concatenate((gid, offsets[k] + np.flatnonzero(keep)))
            times.append(time.perf_counter() - t0)
        return x, qp_count, times

    def _cascade_qp(
        self, slot: Any, lv: CheckedLevel, n: int, E: np.ndarray, x: np.ndarray,
        G: np.ndarray, gl: np.ndarray, gu: np.ndarray,
    ) -> tuple[np.ndarray, bool]:
        """Solve the cascade's level QP over ``(x, slacks)`` through the backend."""
        A, b, C = lv.A, lv.b, lv.C
        mi = C.shape[0]
        p = G.shape[0]
        q = E.shape[0]
        H, g, Cq, Eq = self._buffers(slot, n, mi, p, q)
        H[:n, :n] = A.T @ A
        g[:n] = A.T @ b
        np.negative(g, out=g)
        Eq[:, :n] = E
        Cq[:p, :n] = G
        Cq[p:, :n] = C
        lo = np.concatenate([gl, lv.lower])
        up = np.concatenate([gu, lv.upper])
        # Earlier equality rows are held at their values at the current point,
        # which lies in their optimal set: redundant rows stay consistent.
        return _qp(self._backend, slot, H, g,
                   Eq if q else None, E @ x if q else None,
                   Cq if p + mi else None, lo, up)


def solve(
    levels: Sequence[Level],
    backend: str = "proxsuite",
    final_metric: Any = None,
    final_target: Any = None,
    rank_tol: float = 1e-9,
    algorithm: str = "basis",
) -> Solution:
    """Solve a strict lexicographic hierarchy (docs/architecture.md, "Contract: the solver").

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
        The :class:`Solution` (``x`` of shape ``(n,)``, one report per level, timings).

    Raises:
        InvalidLevel: Malformed level (message names the level and the field).
        InvalidInput: Malformed ``final_metric``, ``final_target`` or ``rank_tol``.
        UnknownBackend: Unknown or uninstalled backend.

    """
    return HierarchicalSolver(backend=backend, algorithm=algorithm, rank_tol=rank_tol).solve(
        levels, final_metric=final_metric, final_target=final_target
    )


RETRY_MARGIN = 1e-9
"""Relative margin by which every inequality bound of a level QP is relaxed
when a backend fails on it (degenerate vertices); the retry's effect on the
costs stays well inside the contract's tolerance."""

RETRY_MARGINS = (RETRY_MARGIN, 1e-7)
"""Relaxations tried in turn when a backend fails on a level QP. Real
whole-body stacks leave feasible sets only ``CARRY_MARGIN`` thick in some
directions (implicit equalities of active friction-cone, torque and
joint-limit rows); a ``1e-7`` relaxation gives the backends a usable interior
there, at a cost change far below the contract's tolerance on such levels.
The larger relaxations are tried only while no finite point came back (an
unconverged finite iterate is kept, as before)."""


_WARNED_LAST_RESORT: set[tuple[str, Any]] = set()
"""``(backend name, QP slot)`` pairs whose fall-back to quadprog was already logged as a
warning: a controller at 1 kHz would otherwise repeat it every step of a hard phase."""


def _qp(backend: QPBackend, slot: Any, H: np.ndarray, g: np.ndarray,
        E: np.ndarray | None, e: np.ndarray | None, C: np.ndarray | None,
        lo: np.ndarray | None, up: np.ndarray | None) -> tuple[np.ndarray, bool]:
    """Call the backend; on failure retry with bounds relaxed by :data:`RETRY_MARGINS`.

    If no finite point came back at all, quadprog is tried (a warning is
    logged), then quadprog with the equality rows as boxes of width
    :data:`RETRY_MARGIN` and relaxed inequality bounds; only if that fails too
    is the non-finite point returned.

    The cost is normalised first (``H / s``, ``g / s`` with ``s`` the largest entry
    of ``H``): the minimiser does not change, and the backends' absolute
    tolerances then mean the same thing for levels of any scale.
    """
    scale = float(np.abs(H).max()) if H.size else 0.0
    if scale > 0.0 and (scale < 0.1 or scale > 10.0):
        H = H / scale
        g = g / scale
    has_in = C is not None and lo is not None and up is not None
    memo: dict[Any, list[int]] = backend.__dict__.setdefault("_hqp_relaxed", {})
    sticky = memo.get(slot) if has_in else None
    if sticky is not None:
        # this slot needed a relaxation lately: start there (see RELAX_STICKY)
        i, left = sticky
        if left <= 1:
            del memo[slot]
        else:
            sticky[1] = left - 1
        v, ok = backend.solve(slot, H, g, E, e, C, *_relaxed(lo, up, RETRY_MARGINS[i]))
        if ok:
            return v, ok
        memo.pop(slot, None)
    v, ok = backend.solve(slot, H, g, E, e, C, lo, up)
    if ok or not has_in:
        return v, ok
    for i, margin in enumerate(RETRY_MARGINS):
        if i and np.isfinite(v).all():
            break  # larger relaxations only where nothing finite came back
        logger.debug("backend %s failed on QP %s; retrying with bounds relaxed by %g",
                     backend.name, slot, margin)
        v2, ok2 = backend.solve(slot, H, g, E, e, C, *_relaxed(lo, up, margin))
        if ok2:
            memo[slot] = [i, RELAX_STICKY]
            return v2, ok2
        if not np.isfinite(v).all():
            v = v2
    if not np.isfinite(v).all():
        # Last resort (rare: nearly degenerate feasible sets of real whole-body
        # stacks): another active-set method, rather than no solution at all.
        key = (backend.name, slot)
        if key in _WARNED_LAST_RESORT:
            logger.debug("backend %s returned no finite solution on QP %s; trying quadprog",
                         backend.name, slot)
        else:
            _WARNED_LAST_RESORT.add(key)
            logger.warning("backend %s returned no finite solution on QP %s; trying quadprog "
                           "(further occurrences on this QP are logged at debug level)",
                           backend.name, slot)
        last = _last_resort()
        if last is not None:
            v2, ok2 = last.solve(slot, H, g, E, e, C, lo, up)
            if not np.isfinite(v2).all() and E is not None and E.shape[0]:
                # the cascade's held equality rows as boxes of RETRY_MARGIN
                # (nearly dependent on held inequality rows, real stacks)
                se = RETRY_MARGIN * np.maximum(1.0, np.abs(e))
                rl, ru = _relaxed(lo, up, RETRY_MARGIN) if has_in else (None, None)
                Cb = E if not has_in else np.concatenate((E, C))
                lb = e - se if not has_in else np.concatenate((e - se, rl))
                ub = e + se if not has_in else np.concatenate((e + se, ru))
                v2, ok2 = last.solve(slot, H, g, None, None, Cb, lb, ub)
            if np.isfinite(v2).all():
                return v2, ok2
    return v, False


RELAX_STICKY = 20
"""Solves of a level slot that start directly with the relaxation that last
succeeded on it. The QPs of a control loop change little from step to step: a
nearly degenerate feasible set that needed a relaxation stays so for a while,
and each failed unrelaxed attempt costs up to tens of milliseconds."""


def _relaxed(lo: np.ndarray, up: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the bounds relaxed by ``margin * max(1, |bound|)``."""
    s_lo = np.maximum(1.0, np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    s_up = np.maximum(1.0, np.abs(np.where(np.isfinite(up), up, 0.0)))
    return lo - margin * s_lo, up + margin * s_up


_LAST_RESORT: list[QPBackend] = []


def _last_resort() -> QPBackend | None:
    """Return the shared quadprog backend of :func:`_qp` (``None`` if not installed)."""
    if not _LAST_RESORT:
        try:
            _LAST_RESORT.append(make_backend("quadprog"))
        except UnknownBackend:
            return None
    return _LAST_RESORT[0]


def _active_rows(lv: CheckedLevel, cx: np.ndarray) -> np.ndarray:
    """Rows on, or beyond, a bound (report tolerance :data:`ROW_TOL`)."""
    return (cx >= lv.upper - ROW_TOL * lv.up_scale) | (cx <= lv.lower + ROW_TOL * lv.lo_scale)


def _sigma_level(
    lv: CheckedLevel,
    Ak: np.ndarray | None,
    Z: np.ndarray | None,
    x: np.ndarray,
    fact: _PivotedQR | None,
    rank_tol: float,
) -> float:
    """``sigma_min`` of one level: the m-th singular value of ``[A; C_active] Z``.

    ``Ak`` is ``A Z`` (``None`` when no direction was left free: then 0, or
    ``inf`` for a level with no equality and no active row).
    """
    me = lv.m_eq
    act = _active_rows(lv, lv.C @ x) if lv.m_in else None
    n_act = 0 if act is None else int(np.count_nonzero(act))
    m = me + n_act
    if m == 0:
        return float("inf")
    if Ak is None:
        return 0.0
    r = Ak.shape[1]
    if m > r:
        return 0.0
    if n_act:
        Ca = lv.C[act]
        M = np.concatenate((Ak, Ca if Z is None else Ca @ Z))
        scale = max(lv.a_scale, float(np.abs(Ca).max()))
        s = _singular_values(M)
    elif fact is not None:
        s = fact.singular_values()
        scale = lv.a_scale
    else:
        s = _singular_values(Ak)
        scale = lv.a_scale
    return _mth_singular(s, m, r, rank_tol * max(float(s[0]) if s.size else 0.0, scale))


def _report(lv: CheckedLevel, x: np.ndarray, sigma: float) -> LevelReport:
    """Build the level's report at the solution ``x``."""
    res = lv.A @ x - lv.b
    if lv.m_in:
        cx = lv.C @ x
        above = cx - lv.upper
        below = cx - lv.lower
        viol = np.where(above > 0.0, above, np.where(below < 0.0, below, 0.0))
        tu = ROW_TOL * lv.up_scale
        tl = ROW_TOL * lv.lo_scale
        active = np.flatnonzero((above >= -tu) | (below <= tl))
        violated = np.flatnonzero((above > tu) | (below < -tl))
    else:
        viol = _ZERO
        active = violated = _NO_ROWS
    cost = float(res @ res + viol @ viol)
    return LevelReport(
        name=lv.name,
        cost=cost,
        satisfied=cost <= SATISFIED_COST,
        active=active,
        violated=violated,
        sigma_min=float(sigma),
        residual_eq=res,
        violation_in=viol,
    )


def _sigma_recursion(levels: list[CheckedLevel], x: np.ndarray, rank_tol: float) -> list[float]:
    """``sigma_min`` of every level at a given solution (used by the cascade).

    Follows the basis algorithm's definition: ``Z`` spans the null space of the
    equality rows and violated rows of the levels above.
    """
    Z: np.ndarray | None = None
    r = x.shape[0]
    out = []
    for lv in levels:
        if r == 0:
            out.append(_sigma_level(lv, None, None, x, None, rank_tol))
            continue
        Ak = lv.A if Z is None else lv.A @ Z
        out.append(_sigma_level(lv, Ak, Z, x, None, rank_tol))
        F = lv.A
        scale = lv.a_scale
        if lv.m_in:
            cx = lv.C @ x
            viol = (cx > lv.upper + ROW_TOL * lv.up_scale) | (cx < lv.lower - ROW_TOL * lv.lo_scale)
            if viol.any():
                F = np.concatenate((F, lv.C[viol]))
                scale = max(scale, float(np.abs(lv.C[viol]).max()))
        if F.shape[0] == 0:
            continue
        null = _PivotedQR(F if Z is None else F @ Z, rank_tol, scale).null()
        Z = null if Z is None else Z @ null
        r = Z.shape[1]
    return out


INDEPENDENT_TOL = 1e-8
"""The cascade holds an earlier equality row only if its distance to the span
of the rows already held exceeds this fraction of its norm."""


def _append_independent(
    E: np.ndarray, Q: np.ndarray, A: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Append the rows of ``A`` to ``E`` that are independent of the rows held.

    The rows of ``A`` are projected off the span of the held rows, then a
    pivoted QR of the residuals picks the independent ones (distance to the
    span above :data:`INDEPENDENT_TOL` times the row's norm).

    Args:
        E: Held rows ``(q, n)``.
        Q: Orthonormal basis of their span ``(n, q)``.
        A: Candidate rows ``(m, n)``.

    Returns:
        The new ``(E, Q)``.

    """
    R = A - (A @ Q) @ Q.T if Q.shape[1] else A.copy()
    R -= (R @ Q) @ Q.T if Q.shape[1] else 0.0
    norms = np.sqrt(np.einsum("ij,ij->i", A, A))
    qr, jpvt, tau, _work, _info = _dgeqp3(np.asfortranarray(R.T))
    piv = jpvt - 1
    d = np.abs(np.diagonal(qr))
    keep = piv[: d.size][d > INDEPENDENT_TOL * np.maximum(norms[piv[: d.size]], 1e-300)]
    k = keep.size
    if k == 0:
        return E, Q
    # the first k columns of the QR's orthogonal factor span the kept residuals
    n = R.shape[1]
    a = np.array(qr[:, :k], order="F")
    Qk = _dorgqr(a, tau[:k])[0] if k <= n else a
    return np.concatenate((E, A[keep])), np.concatenate((Q, Qk[:, :k]), axis=1)
