"""One BLAS thread, so that simulation metrics are identical on repeated runs.

Environment variables only act before numpy loads OpenBLAS; once it is
loaded, the thread count is set through the library's own entry point.
"""

from __future__ import annotations

import ctypes
import glob
import logging
import os
from pathlib import Path

logger = logging.getLogger(__name__)

_SYMBOLS = (
    "scipy_openblas_set_num_threads64_",
    "scipy_openblas_set_num_threads",
    "openblas_set_num_threads64_",
    "openblas_set_num_threads",
)


def single_blas_thread() -> int:
    """Ask every bundled OpenBLAS (numpy's, scipy's) to use one thread.

    Returns:
        The number of libraries whose thread count was set.

    """
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"
    import numpy
    import scipy

    count = 0
    for pkg in (numpy, scipy):
        libs = Path(pkg.__file__).parent.parent / f"{pkg.__name__}.libs"
        for path in glob.glob(str(libs / "*openblas*.so*")):
            try:
                lib = ctypes.CDLL(path)
            except OSError:
                logger.debug("cannot load %s", path)
                continue
            for sym in _SYMBOLS:
                fn = getattr(lib, sym, None)
                if fn is not None:
                    fn(1)
                    count += 1
                    break
    return count
