"""DAQP's native hierarchical mode, a peer of the solver benchmark (not a backend).

DAQP solves a hierarchy of soft constraints (``break_points``): level by level
it minimises the squared violations of the rows *normalised by their norms*,
``sum_i (a_i x - b_i)^2 / ||a_i||^2``, then the norm of ``x``. That is a
different problem from the contract's (unnormalised) level costs, so the
benchmark reports its level-cost excess against the contract's solution.
"""

from __future__ import annotations

from collections.abc import Sequence
from ctypes import c_int

import daqp
import numpy as np

from hqp.solver.level import Level, check_level

_BIG = 1e30


def daqp_hierarchy_data(levels: Sequence[Level]) -> tuple:
    """Stack the levels into DAQP's hierarchical form.

    Returns:
        ``(H, f, A, bupper, blower, sense, break_points)`` with ``H = I``, ``f = 0``
        (after the last level DAQP minimises ``||x||^2``), equality rows as
        ``sense = 5`` and ``break_points = [0, end_0, end_1, ...]``.

    """
    checked = []
    n = None
    for k, lv in enumerate(levels):
        c = check_level(lv, k, n)
        if c.m_eq or c.m_in:
            n = c.A.shape[1]
        checked.append(c)
    if n is None:
        raise ValueError("daqp-hier: no level holds rows")
    rows, bu, bl, sense, bp = [], [], [], [], [0]
    for c in checked:
        if c.m_eq:
            rows.append(c.A)
            bu.append(c.b)
            bl.append(c.b)
            sense.append(np.full(c.m_eq, 5))
        if c.m_in:
            rows.append(c.C)
            bu.append(np.minimum(c.upper, _BIG))
            bl.append(np.maximum(c.lower, -_BIG))
            sense.append(np.zeros(c.m_in, dtype=int))
        if c.m_eq or c.m_in:
            bp.append(bp[-1] + c.m_eq + c.m_in)
    return (
        np.eye(n),
        np.zeros(n),
        np.ascontiguousarray(np.concatenate(rows)),
        np.concatenate(bu),
        np.concatenate(bl),
        np.concatenate(sense).astype(c_int),
        np.array(bp, dtype=np.intc),
    )


def solve_daqp_hierarchy(data: tuple) -> tuple[np.ndarray, int]:
    """Solve data from :func:`daqp_hierarchy_data`; return ``(x, exitflag)``.

    ``eps_prox = 0``: DAQP refuses hierarchies with its proximal loop.
    """
    H, f, A, bu, bl, sense, bp = data
    x, _fval, exitflag, _info = daqp.solve(H, f, A, bu, bl, sense, break_points=bp, eps_prox=0)
    return np.asarray(x, dtype=float), int(exitflag)
