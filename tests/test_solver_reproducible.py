"""Bit-reproducible solves across processes (docs/reference/contracts.md: simulation metrics are
identical on repeated runs).

The wheel's AVX builds of proxsuite sum in an order that follows the heap addresses of
ProxQP's own workspace, so ``x`` changed in its last bits from one process to the next
and the closed loop amplified it; :mod:`hqp.solver.backends.proxsuite` loads the portable
build. Each check runs the same work in fresh processes whose heaps differ (dummy
allocations of different sizes, different ``PYTHONHASHSEED``) and compares bytes.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from hqp.solver import available_backends

ENV = {**os.environ, "OMP_NUM_THREADS": "1"}

SOLVE_RECORDED = """
import hashlib, sys
import numpy as np
dummies = [np.empty(int(k)) for k in sys.argv[2].split(",")]
from hqp.bench.recorded import load_all
from hqp.solver import HierarchicalSolver
solver = HierarchicalSolver(sys.argv[1])
h = hashlib.sha256()
for step in load_all():
    h.update(np.ascontiguousarray(solver.solve(step.levels).x).tobytes())
print(h.hexdigest())
"""

HEAPS = (("1", "0"), ("3,517,12", "1"), ("40000,7", "2"))
"""(dummy array sizes, PYTHONHASHSEED) of the processes compared."""


def _run(args: list[str], seed: str) -> str:
    proc = subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=600,
                          env={**ENV, "PYTHONHASHSEED": seed})
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


@pytest.mark.parametrize("backend", [b for b in ("proxsuite", "daqp") if b in available_backends()])
def test_recorded_solves_identical_across_processes(backend):
    digests = {_run(["-c", SOLVE_RECORDED, backend, sizes], seed).strip()
               for sizes, seed in HEAPS}
    assert len(digests) == 1, digests


def test_proxsuite_portable_build_loaded():
    code = ("import hqp.solver.backends.proxsuite as p, proxsuite; "
            "print(proxsuite.proxqp.__name__.split('.')[1], p.PORTABLE_BUILD)")
    loaded, wanted = _run(["-c", code], "0").split()
    assert loaded == wanted


def test_hqp_run_metrics_identical_across_processes():
    """``hqp run`` with the default backend: the same JSON twice, timing fields aside."""
    outs = []
    for sizes, seed in HEAPS[:2]:
        code = (f"import numpy as np; dummies = [np.empty(k) for k in ({sizes},)]; "
                "from hqp.app.cli import main; "
                "raise SystemExit(main(['run', 'stand', '--duration', '0.3', '--json']))")
        out = json.loads(_run(["-c", code], seed))
        assert out["backend"] == "native"  # the default: the native step and solver
        out.pop("step_time_median_ms")
        out.pop("realtime_factor")
        outs.append(out)
    assert outs[0] == outs[1]
