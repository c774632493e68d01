"""Former home of the backend registry, now :mod:`hqp.solver.backends` (kept for importers)."""

from hqp.solver.backends import (
    QPBackend,
    available_backends,
    known_backends,
    make_backend,
    one_sided,
    supports,
)

__all__ = [
    "QPBackend",
    "available_backends",
    "known_backends",
    "make_backend",
    "one_sided",
    "supports",
]
