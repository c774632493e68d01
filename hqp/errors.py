"""The hqp exception family.

Every error raised on bad input is an :class:`HQPError`, a subclass of
:class:`ValueError`; its message says what was wrong and where (the level and
field, the primitive, the file and key).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


class HQPError(ValueError):
    """Base class of every hqp error raised on bad input."""


class InvalidInput(HQPError):
    """An array has the wrong shape, holds NaN or inf, or a value is out of range."""


class InvalidLevel(InvalidInput):
    """A solver level is malformed (names the level and the field)."""


class InvalidGain(InvalidInput):
    """A gain, saturation or limit is negative or not finite."""


class InvalidFrame(HQPError):
    """A frame name is not in the robot model; the message lists the frames that exist."""

    def __init__(self, name: str, available: Iterable[str], where: str = "") -> None:
        names = sorted(set(available))
        prefix = f"{where}: " if where else ""
        super().__init__(
            f"{prefix}unknown frame {name!r}; frames in the model: {', '.join(names)}"
        )
        self.name = name
        self.available = names


class UnknownName(HQPError):
    """A name (backend, robot, scenario, controller, behavior) that is not registered."""

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        names = sorted(valid)
        super().__init__(f"unknown {kind} {name!r}; valid {kind}s: {', '.join(names)}")
        self.kind = kind
        self.name = name
        self.valid = names


class UnknownBackend(UnknownName):
    """A QP backend that is not known or not installed."""

    def __init__(self, name: str, valid: Iterable[str]) -> None:
        super().__init__("backend", name, valid)


class BehaviorFileError(HQPError):
    """A behavior description file is malformed (names the file, key or line)."""


class SolverFailure(HQPError):
    """A QP backend failed on a well-formed problem (numerical failure)."""


def check_array(
    value: object,
    shape: tuple[int | None, ...],
    where: str,
    *,
    allow_inf: bool = False,
) -> np.ndarray:
    """Convert an array-like to a float array, check its shape and finiteness.

    Args:
        value: Array-like input.
        shape: Expected shape; ``None`` entries match any size.
        where: Prefix of the error message (e.g. ``"PositionTask 'hand': goal"``).
        allow_inf: Accept ``±inf`` entries (bounds), never NaN.

    Returns:
        A new float64 array (a copy: later changes of ``value`` do not leak in).

    Raises:
        InvalidInput: Wrong shape, NaN, or inf where not allowed.

    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"{where}: not a numeric array ({exc})") from None
    if arr.ndim != len(shape) or any(
        s is not None and s != d for s, d in zip(shape, arr.shape)
    ):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise InvalidInput(f"{where}: expected shape {want}, got {arr.shape}")
    if not np.isfinite(arr).all():  # one pass on the common, finite case
        if np.isnan(arr).any():
            raise InvalidInput(f"{where}: contains NaN")
        if not allow_inf:
            raise InvalidInput(f"{where}: contains inf")
    return arr

