"""hqp: whole-body control of humanoid robots with a strict lexicographic hierarchy of QPs."""

from hqp.errors import (
    BehaviorFileError,
    HQPError,
    InvalidFrame,
    InvalidGain,
    InvalidInput,
    InvalidLevel,
    SolverFailure,
    UnknownBackend,
    UnknownName,
)

__version__ = "0.1.0"

__all__ = [
    "BehaviorFileError",
    "HQPError",
    "InvalidFrame",
    "InvalidGain",
    "InvalidInput",
    "InvalidLevel",
    "SolverFailure",
    "UnknownBackend",
    "UnknownName",
    "__version__",
]
