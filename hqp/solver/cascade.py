"""The plain cascade (the baseline): every level one QP over the full ``x``.

Each level is one QP over ``x`` and the level's slacks, earlier levels held as
constraints: equality rows at their values at the current point (which lies in their
optimal set, so redundant rows stay consistent under the QP tolerance) and inequality
rows with bounds widened to contain their optimal violation (``C x - w* in [l, u]``).
Only linearly independent equality rows are held (active-set backends need it, and
redundant rows mislead ProxQP's infeasibility detection). Same backend, same persistent
per-level QPs and the same active-set warm start as :mod:`hqp.solver.basis`, so that
comparisons are fair.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np
from scipy.linalg import lapack

from hqp.errors import SolverFailure
from hqp.solver.active_set import Guess, LevelRows, guess_from_point, solve_guess
from hqp.solver.backends import QPBackend
from hqp.solver.basis import FIX_TOL
from hqp.solver.carried import Carried, inequality_offsets
from hqp.solver.level import CheckedLevel, Internal
from hqp.solver.linalg import weak_filter
from hqp.solver.qp import QPBuffers, solve_qp
from hqp.solver.warm import ACTIVE_TOL, POLISH_ITER, WarmStart

logger = logging.getLogger(__name__)

_dgeqp3 = lapack.dgeqp3
_dorgqr = lapack.dorgqr


class CascadeAlgorithm:
    """The cascade with its persistent state (warm start, QP buffers).

    Args:
        backend: The QP backend of every level.
        rank_tol: Relative rank threshold (of the warm start's factorisations).
        warm_start: Use the active-set warm start and polishing (:mod:`hqp.solver.warm`).

    """

    def __init__(self, backend: QPBackend, rank_tol: float, warm_start: bool) -> None:
        self.backend = backend
        self.rank_tol = rank_tol
        self.warm_start = warm_start
        self.memory = WarmStart()
        self.buffers = QPBuffers(level_rows_first=False)

    def reset(self) -> None:
        """Forget the warm start's memory."""
        self.memory.reset()

    def solve(
        self, all_levels: list[tuple[CheckedLevel, int]], n: int
    ) -> tuple[np.ndarray, int, list[float]]:
        """Solve the levels (the internal final ones included).

        Returns:
            ``(x, QP count, seconds per level, weak directions per user level)``.

        """
        x = np.zeros(n)
        E = np.zeros((0, n))  # held equality rows of earlier levels (independent)
        Q = np.zeros((n, 0))  # orthonormal basis of their span
        carried = Carried(n)  # held inequality rows of earlier levels
        offsets, total_in = inequality_offsets(all_levels)
        times: list[float] = []
        weak: list[int] = []
        # for the weak-direction filter only: the basis algorithm's fixed rows (equalities and
        # violated rows), whose null space is its Z
        filtering = any(lv.weak > 0.0 for lv, _kind in all_levels)
        F, QF = E, Q
        qp_count = 0
        for k, (lv, kind) in enumerate(all_levels):
            t0 = time.perf_counter()
            b, count = lv.b, 0
            if lv.weak > 0.0 and kind == Internal.NONE and lv.m_eq:
                # the weak directions of A on the null space of the fixed rows above (the
                # basis algorithm's Z)
                Ap = lv.A - (lv.A @ QF) @ QF.T
                rhs = lv.b - lv.A @ x
                # (from the minimum-norm point QF QF^T x of the optimal set above)
                centred = lv.b - lv.A @ (QF @ (QF.T @ x))
                rhs, count = weak_filter(Ap, rhs, lv.weak, self.rank_tol, lv.a_scale, centred)
                b = rhs + lv.A @ x
            if kind == Internal.NONE:
                weak.append(count)
            if lv.m_eq + lv.m_in:
                x, used_qp = self._level(k, lv, b, x, E, carried, total_in, n)
                qp_count += used_qp
                if lv.m_eq:
                    E, Q = append_independent(E, Q, lv.A)
                if filtering:
                    fixed = lv.A
                    if lv.m_in:
                        cx = lv.C @ x
                        viol = (cx > lv.upper + FIX_TOL * lv.up_scale) | (
                            cx < lv.lower - FIX_TOL * lv.lo_scale)
                        fixed = np.vstack([lv.A, lv.C[viol]])
                    if fixed.shape[0]:
                        F, QF = append_independent(F, QF, fixed)
                if lv.m_in:
                    keep = lv.bounded
                    carried.add(lv.C[keep], lv.C[keep] @ x, lv.lower[keep], lv.upper[keep],
                                lv.lo_scale[keep], lv.up_scale[keep],
                                offsets[k] + np.flatnonzero(keep))
            times.append(time.perf_counter() - t0)
        return x, qp_count, times, weak

    def _level(self, k: int, lv: CheckedLevel, b: np.ndarray, x: np.ndarray, E: np.ndarray,
               carried: Carried, total_in: int, n: int) -> tuple[np.ndarray, bool]:
        """Solve level ``k`` (target ``b``); return its optimum and whether a QP ran."""
        A, C = lv.A, lv.C
        mi = C.shape[0]
        p = carried.count
        q = E.shape[0]
        slot = ("cascade", k)
        rows = LevelRows(A, b, C, lv.lower, lv.upper, lv.lo_scale, lv.up_scale)
        held = carried.rows()
        held_or_none = held if p else None
        Eh = E if q else None
        eh = E @ x if q else None
        scale = max(lv.a_scale, lv.c_scale)
        v = None
        ok = True
        ws = self.warm_start and self.memory.use(slot)
        if ws:
            # the same active-set warm start as the basis algorithm (full x)
            guess = self.memory.guess(slot, mi, carried.gid, total_in, n)
            if guess is None:
                guess = Guess(np.zeros(mi, dtype=np.int8), np.zeros(p, dtype=np.int8))
                ref = x
            else:
                ref = self.memory.points[slot]
            v, guess, _its = solve_guess(rows, held_or_none, guess, self.rank_tol, scale,
                                         E=Eh, e=eh, ref=ref)
        used_qp = v is None
        if v is None:
            v, ok = self._qp(slot, lv, b, n, E, x, carried.G, carried.gl, carried.gu)
            if ws and np.isfinite(v).all():
                xq = v[:n]
                guess = guess_from_point(C @ xq if mi else None, rows,
                                         carried.G @ xq if p else None, held, ACTIVE_TOL)
                xp, guess2, _its = solve_guess(rows, held_or_none, guess, self.rank_tol,
                                               scale, E=Eh, e=eh, max_iter=POLISH_ITER, ref=xq)
                if xp is not None:
                    v, guess, ok = xp, guess2, True
                else:
                    self.memory.failed(slot)
        if ws:
            self.memory.remember(slot, guess, carried.gid, total_in, v[:n].copy())
        if not ok:
            logger.debug("level %d: backend %s did not converge", k, self.backend.name)
        if not np.all(np.isfinite(v)):
            raise SolverFailure(
                f"level {k}: backend {self.backend.name!r} returned a non-finite solution"
            )
        x = v[:n].copy()
        if p:
            carried.contain(carried.G @ x)
        return x, used_qp

    def _qp(
        self, slot: Any, lv: CheckedLevel, b: np.ndarray, n: int, E: np.ndarray, x: np.ndarray,
        G: np.ndarray, gl: np.ndarray, gu: np.ndarray,
    ) -> tuple[np.ndarray, bool]:
        """Solve the cascade's level QP (target ``b``) over ``(x, slacks)``."""
        A, C = lv.A, lv.C
        mi = C.shape[0]
        p = G.shape[0]
        q = E.shape[0]
        H, g, Cq, Eq = self.buffers.get(slot, n, mi, p, q)
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
        return solve_qp(self.backend, slot, H, g,
                        Eq if q else None, E @ x if q else None,
                        Cq if p + mi else None, lo, up)



INDEPENDENT_TOL = 1e-8
"""The cascade holds an earlier equality row only if its distance to the span
of the rows already held exceeds this fraction of its norm."""


def append_independent(
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
