"""The ``native`` backend: the whole hierarchy solved by the C++ core (``hqp._core``).

Unlike the QP backends, ``native`` is not called level by level: the basis algorithm, its
active-set warm start, the rank decisions and a compiled QP (DAQP's C sources) for the
cold and degenerate levels all run in C++ (``hqp/_core/src/solver/``), with the GIL
released, in a workspace that is allocated once per shape of the hierarchy. The Python
basis algorithm of :mod:`hqp.solver.basis` is its reference and test oracle.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from hqp.errors import InvalidLevel, SolverFailure
from hqp.solver.backends import QPBackend
from hqp.solver.level import Level, _constant, check_level
from hqp.solver.solution import LevelReport, Solution

_F64 = np.dtype(np.float64)


def load_core() -> Any:
    """Return the compiled module ``hqp._core._ext`` (``ImportError`` if it is not built)."""
    from hqp._core import _ext

    return _ext


class NativeBackend(QPBackend):
    """Registry entry of ``native``: a whole-hierarchy solver, not a per-level QP backend."""

    name = "native"

    def __init__(self) -> None:
        load_core()

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        raise SolverFailure(
            "backend 'native' solves whole hierarchies (HierarchicalSolver or solve), "
            "not single QPs")


def _is_matrix(a: Any) -> bool:
    return type(a) is np.ndarray and a.dtype == _F64 and a.ndim == 2


def _is_vector(a: Any, m: int) -> bool:
    return type(a) is np.ndarray and a.dtype == _F64 and a.shape == (m,)


def fast_rows(levels: Sequence[Level], n_hint: int | None) -> tuple[list[tuple], int] | None:
    """Return the levels as ``(A, b, C, lower, upper, weak_threshold)``, arrays without a copy.

    ``None`` when a level is not in that form already (lists, integers, a 1-D ``A``,
    ``b`` without ``A``...): the caller then converts and checks in Python.
    """
    if isinstance(levels, Level):
        return None
    n = n_hint
    for lv in levels:
        if type(lv) is not Level:
            return None
        M = lv.A if lv.A is not None else lv.C
        if M is not None:
            if not _is_matrix(M):
                return None
            n = M.shape[1]
            break
    if n is None:
        return None
    rows = []
    empty = np.zeros((0, n))
    none = _constant(0, 0.0)
    for lv in levels:
        if type(lv) is not Level:
            return None
        A, b, C, lo, up = lv.A, lv.b, lv.C, lv.lower, lv.upper
        weak = lv.weak_threshold
        if type(weak) is not float or not 0.0 <= weak < np.inf:
            if type(weak) is not int or weak < 0:
                return None
            weak = float(weak)
        if A is None:
            if b is not None:
                return None
            A = empty
            b = none
        else:
            if not _is_matrix(A):
                return None
            m = A.shape[0]
            if b is None:
                b = _constant(m, 0.0)
            elif not _is_vector(b, m):
                return None
        if C is None:
            if lo is not None or up is not None:
                return None
            C = empty
            lo = up = none
        else:
            if not _is_matrix(C):
                return None
            m = C.shape[0]
            if lo is None:
                lo = _constant(m, -np.inf)
            elif not _is_vector(lo, m):
                return None
            if up is None:
                up = _constant(m, np.inf)
            elif not _is_vector(up, m):
                return None
        rows.append((A, b, C, lo, up, weak))
    return rows, n


def checked_rows(checked: Sequence[Any]) -> list[tuple]:
    """Return ``(A, b, C, lower, upper, weak_threshold)`` of levels checked by ``check_level``."""
    return [(lv.A, lv.b, lv.C, lv.lower, lv.upper, lv.weak) for lv in checked]


def explain_invalid(levels: Sequence[Level], k: int, n: int) -> None:
    """Raise the Python checks' :class:`InvalidLevel` for the level the core rejected."""
    check_level(levels[k], k, n)
    raise InvalidLevel(f"level {k}: malformed (rejected by the native solver's checks)")


def make_solution(out: Any, levels: Sequence[Any], total: float) -> Solution:
    """Wrap the core's result tuple ``(x, reports, qp_count, final_seconds)``."""
    x, reports, qp_count, final_s = out
    level_reports = []
    timings: dict[str, float] = {}
    for k, (rep, lv) in enumerate(zip(reports, levels)):
        cost, satisfied, sigma, res, viol, active, violated, seconds, weak = rep
        level_reports.append(LevelReport(
            name=str(lv.name), cost=cost, satisfied=satisfied, active=active,
            violated=violated, sigma_min=sigma, residual_eq=res, violation_in=viol,
            weak_directions=weak))
        timings[f"level_{k}"] = seconds
    timings["final"] = final_s
    timings["total"] = total
    return Solution(x=x, levels=tuple(level_reports), timings=timings, backend="native",
                    algorithm="basis", qp_count=qp_count)
