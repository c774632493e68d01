"""ProxQP backend: one persistent dense QP per slot, updated and warm started."""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np
import proxsuite

from hqp.solver.backend import _INF, QPBackend

EPS_ABS = 1e-10
"""Absolute primal/dual residual tolerance (the contract's cost tolerance needs ~1e-9)."""


class ProxsuiteBackend(QPBackend):
    """``proxsuite.proxqp.dense.QP`` kept per slot while ``(nv, neq, nin)`` holds.

    The first solve of a slot runs ``init`` (cold start, equilibration); later
    solves with the same dimensions run ``update`` and start from the previous
    primal and dual solution (``WARM_START_WITH_PREVIOUS_RESULT``).
    """

    name = "proxsuite"

    def __init__(self) -> None:
        self._qps: dict[Hashable, tuple[tuple[int, int, int], object]] = {}

    def reset(self) -> None:
        """Drop every persistent problem."""
        self._qps.clear()

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        nv = H.shape[0]
        neq = 0 if E is None else E.shape[0]
        nin = 0 if C is None else C.shape[0]
        if nin:
            lo = np.maximum(lo, -_INF)
            up = np.minimum(up, _INF)
        dims = (nv, neq, nin)
        entry = self._qps.get(slot)
        if entry is None or entry[0] != dims:
            qp = proxsuite.proxqp.dense.QP(nv, neq, nin)
            s = qp.settings
            s.eps_abs = EPS_ABS
            s.eps_rel = 0.0
            s.max_iter = 10000
            s.verbose = False
            s.compute_timings = False
            qp.init(
                H,
                g,
                E if neq else None,
                e if neq else None,
                C if nin else None,
                lo if nin else None,
                up if nin else None,
            )
            qp.solve()
            # Warm starts need a previous result: switch only after the first solve.
            s.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            self._qps[slot] = (dims, qp)
        else:
            qp = entry[1]
            qp.update(
                H,
                g,
                E if neq else None,
                e if neq else None,
                C if nin else None,
                lo if nin else None,
                up if nin else None,
            )
            qp.solve()
        ok = qp.results.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
        return qp.results.x, ok
