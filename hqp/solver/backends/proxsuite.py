"""ProxQP backend: one persistent dense QP per slot, updated and warm started."""

from __future__ import annotations

import logging
import sys
import types
from collections.abc import Hashable

import numpy as np

from hqp.solver.backends import _INF, QPBackend

PORTABLE_BUILD = "proxsuite_pywrap"
"""The proxsuite extension hqp loads: the wheel's build without AVX kernels.

The wheel ships three builds and by default loads the widest the CPU runs
(``proxsuite_pywrap_avx512``, ``_avx2``). Their Eigen kernels peel each loop
(dot products, matrix-vector products of the factorisation) by the address of
the operand modulo 32 bytes, so the summation order follows where the heap
placed ProxQP's own workspace (``veg`` vectors, ``malloc``, 16-byte aligned) and
``x`` changes in the last bits from one process to the next (cold solves of the
same QP differ even within a process). The portable build's 16-byte SSE2 packets
always sit aligned on a 16-byte aligned heap: its results are bit-reproducible.
The price, on the 246 level QPs of the recorded steps (``hqp/bench/data``): a warm
``update`` + ``solve`` takes about 0.23 ms on average instead of 0.15 ms (AVX-512), a cold
``init`` + ``solve`` 1.1 to 1.5 times as long."""


def _import_portable() -> types.ModuleType:
    """Import ``proxsuite`` so that it loads :data:`PORTABLE_BUILD`.

    ``proxsuite/__init__.py`` picks its build with ``instructionset.has_AVX512F()``
    and ``has_AVX2()``; a stand-in answering ``False`` to both is in
    ``sys.modules`` during the import only. A proxsuite imported earlier (by the
    caller, or by qpsolvers before hqp) keeps its build, with a warning: one
    process cannot load two builds.
    """
    if "proxsuite" not in sys.modules:
        name = "proxsuite.instructionset"
        stand_in = types.ModuleType(name)
        stand_in.has_AVX512F = stand_in.has_AVX2 = lambda: False  # type: ignore[attr-defined]
        real = sys.modules.get(name)
        sys.modules[name] = stand_in
        try:
            import proxsuite
        finally:
            if real is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = real
        vars(proxsuite).pop("instructionset", None)
    import proxsuite

    build = proxsuite.proxqp.__name__.split(".")[1]
    if build != PORTABLE_BUILD:
        logger.warning(
            "proxsuite was imported before hqp with its %s build, whose results depend on "
            "memory alignment: the proxsuite backend is not bit-reproducible across runs "
            "(import hqp.solver.backends.proxsuite first)", build)
    return proxsuite


logger = logging.getLogger(__name__)
proxsuite = _import_portable()

EPS_ABS = 1e-9
"""Absolute primal/dual residual tolerance (the contract's cost tolerance needs ~1e-9)."""

MAX_ITER = 50
"""Outer (proximal augmented Lagrangian) iterations per solve. On the recorded
whole-body problems (``hqp/bench/data``) the QPs ProxQP solves take a median of
6 and a 99th percentile of 14 outer iterations (largest seen: 606); the ones it does not solve
within 1000 are flat, nearly degenerate feasible sets (implicit equalities from
active friction-cone, torque and joint-limit rows) with multipliers of order
1e7, on which ProxQP stalls at 0.2-0.7 s per attempt. Such QPs are handed to
DAQP (exact on active sets) after this budget instead."""

MAX_ITER_IN = 100
"""Inner (semismooth Newton) iterations per outer iteration. On the stalls
above the inner loops run long (tens of thousands of inner iterations per
solve); solved QPs need a few dozen in all."""

STALL_SKIP = 200
"""Solves of a slot handed straight to DAQP after ProxQP stalled on it. The
level QPs of a control loop change little between steps, so a slot whose
feasible set was nearly degenerate usually stays so for a while; ProxQP is
tried again afterwards (the slot starts cold)."""

_SOLVED = proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
_MAX_ITER = proxsuite.proxqp.QPSolverOutput.PROXQP_MAX_ITER_REACHED
_WARM = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT


class ProxsuiteBackend(QPBackend):
    """``proxsuite.proxqp.dense.QP`` kept per slot while ``(nv, neq, nin)`` holds.

    The first solve of a slot runs ``init`` (cold start, equilibration); later
    solves with the same dimensions run ``update`` and start from the previous
    primal and dual solution (``WARM_START_WITH_PREVIOUS_RESULT``). A warm
    solve that reports infeasibility (a stale preconditioner or start can
    mislead ProxQP's infeasibility detection) is repeated cold, once; a solve
    that stalls (:data:`MAX_ITER` outer iterations, nearly degenerate feasible
    sets) or fails cold is handed to DAQP, an active-set method that is exact
    there; the slot's next :data:`STALL_SKIP` solves go to DAQP directly
    (ProxQP would stall again on the same nearly degenerate set), then ProxQP
    starts cold.
    """

    name = "proxsuite"
    warm_started = True
    """Warm starts its persistent per-level QPs itself (the hierarchy's
    active-set warm start is off by default with this backend)."""

    def __init__(self) -> None:
        self._qps: dict[Hashable, tuple[tuple[int, int, int], object]] = {}
        self._daqp: QPBackend | None = None
        self._skip: dict[Hashable, int] = {}

    def reset(self) -> None:
        """Drop every persistent problem."""
        self._qps.clear()
        self._skip.clear()

    @staticmethod
    def _cold(dims, H, g, E, e, C, lo, up):
        nv, neq, nin = dims
        qp = proxsuite.proxqp.dense.QP(nv, neq, nin)
        s = qp.settings
        s.eps_abs = EPS_ABS
        s.eps_rel = 0.0
        s.max_iter = MAX_ITER
        s.max_iter_in = MAX_ITER_IN
        s.verbose = False
        s.compute_timings = False
        # Residuals alone can be tiny while the cost is still off on semidefinite
        # Hessians (rank-deficient least squares): require a small duality gap too.
        s.check_duality_gap = True
        s.eps_duality_gap_abs = EPS_ABS
        s.eps_duality_gap_rel = 1e-10
        # The level QPs are feasible by construction (they contain the previous
        # optimum); the default 1e-4 infeasibility test misfires on degenerate
        # feasible sets, so it is made much stricter.
        s.eps_primal_inf = 1e-12
        s.eps_dual_inf = 1e-12
        qp.init(H, g, E, e, C, lo, up)
        qp.solve()
        # Warm starts need a previous result: switch only after the first solve.
        s.initial_guess = _WARM
        return qp

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        nv = H.shape[0]
        neq = 0 if E is None else E.shape[0]
        nin = 0 if C is None else C.shape[0]
        if not neq:
            E = e = None
        if nin:
            lo = np.maximum(lo, -_INF)
            up = np.minimum(up, _INF)
        else:
            C = lo = up = None
        dims = (nv, neq, nin)
        skip = self._skip.get(slot, 0)
        if skip:
            # ProxQP stalled on this slot lately: DAQP only (its failure is
            # reported, and the hierarchy retries with relaxed bounds)
            self._skip[slot] = skip - 1
            return self._fallback().solve(slot, H, g, E, e, C, lo, up)
        entry = self._qps.get(slot)
        if entry is None or entry[0] != dims:
            qp = self._cold(dims, H, g, E, e, C, lo, up)
            self._qps[slot] = (dims, qp)
        else:
            qp = entry[1]
            qp.update(H, g, E, e, C, lo, up)
            qp.solve()
            status = qp.results.info.status
            if status != _SOLVED and status != _MAX_ITER:
                # a stale warm start or preconditioner misled the infeasibility test
                qp = self._cold(dims, H, g, E, e, C, lo, up)
                self._qps[slot] = (dims, qp)
        if qp.results.info.status == _SOLVED:
            return qp.results.x, True
        # the stalled iterate is no start for the next step: start that one cold,
        # and give the next STALL_SKIP solves of this slot to DAQP directly
        self._qps.pop(slot, None)
        if qp.results.info.status == _MAX_ITER:
            self._skip[slot] = STALL_SKIP
        # ProxQP can stall on degenerate vertices (many rows active at one point,
        # which lexicographic problems produce); an active-set method is exact there.
        logger.debug("ProxQP status %s on %s; falling back to DAQP", qp.results.info.status, slot)
        return self._fallback().solve(slot, H, g, E, e, C, lo, up)

    def _fallback(self) -> QPBackend:
        if self._daqp is None:
            from hqp.solver.backends.daqp import DaqpBackend

            self._daqp = DaqpBackend()
        return self._daqp
