"""The per-level reports of a solution, and ``sigma_min``, the level's conditioning.

``sigma_min`` of level ``k`` is the ``m``-th singular value of ``[A_k; C_k[active]] Z``
(``m`` its rows; ``Z`` the basis of the optimal set of the levels above, as the basis
algorithm builds it): 0 for a level with more rows than free directions, ``inf`` for a
level with no equality and no active row.
"""

from __future__ import annotations

import numpy as np

from hqp.solver.level import CheckedLevel
from hqp.solver.linalg import PivotedQR, singular_values
from hqp.solver.solution import ROW_TOL, SATISFIED_COST, LevelReport

_ZERO = np.zeros(0)
_NO_ROWS = np.zeros(0, dtype=int)


def mth_singular(s: np.ndarray, m: int, r: int, thr: float) -> float:
    """Return the ``m``-th singular value of an ``(m, r)`` matrix with singular values ``s``."""
    if m == 0:
        return float("inf")
    if m > r or m > s.size:
        return 0.0
    v = float(s[m - 1])
    return v if v > thr else 0.0



def active_rows(lv: CheckedLevel, cx: np.ndarray) -> np.ndarray:
    """Rows on, or beyond, a bound (report tolerance :data:`ROW_TOL`)."""
    return (cx >= lv.upper - ROW_TOL * lv.up_scale) | (cx <= lv.lower + ROW_TOL * lv.lo_scale)


def sigma_level(
    lv: CheckedLevel,
    Ak: np.ndarray | None,
    Z: np.ndarray | None,
    x: np.ndarray,
    fact: PivotedQR | None,
    rank_tol: float,
) -> float:
    """``sigma_min`` of one level: the m-th singular value of ``[A; C_active] Z``.

    ``Ak`` is ``A Z`` (``None`` when no direction was left free: then 0, or
    ``inf`` for a level with no equality and no active row).
    """
    me = lv.m_eq
    act = active_rows(lv, lv.C @ x) if lv.m_in else None
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
        s = singular_values(M)
    elif fact is not None:
        s = fact.singular_values()
        scale = lv.a_scale
    else:
        s = singular_values(Ak)
        scale = lv.a_scale
    return mth_singular(s, m, r, rank_tol * max(float(s[0]) if s.size else 0.0, scale))


def level_report(lv: CheckedLevel, x: np.ndarray, sigma: float, weak: int = 0) -> LevelReport:
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
        weak_directions=int(weak),
    )


def sigma_recursion(levels: list[CheckedLevel], x: np.ndarray, rank_tol: float) -> list[float]:
    """``sigma_min`` of every level at a given solution (used by the cascade).

    Follows the basis algorithm's definition: ``Z`` spans the null space of the
    equality rows and violated rows of the levels above.
    """
    Z: np.ndarray | None = None
    r = x.shape[0]
    out = []
    for lv in levels:
        if r == 0:
            out.append(sigma_level(lv, None, None, x, None, rank_tol))
            continue
        Ak = lv.A if Z is None else lv.A @ Z
        out.append(sigma_level(lv, Ak, Z, x, None, rank_tol))
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
        null = PivotedQR(F if Z is None else F @ Z, rank_tol, scale).null()
        Z = null if Z is None else Z @ null
        r = Z.shape[1]
    return out
