"""The QP of one level, through a backend, with its retries, relaxations and last resort.

Both algorithms hand a level's QP over ``v`` (and the level's slacks) to
:func:`solve_qp`: the backend first; on failure the same QP with its bounds relaxed by
:data:`RETRY_MARGINS`; where nothing finite came back, quadprog. :class:`QPBuffers`
holds each slot's preallocated matrices.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from hqp.errors import UnknownBackend
from hqp.solver.backends import QPBackend, make_backend

logger = logging.getLogger(__name__)


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
"""``(backend name, QP slot)`` pairs whose fall-back to quadprog was already logged: a
controller at 1 kHz would otherwise repeat the first-time note every step of a hard phase."""

_LAST_RESORTS = [0]
"""Fall-backs to quadprog in this process (:func:`last_resort_count`)."""


def last_resort_count() -> int:
    """Return how many level QPs quadprog took over in this process.

    Each time a backend returned no finite point, relaxed retries included; a run reports
    the difference across it.
    """
    return _LAST_RESORTS[0]


def solve_qp(backend: QPBackend, slot: Any, H: np.ndarray, g: np.ndarray,
             E: np.ndarray | None, e: np.ndarray | None, C: np.ndarray | None,
             lo: np.ndarray | None, up: np.ndarray | None,
             quick: bool = False) -> tuple[np.ndarray, bool]:
    """Call the backend; on failure retry with bounds relaxed by :data:`RETRY_MARGINS`.

    If no finite point came back at all, quadprog is tried (a warning is
    logged), then quadprog with the equality rows as boxes of width
    :data:`RETRY_MARGIN` and relaxed inequality bounds; only if that fails too
    is the non-finite point returned.

    The cost is normalised first (``H / s``, ``g / s`` with ``s`` the largest entry
    of ``H``): the minimiser does not change, and the backends' absolute
    tolerances then mean the same thing for levels of any scale.

    ``quick``: the backend's cheap attempts only (:meth:`QPBackend.solve_quick`) at every
    margin, and no quadprog: for a caller that has a better remedy than the expensive
    retries (the basis algorithm's absorbing second pass).
    """
    solve = backend.solve_quick if quick else backend.solve
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
        v, ok = solve(slot, H, g, E, e, C, *_relaxed(lo, up, RETRY_MARGINS[i]))
        if ok:
            return v, ok
        memo.pop(slot, None)
    v, ok = solve(slot, H, g, E, e, C, lo, up)
    if ok or not has_in:
        return v, ok
    for i, margin in enumerate(RETRY_MARGINS):
        if i and np.isfinite(v).all():
            break  # larger relaxations only where nothing finite came back
        logger.debug("backend %s failed on QP %s; retrying with bounds relaxed by %g",
                     backend.name, slot, margin)
        v2, ok2 = solve(slot, H, g, E, e, C, *_relaxed(lo, up, margin))
        if ok2:
            memo[slot] = [i, RELAX_STICKY]
            return v2, ok2
        if not np.isfinite(v).all():
            v = v2
    if not quick and not np.isfinite(v).all():
        # Last resort (rare: nearly degenerate feasible sets of real whole-body
        # stacks): another active-set method, rather than no solution at all.
        key = (backend.name, slot)
        _LAST_RESORTS[0] += 1
        if key in _WARNED_LAST_RESORT:
            logger.debug("backend %s returned no finite solution on QP %s; trying quadprog",
                         backend.name, slot)
        else:
            _WARNED_LAST_RESORT.add(key)
            # part of normal operation on real whole-body stacks: not a warning (issue 19)
            logger.debug("backend %s returned no finite solution on QP %s; trying quadprog "
                         "(first time on this QP)", backend.name, slot)
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
    """Return the shared quadprog backend of :func:`solve_qp` (``None`` if not installed)."""
    if not _LAST_RESORT:
        try:
            _LAST_RESORT.append(make_backend("quadprog"))
        except UnknownBackend:
            return None
    return _LAST_RESORT[0]


def forget_relaxations(backend: QPBackend) -> None:
    """Forget which slots of ``backend`` needed a relaxation lately (see :data:`RELAX_STICKY`)."""
    backend.__dict__.pop("_hqp_relaxed", None)


class QPBuffers:
    """Preallocated matrices of each slot's level QP over ``(v, w)``, reused while shapes hold.

    Args:
        level_rows_first: Stack the level's inequality rows before the carried ones (the
            basis algorithm) rather than after the held ones (the cascade).

    """

    def __init__(self, level_rows_first: bool) -> None:
        self.level_rows_first = level_rows_first
        self._bufs: dict[Any, tuple[tuple[int, int, int, int], tuple[np.ndarray, ...]]] = {}

    def get(
        self, slot: Any, r: int, mi: int, p: int, q: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(H, g, Cq, Eq)`` of a level QP over ``(v, w)``, ``v`` ``(r,)``, ``w`` ``(mi,)``.

        ``H`` ``(r+mi, r+mi)`` with its slack block ``I`` set, ``g`` ``(r+mi,)``,
        inequality rows ``(p+mi, r+mi)`` with the slack block ``-I`` in the level's
        ``mi`` rows (the basis algorithm stacks the level's rows first: they are
        then given as ``p = 0`` rows after ``mi`` carried ones, see the caller),
        and equality rows ``(q, r+mi)``. The caller overwrites the ``v`` blocks;
        the slack blocks are never written, so the buffers are reused while the
        shapes hold (kept per slot).
        """
        key = (r, mi, p, q)
        entry = self._bufs.get(slot)
        if entry is not None and entry[0] == key:
            return entry[1]  # type: ignore[return-value]
        nv = r + mi
        H = np.zeros((nv, nv))
        H[r:, r:] = np.eye(mi)
        g = np.zeros(nv)
        Cq = np.zeros((p + mi, nv))
        if self.level_rows_first:
            Cq[:mi, r:] = -np.eye(mi)  # level rows first, carried rows after
        else:
            Cq[p:, r:] = -np.eye(mi)  # held rows first, level rows after
        Eq = np.zeros((q, nv))
        bufs = (H, g, Cq, Eq)
        self._bufs[slot] = (key, bufs)
        return bufs
