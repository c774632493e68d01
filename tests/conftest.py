"""Shared test configuration: one BLAS thread, deterministic random generators.

No test installs a peer's environment (``hqp compare`` would make PlaCo's on first use):
``HQP_NO_PEER_INSTALL=1``; CI makes it before the tests (``.ci/run``), and the tests that need
it skip, saying so, where it is absent.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HQP_NO_PEER_INSTALL", "1")
