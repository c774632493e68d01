"""The basis algorithm (Escande, Mansard, Wieber, IJRR 2014; Kanoun et al. 2011).

The optimal set of the levels solved so far is kept as
``{x0 + Z y : gl <= G (x0 + Z y) <= gu}`` with ``Z`` ``(n, r)`` orthonormal.
For level ``k`` with ``A_k Z``, ``C_k Z``:

1. Least squares: ``y = (A_k Z)^+ (b_k - A_k x0)`` by a pivoted QR (rank decided by
   ``rank_tol`` times the level's scale).
2. If ``x0 + Z y`` satisfies the level's and the carried inequalities, the
   level is solved: no QP. Warm, the least-squares point nearest the previous solve's
   solution (the *anchor*, ``y + (I - P) Z^T (x_prev - x0)`` with ``P`` the projector on
   the row space of ``A_k Z``) is tried first: a control loop's solution moves little from
   one step to the next, so where the previous one had slack in every inequality row, this
   point usually has it too, and the level needs no active set (an inequality-only level,
   such as the contact or joint limits, is then solved by a projection). It is accepted
   only strictly inside every bound (:func:`~hqp.solver.carried.inside`).
3. Otherwise the active set of the level's previous solve (or of the least-squares
   point), verified by the optimality conditions (:mod:`hqp.solver.active_set`), or
   else a QP in the reduced coordinates and one slack per inequality row,

       min_{y, w} ||A_k Z y - (b_k - A_k x0)||^2 + ||w||^2
       s.t.       lower_k - C_k x0 <= C_k Z y - w <= upper_k - C_k x0,
                  gl - G x0 <= G Z y <= gu - G x0,

   which is exact: for fixed ``y`` the best ``w`` is the distance of
   ``C_k x`` to its interval, so the optimal cost is the level's cost.
4. The cost is strictly convex in ``(A_k x, w)``, so the equality residual and
   every row's violation are the same at every optimum. The equality rows and
   the violated rows become equalities: ``Z`` shrinks to ``Z N`` with ``N`` the
   null space of ``[A_k Z; C_k[violated] Z]`` and ``x0`` moves to the optimum.
5. Satisfied inequality rows are carried as inequalities, their bounds widened
   to contain the optimum (which only absorbs the QP tolerance).

The C++ core (``hqp/_core/src/solver/hierarchy.cpp``) follows this module step by step;
this module is its test oracle (``tests/test_solver_native.py``).
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np

from hqp.errors import SolverFailure
from hqp.solver.active_set import (
    ABSORB_TOL,
    CarriedRows,
    Guess,
    LevelRows,
    guess_from_point,
    held_multipliers,
    solve_guess,
)
from hqp.solver.backends import QPBackend
from hqp.solver.carried import FEAS_TOL, Carried, inequality_offsets, inside, within
from hqp.solver.level import CheckedLevel, Internal
from hqp.solver.linalg import PivotedQR, weak_filter
from hqp.solver.qp import QPBuffers, solve_qp
from hqp.solver.report import sigma_level
from hqp.solver.warm import ACTIVE_TOL, POLISH_ITER, WarmStart

logger = logging.getLogger(__name__)

FIX_TOL = 1e-6
"""A row violated by more than this (times ``max(1, |bound|)``) after a level's
QP becomes an equality (shrinking the basis). Rows violated by less stay
carried inequalities with their bound widened to the optimum, which is just as
exact (a lower level cannot reduce a violation without contradicting the
level's optimality) but never pins a row that the QP's tolerance made look
violated."""


class _OptimalSet:
    """The optimal set of the levels solved so far: ``x + Z y`` within the carried rows."""

    __slots__ = ("x", "Z", "r", "carried")

    def __init__(self, n: int) -> None:
        self.x = np.zeros(n)
        self.Z: np.ndarray | None = None  # None: identity
        self.r = n
        self.carried = Carried(n)

    def project(self, M: np.ndarray) -> np.ndarray:
        """Return ``M Z`` (rows in the reduced coordinates)."""
        return M if self.Z is None else M @ self.Z

    def lift(self, y: np.ndarray) -> np.ndarray:
        """Return the point ``x + Z y``."""
        return self.x + (y if self.Z is None else self.Z @ y)

    def reduce(self, dx: np.ndarray) -> np.ndarray:
        """Return ``Z^T dx`` (a displacement in the reduced coordinates)."""
        return dx if self.Z is None else self.Z.T @ dx

    def shrink(self, null: np.ndarray) -> None:
        """Restrict the set to ``Z null``."""
        self.Z = null if self.Z is None else self.Z @ null
        self.r = self.Z.shape[1]


class BasisAlgorithm:
    """The basis algorithm with its persistent state (warm start, QP buffers).

    Args:
        backend: The QP backend of the levels that need a QP.
        rank_tol: Relative rank threshold.
        warm_start: Use the active-set warm start and polishing (:mod:`hqp.solver.warm`).
        compute_sigma: Compute ``sigma_min`` of every level (``nan`` otherwise).

    """

    def __init__(self, backend: QPBackend, rank_tol: float, warm_start: bool,
                 compute_sigma: bool) -> None:
        self.backend = backend
        self.rank_tol = rank_tol
        self.warm_start = warm_start
        self.compute_sigma = compute_sigma
        self.memory = WarmStart()
        self.buffers = QPBuffers(level_rows_first=True)
        self.needed_qp: dict[Any, tuple[int, int, int]] = {}
        self._qp_count = 0  # QPs of the current solve
        self.anchored = 0
        """Levels of the last solve whose point was the anchor's (:meth:`_anchored`)."""
        self._absorb = False  # this pass absorbs (see solve)

    def reset(self) -> None:
        """Forget the warm start's memory."""
        self.memory.reset()
        self.needed_qp.clear()

    def solve(
        self, all_levels: list[tuple[CheckedLevel, int]], n: int
    ) -> tuple[np.ndarray, list[float], int, list[float]]:
        """Solve the levels (the internal final ones included).

        A level whose QP no backend solves (a thin feasible set: carried rows active over
        a whole optimal set above it, implicit equalities the QP's dual steps report
        infeasible) sends the solve to a second pass that absorbs those rows
        (:meth:`_absorbed`). Only then: the multipliers that decide absorption come from
        one dual solution (NNLS) of a degenerate vertex, and at nearly dependent rows they
        are only as good as the dual tolerance, so a first pass that succeeds keeps the
        rows as inequalities.

        Returns:
            ``(x, sigma_min per user level, QP count, seconds per level, weak directions
            per user level)``.

        """
        self.memory.anchor, anchor = None, self.memory.anchor
        try:
            out = self._solve_pass(all_levels, n, anchor)
        except SolverFailure:
            first = self._qp_count
            self._absorb = True
            try:
                x, sigmas, count, times, weak = self._solve_pass(all_levels, n, anchor)
            finally:
                self._absorb = False
            out = x, sigmas, first + count, times, weak
        if self.warm_start:
            self.memory.anchor = out[0].copy()
        return out

    def _solve_pass(
        self, all_levels: list[tuple[CheckedLevel, int]], n: int,
        anchor: np.ndarray | None = None,
    ) -> tuple[np.ndarray, list[float], int, list[float], list[int]]:
        """One pass of :meth:`solve` (absorbing rows if ``self._absorb``) from ``anchor``."""
        if anchor is not None and anchor.shape != (n,):
            anchor = None
        opt = _OptimalSet(n)
        offsets, total_in = inequality_offsets(all_levels)
        pending: list[tuple[CheckedLevel, Any, Any, Any, int]] = []
        times: list[float] = []
        self._qp_count = 0
        self.anchored = 0
        clock = time.perf_counter
        for k, (lv, kind) in enumerate(all_levels):
            t0 = clock()
            if opt.r == 0 or lv.m_eq + lv.m_in == 0:
                if kind == Internal.NONE:
                    pending.append((lv, None, None, None, 0))
            else:
                entry = self._level(k, lv, kind, opt, offsets[k], total_in, n, anchor)
                if kind == Internal.NONE:
                    pending.append(entry)
            times.append(clock() - t0)
        # sigma_min at the solution (its active rows), from the projections above
        x = opt.x
        if self.compute_sigma:
            sigmas = [sigma_level(lv, Ak, Zb, x, fact, self.rank_tol)
                      for lv, Ak, Zb, fact, _weak in pending]
        else:
            sigmas = [float("nan")] * len(pending)
        return x, sigmas, self._qp_count, times, [entry[4] for entry in pending]

    def _level(self, k: int, lv: CheckedLevel, kind: int, opt: _OptimalSet, offset: int,
               total_in: int, n: int,
               anchor: np.ndarray | None = None) -> tuple[CheckedLevel, Any, Any, Any, int]:
        """Solve level ``k`` over ``opt`` and restrict ``opt`` to its optimal set.

        Returns:
            ``(lv, A Z, Z, factorisation of A Z)`` for the level's ``sigma_min``, and the
            number of weak directions whose target was filtered.

        """
        A, C = lv.A, lv.C
        mi = C.shape[0]
        carried = opt.carried
        Zb = opt.Z
        has_carried = carried.count > 0
        Ak = opt.project(A)
        bk = lv.b - A @ opt.x
        # a level of equality rows alone that the basis no longer reaches (A Z below the rank
        # tolerance: its rows in the span of the equalities above, absorbed rows among them)
        # has a constant cost over the feasible set: its point is x, found by least squares
        # (rank 0), never by a QP whose Hessian would be rounding noise
        inert = mi == 0 and Ak.size > 0 and float(np.abs(Ak).max()) <= self.rank_tol * lv.a_scale
        if inert:
            Ak = np.zeros_like(Ak)
        weak = 0
        if lv.weak > 0.0 and kind == Internal.NONE and lv.m_eq and not inert:
            # the weak directions' targets filtered before any step uses them (Level)
            # (measured from the minimum-norm point x - Z Z^T x of the optimal set above)
            centred = lv.b if opt.Z is None else bk + Ak @ (opt.Z.T @ opt.x)
            bk, weak = weak_filter(Ak, bk, lv.weak, self.rank_tol, lv.a_scale, centred)
        ws = self.warm_start and self.memory.use(k)
        warm = self.memory.guess(k, mi, carried.gid, total_in, n) if ws and (
            mi or has_carried) else None
        if ws:
            deferred = warm is not None and (warm.s.any() or warm.w.any()) and not inert
        else:
            deferred = (mi > 0 or has_carried) and self.needed_qp.get(k) == (
                mi, opt.r, carried.count) and not inert
        fact = None
        use_anchor = (ws and anchor is not None and kind == Internal.NONE and not inert
                      and bool(mi or has_carried))
        if deferred and not use_anchor:
            # the previous solve needed this level's inequalities: go straight
            # to its active set or its QP, skipping the least-squares point that
            # was infeasible then; the null space is computed when shrinking.
            y, null = None, None
        else:
            y, null, fact = self._least_squares(lv, kind, Ak, bk, opt)
        cx = None
        anchored = None
        if use_anchor:
            assert anchor is not None
            anchored = self._anchored(lv, opt, anchor, y, null)
        if anchored is not None:
            self.anchored += 1
            y, xl, cx = anchored
            feasible = True
            deferred = False
        else:
            if deferred:
                y, null = None, None
            xl = opt.x.copy() if y is None else opt.lift(y)
            feasible = not deferred
            if feasible:
                feasible, cx = self._feasible(lv, xl, carried)
        violated = None
        absorbed = None
        qp_point = False
        if not feasible:
            xl, qp_point, exact = self._inequalities(k, lv, Ak, bk, opt, xl, ws, warm,
                                                     total_in)
            if mi:
                cx = C @ xl
                viol = (cx > lv.upper + FIX_TOL * lv.up_scale) | (
                    cx < lv.lower - FIX_TOL * lv.lo_scale)
                if viol.any():
                    violated = viol
            if self._absorb and exact is not None and has_carried:
                absorbed = self._absorbed(*exact)
        if qp_point:
            self.needed_qp[k] = (mi, opt.r, carried.count)
        else:
            self.needed_qp.pop(k, None)
        if violated is not None or absorbed is not None:
            null = self._violated_null(lv, Ak, violated, absorbed, opt)
        elif deferred:
            null, fact = self._null(lv, kind, Ak, opt.r)
        opt.x = xl
        if null is not None:
            opt.shrink(null)
        if has_carried and qp_point:
            # (a verified active-set point is within FEAS_TOL of the carried bounds)
            carried.widen(carried.G @ opt.x)
        if mi:
            self._carry(lv, cx, violated, carried, offset)
        return lv, Ak, Zb, fact, weak

    # 1. least squares -------------------------------------------------------
    def _least_squares(
        self, lv: CheckedLevel, kind: int, Ak: np.ndarray, bk: np.ndarray, opt: _OptimalSet
    ) -> tuple[np.ndarray | None, np.ndarray | None, PivotedQR | None]:
        """Return the least-squares step ``y`` (``None``: 0), the null space of ``A Z``, the QR."""
        if kind == Internal.NORM:
            # A = I and Z orthonormal: (I Z)^+ = Z^T; nothing is left free afterwards.
            return opt.reduce(bk), np.zeros((opt.r, 0)), None
        if lv.m_eq:
            fact = PivotedQR(Ak, self.rank_tol, lv.a_scale)
            return fact.lstsq(bk), fact.null(), fact
        return None, None, None

    def _null(self, lv: CheckedLevel, kind: int, Ak: np.ndarray,
              r: int) -> tuple[np.ndarray | None, PivotedQR | None]:
        """Return the null space of ``A Z`` and its QR (a deferred level, no violated row)."""
        if kind == Internal.NORM:
            return np.zeros((r, 0)), None
        if lv.m_eq:
            fact = PivotedQR(Ak, self.rank_tol, lv.a_scale)
            return fact.null(), fact
        return None, None

    @staticmethod
    def _anchored(lv: CheckedLevel, opt: _OptimalSet, anchor: np.ndarray,
                  y: np.ndarray | None, null: np.ndarray | None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
        """Return the least-squares point nearest the anchor, if strictly inside every bound.

        ``y_a = y + N N^T Z^T (anchor - x0)`` (``N``: the null space of ``A Z``; without
        equality rows ``y = 0`` and ``N N^T = I``). Returns ``(y_a, x, C x)`` or ``None``.
        """
        d = opt.reduce(anchor - opt.x)
        if y is not None and lv.m_eq:
            assert null is not None
            d = y + null @ (null.T @ d)
        xa = opt.lift(d)
        cx = None
        if lv.m_in:
            cx = lv.C @ xa
            if not inside(cx, lv.lower, lv.upper, lv.lo_scale, lv.up_scale):
                return None
        carried = opt.carried
        if carried.count and not carried.inside(carried.G @ xa):
            return None
        return d, xa, cx

    # 2. feasibility check ---------------------------------------------------
    @staticmethod
    def _feasible(lv: CheckedLevel, xl: np.ndarray,
                  carried: Carried) -> tuple[bool, np.ndarray | None]:
        """Whether ``xl`` satisfies the level's and the carried inequalities; ``C xl``."""
        cx = None
        feasible = True
        if lv.m_in:
            cx = lv.C @ xl
            feasible = within(cx, lv.lower, lv.upper, lv.lo_scale, lv.up_scale)
        if feasible and carried.count:
            feasible = carried.contains(carried.G @ xl)
        return feasible, cx

    # 3. the level's inequalities: warm guess, QP, polish ---------------------
    def _inequalities(self, k: int, lv: CheckedLevel, Ak: np.ndarray, bk: np.ndarray,
                      opt: _OptimalSet, xl: np.ndarray, ws: bool, warm: Guess | None,
                      total_in: int) -> tuple[np.ndarray, bool, tuple | None]:
        """Solve the level with its inequalities.

        Returns:
            ``(x, qp_point, exact)``: the optimum, whether a QP ran, and where the point was
            verified on an active set, ``(guess, rows, held, y)`` (else ``None``).

        """
        x = opt.x
        carried = opt.carried
        mi = lv.m_in
        Ck = opt.project(lv.C)
        cx0 = lv.C @ x
        rows = LevelRows(Ak, bk, Ck, lv.lower - cx0, lv.upper - cx0, lv.lo_scale, lv.up_scale)
        held = carried.shifted(opt.project(carried.G), carried.G @ x)
        held_or_none = held if carried.count else None
        scale = max(lv.a_scale, lv.c_scale)
        y = None
        guess = warm
        if ws:
            y, guess = self._warm_guess(k, rows, held, held_or_none, opt, xl, warm, scale)
        ok = True
        qp_point = False
        verified = y is not None
        if y is None:
            qp_point = True
            self._qp_count += 1
            y, ok = self._qp(k, rows, held, held_or_none is not None, opt.r, mi)
            if ws and np.isfinite(y).all():
                y, guess, ok, verified = self._polish(k, rows, held, held_or_none, y, guess,
                                                      ok, scale)
        if ws:
            self.memory.remember(k, guess, carried.gid, total_in, opt.lift(y))
        if not ok:
            logger.debug("level %d: backend %s did not converge", k, self.backend.name)
        if not np.isfinite(y).all():
            raise SolverFailure(
                f"level {k}: backend {self.backend.name!r} returned a non-finite solution"
            )
        exact = (guess, rows, held, y) if verified and guess is not None else None
        return opt.lift(y), qp_point, exact

    def _warm_guess(self, k: int, rows: LevelRows, held: CarriedRows,
                    held_or_none: CarriedRows | None, opt: _OptimalSet, xl: np.ndarray,
                    warm: Guess | None, scale: float) -> tuple[np.ndarray | None, Guess]:
        """Try the previous solve's active set (or, cold, the least-squares point's), verified."""
        if warm is None:
            # cold: the least-squares point's violated rows
            ref = opt.reduce(xl - opt.x)
            gv = held.G @ ref if held_or_none is not None else None
            guess = guess_from_point(rows.C @ ref if rows.C.shape[0] else None, rows, gv, held,
                                     -FEAS_TOL)
        else:
            # warm: closest to the previous solve's point of this level
            guess = warm
            ref = opt.reduce(self.memory.points[k] - opt.x)
        y, guess, _its = solve_guess(rows, held_or_none, guess, self.rank_tol, scale, ref=ref)
        return y, guess

    def _qp(self, k: int, rows: LevelRows, held: CarriedRows, has_carried: bool, r: int,
            mi: int) -> tuple[np.ndarray, bool]:
        """Solve the level's QP in the reduced coordinates (and the level's slacks)."""
        Ak = rows.A
        H11 = Ak.T @ Ak
        g1 = Ak.T @ rows.b
        np.negative(g1, out=g1)
        if mi == 0:
            return solve_qp(self.backend, k, H11, g1, None, None,
                            held.G if has_carried else None,
                            held.gl if has_carried else None,
                            held.gu if has_carried else None, quick=not self._absorb)
        H, g, Cq = self.buffers.get(k, r, mi, held.G.shape[0], 0)[:3]
        H[:r, :r] = H11
        g[:r] = g1
        Cq[:mi, :r] = rows.C
        if has_carried:
            Cq[mi:, :r] = held.G
        lo = np.concatenate((rows.lo, held.gl))
        up = np.concatenate((rows.up, held.gu))
        v, ok = solve_qp(self.backend, k, H, g, None, None, Cq, lo, up, quick=not self._absorb)
        return v[:r], ok

    def _polish(self, k: int, rows: LevelRows, held: CarriedRows,
                held_or_none: CarriedRows | None, y: np.ndarray, guess: Guess | None,
                ok: bool, scale: float) -> tuple[np.ndarray, Guess | None, bool, bool]:
        """Polish: the QP point's active set, solved exactly if it verifies (else rest the slot).

        Returns:
            ``(y, guess, ok, verified)``.

        """
        guess = guess_from_point(rows.C @ y if rows.C.shape[0] else None, rows,
                                 held.G @ y if held_or_none is not None else None, held, ACTIVE_TOL)
        yp, guess2, _its = solve_guess(rows, held_or_none, guess, self.rank_tol, scale,
                                       max_iter=POLISH_ITER, ref=y)
        if yp is not None:
            return yp, guess2, True, True
        self.memory.failed(k)
        return y, guess, ok, False

    @staticmethod
    def _absorbed(guess: Guess, rows: LevelRows, held: CarriedRows,
                  y: np.ndarray) -> np.ndarray | None:
        """Return the carried rows active over the level's whole optimal set (``None``: none).

        Rows held with a positive multiplier (:func:`hqp.solver.active_set.held_multipliers`)
        are at their bound at every optimum of the level: they become equalities of the
        basis (and stay carried: a row whose direction the basis's rank decision keeps is
        still held by its bounds). Left as inequalities alone, they (and the rows they make
        dependent) bound a feasible set of no width in those directions for the levels
        below, which the QP backends report infeasible (the thin feasible sets of issue 17).
        Used on the second pass of :meth:`solve` only.
        """
        mu = held_multipliers(rows, held, guess, y)
        if mu is None:
            return None
        absorbed = mu > ABSORB_TOL
        return absorbed if absorbed.any() else None

    # 4. shrink the basis ----------------------------------------------------
    def _violated_null(self, lv: CheckedLevel, Ak: np.ndarray, violated: np.ndarray | None,
                       absorbed: np.ndarray | None, opt: _OptimalSet) -> np.ndarray:
        """Return the null space of ``[A Z; C[violated] Z; G[absorbed] Z]`` (fixed below)."""
        parts = [Ak] if lv.m_eq else []
        scale = lv.a_scale
        for M, sel in ((lv.C, violated), (opt.carried.G, absorbed)):
            if sel is not None:
                Mv = M[sel]
                parts.append(opt.project(Mv))
                scale = max(scale, float(np.abs(Mv).max()))
        return PivotedQR(np.concatenate(parts), self.rank_tol, scale).null()

    # 5. carry the level's satisfied rows ------------------------------------
    @staticmethod
    def _carry(lv: CheckedLevel, cx: np.ndarray, violated: np.ndarray | None,
               carried: Carried, offset: int) -> None:
        """Carry the level's bounded rows that are not violated, widened to contain ``cx``."""
        keep = lv.bounded if violated is None else lv.bounded & ~violated
        if keep.any():
            carried.add(lv.C[keep], cx[keep], lv.lower[keep], lv.upper[keep],
                        lv.lo_scale[keep], lv.up_scale[keep], offset + np.flatnonzero(keep))

