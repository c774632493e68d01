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


def checked_core():
    """The allocation-checked extension module ``hqp._core._ext_checked``.

    It is built only with the CMake option ``HQP_CHECKED=ON`` (``.ci/run`` sets it; a user's
    install does not carry it). Without it the no-allocation tests skip, unless
    ``HQP_REQUIRE_CHECKED=1`` (set by ``.ci/run``), where its absence is a failure.
    """
    import pytest

    try:
        from hqp._core import _ext_checked
    except ImportError:
        if os.environ.get("HQP_REQUIRE_CHECKED") == "1":
            raise
        pytest.skip("hqp._core._ext_checked not built: pip install -e . "
                    "-Ccmake.define.HQP_CHECKED=ON")
    return _ext_checked
