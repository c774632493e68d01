"""A priority level over plain matrices, and its validation."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hqp.errors import InvalidLevel


@dataclass(frozen=True)
class Level:
    """One priority level: equality rows ``A x = b`` and/or inequality rows.

    The level's cost is ``||A x - b||^2 + ||dist(C x, [lower, upper])||^2``.
    Arrays are taken as given (array-likes accepted); they are converted and
    checked by :func:`hqp.solver.solve`, which knows the level's index and
    names it in its error messages.

    Attributes:
        A: Equality matrix ``(m_eq, n)`` or ``None``.
        b: Equality target ``(m_eq,)``; ``None`` means zeros.
        C: Inequality matrix ``(m_in, n)`` or ``None``.
        lower: Lower bounds ``(m_in,)`` (``-inf`` entries allowed); ``None`` means ``-inf``.
        upper: Upper bounds ``(m_in,)`` (``+inf`` entries allowed); ``None`` means ``+inf``.
        name: Label used in reports and error messages.
        weak_threshold: Singular-value threshold of the level's weak directions, in the
            units of its (weighted) equality rows, ``>= 0``. Along each direction in which
            the equality rows, projected on the optimal set of the levels above, have a
            singular value ``s`` below it, the level's target is scaled by
            ``(s / weak_threshold)^2``: the step there is bounded and goes to 0 at a
            singularity instead of growing as ``1 / s`` (the seed's truncation of vanishing
            eigenvalues, hierarchy paper eq. 22-23, made continuous). Directions at or
            above it keep their exact target, so a level whose singular values all reach
            it is solved exactly as with 0 (the default: no filtering). The level's
            reported cost stays measured against ``b``.

    """

    A: Any = None
    b: Any = None
    C: Any = None
    lower: Any = None
    upper: Any = None
    name: str = ""
    weak_threshold: float = 0.0


@dataclass(frozen=True)
class CheckedLevel:
    """A validated level: float arrays of consistent shapes (internal).

    Attributes:
        A: ``(m_eq, n)``; ``b``: ``(m_eq,)``; ``C``: ``(m_in, n)``;
        ``lower``/``upper``: ``(m_in,)`` with ``±inf`` for absent bounds.

    """

    A: np.ndarray
    b: np.ndarray
    C: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    name: str
    lo_scale: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """``max(1, |lower|)`` per row (``1e300`` where infinite): scale of row tolerances."""
    up_scale: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """``max(1, |upper|)`` per row (``1e300`` where infinite)."""
    bounded: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    """Rows with at least one finite bound."""
    a_scale: float = 0.0
    """Largest absolute entry of ``A`` (0 without equality rows)."""
    c_scale: float = 0.0
    """Largest absolute entry of ``C`` (0 without inequality rows)."""
    weak: float = 0.0
    """The level's ``weak_threshold`` (0: no filtering)."""

    @property
    def m_eq(self) -> int:
        """Number of equality rows."""
        return self.A.shape[0]

    @property
    def m_in(self) -> int:
        """Number of inequality rows."""
        return self.C.shape[0]


class Internal:
    """Kind of a level: a user's, or one of the solver's internal final levels."""

    NONE = 0
    """A user's level."""
    METRIC = 1
    """The final metric ``(x - t)^T M (x - t)`` as ``A = M^{1/2}``, ``b = M^{1/2} t``."""
    NORM = 2
    """The minimum norm (``A = I``, ``b = 0``; or ``b = t`` without a metric)."""


def _where(k: int, name: str, field: str) -> str:
    label = f"level {k}" + (f" ({name!r})" if name else "")
    return f"{label}, field {field}"


BOUND_INF = 1e20
"""Bounds beyond ``±BOUND_INF`` are absent: a lower bound below ``-BOUND_INF`` is ``-inf``, an
upper bound above ``BOUND_INF`` is ``+inf`` (the convention of OSQP and DAQP); a lower bound
above it or an upper bound below ``-BOUND_INF`` is refused."""
MAX_ENTRY = 1e100
"""Largest magnitude of an entry of ``A``, ``b`` or ``C`` (its square must not overflow)."""


def _as_float(value: Any, k: int, name: str, field: str) -> np.ndarray:
    """Float64 view of ``value`` (no copy when it already is one)."""
    if type(value) is np.ndarray and value.dtype == np.float64:
        return value
    try:
        arr = np.asarray(value)
        if arr.dtype.kind == "c":
            raise InvalidLevel(f"{_where(k, name, field)}: complex entries (a level is real)")
        return np.asarray(arr, dtype=float)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, InvalidLevel):
            raise
        raise InvalidLevel(f"{_where(k, name, field)}: not a numeric array ({exc})") from None


def _huge_or_raise(arr: np.ndarray, k: int, name: str, field: str) -> None:
    if arr.size and float(np.abs(arr).max()) > MAX_ENTRY:
        i = int(np.argmax(np.abs(arr)))
        raise InvalidLevel(f"{_where(k, name, field)}: entry {arr.flat[i]:g} beyond "
                           f"±{MAX_ENTRY:g} (scale the level)")


def _absent_bounds(lower: np.ndarray, upper: np.ndarray, k: int, name: str
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Bounds beyond :data:`BOUND_INF` made infinite (copies only where one is)."""
    if (lower > BOUND_INF).any():
        raise InvalidLevel(f"{_where(k, name, 'lower')}: lower bound above {BOUND_INF:g}")
    if (upper < -BOUND_INF).any():
        raise InvalidLevel(f"{_where(k, name, 'upper')}: upper bound below {-BOUND_INF:g}")
    if (lower < -BOUND_INF).any():
        lower = np.where(lower < -BOUND_INF, -np.inf, lower)
    if (upper > BOUND_INF).any():
        upper = np.where(upper > BOUND_INF, np.inf, upper)
    return lower, upper


def beyond_range(levels: Any) -> bool:
    """Whether a level holds values :func:`check_level` changes or refuses.

    A finite bound beyond :data:`BOUND_INF`, or an entry of ``A``, ``b`` or ``C`` beyond
    :data:`MAX_ENTRY`.
    """
    for level in levels:
        for name in ("lower", "upper", "A", "b", "C"):
            value = getattr(level, name, None)
            if value is None:
                continue
            arr = np.abs(np.asarray(value, dtype=float))
            if not arr.size:
                continue
            if name in ("lower", "upper"):
                if (arr[np.isfinite(arr)] > BOUND_INF).any():
                    return True
            elif float(arr.max()) > MAX_ENTRY:
                return True
    return False


def _finite_or_raise(arr: np.ndarray, k: int, name: str, field: str, allow_inf: bool) -> None:
    # One reduction first (NaN propagates through a sum; inf too, or overflow, in
    # which case the detailed checks below decide).
    total = float(arr.sum()) if arr.size else 0.0
    if allow_inf:
        if total == total:
            return
        if np.isnan(arr).any():
            raise InvalidLevel(f"{_where(k, name, field)}: contains NaN")
        return
    if -_HUGE < total < _HUGE:
        return
    if not np.isfinite(arr).all():
        what = "NaN" if np.isnan(arr).any() else "inf"
        bad = np.argwhere(~np.isfinite(arr))[0].tolist()
        raise InvalidLevel(f"{_where(k, name, field)}: contains {what} (at index {bad})")


_HUGE = float("inf")


def _matrix(value: Any, k: int, name: str, field: str) -> np.ndarray:
    arr = _as_float(value, k, name, field)
    if arr.ndim == 1:
        arr = arr[None, :]  # one row given as a vector
    if arr.ndim != 2:
        raise InvalidLevel(f"{_where(k, name, field)}: expected a 2-D matrix, got shape "
                           f"{arr.shape}")
    _finite_or_raise(arr, k, name, field, False)
    _huge_or_raise(arr, k, name, field)
    return arr


def _vector(value: Any, m: int, k: int, name: str, field: str, *, fill: float,
            allow_inf: bool) -> np.ndarray:
    if value is None:
        return _constant(m, fill)
    arr = _as_float(value, k, name, field)
    if arr.ndim == 0 and m == 1:
        arr = arr.reshape(1)
    if arr.shape != (m,):
        raise InvalidLevel(f"{_where(k, name, field)}: expected shape ({m},), got {arr.shape}")
    _finite_or_raise(arr, k, name, field, allow_inf)
    return arr


_CONSTANTS: dict[tuple[int, float], np.ndarray] = {}


def _constant(m: int, fill: float) -> np.ndarray:
    """Return a read-only ``(m,)`` array of ``fill`` (shared: levels never write their arrays)."""
    arr = _CONSTANTS.get((m, fill))
    if arr is None:
        arr = np.full(m, fill)
        arr.flags.writeable = False
        if len(_CONSTANTS) < 256:
            _CONSTANTS[(m, fill)] = arr
    return arr


def check_level(level: Any, k: int, n: int | None) -> CheckedLevel:
    """Convert and validate one level.

    Args:
        level: A :class:`Level` (or any object with its attributes).
        k: Index of the level (0 = highest priority), for messages.
        n: Number of variables when known (from an earlier level), else ``None``.

    Returns:
        The validated level.

    Raises:
        InvalidLevel: Not a level, wrong shapes, complex entries, NaN or inf in ``A``,
            ``b`` or ``C`` (or entries beyond :data:`MAX_ENTRY`), NaN in a bound, a lower
            bound above :data:`BOUND_INF` (or an upper one below its negative),
            ``lower > upper``, or a vector without its matrix. Bounds beyond
            :data:`BOUND_INF` on their own side are absent (infinite).

    """
    if not isinstance(level, Level):
        raise InvalidLevel(f"level {k}: expected hqp.solver.Level, got {type(level).__name__}")
    name = str(level.name)
    widths = []
    if level.A is None:
        if level.b is not None:
            raise InvalidLevel(f"{_where(k, name, 'b')}: given without A")
        A = None
    else:
        A = _matrix(level.A, k, name, "A")
        widths.append(("A", A.shape[1]))
    if level.C is None:
        for field in ("lower", "upper"):
            if getattr(level, field) is not None:
                raise InvalidLevel(f"{_where(k, name, field)}: given without C")
        C = None
    else:
        C = _matrix(level.C, k, name, "C")
        widths.append(("C", C.shape[1]))
    for field, width in widths:
        if n is not None and width != n:
            raise InvalidLevel(
                f"{_where(k, name, field)}: has {width} columns, expected n = {n} "
                "(the number of variables of the other levels)"
            )
        n = width
    if n is None:
        n = 0  # empty level; resized by the caller once n is known
    if A is None:
        A = np.zeros((0, n))
    if C is None:
        C = np.zeros((0, n))
    b = _vector(level.b, A.shape[0], k, name, "b", fill=0.0, allow_inf=False)
    _huge_or_raise(b, k, name, "b")
    lower = _vector(level.lower, C.shape[0], k, name, "lower", fill=-np.inf, allow_inf=True)
    upper = _vector(level.upper, C.shape[0], k, name, "upper", fill=np.inf, allow_inf=True)
    lo_s = up_s = _EMPTY
    bounded = _NO_BOOL
    if C.shape[0]:
        if float(lower.max()) == np.inf:
            raise InvalidLevel(f"{_where(k, name, 'lower')}: contains +inf")
        if float(upper.min()) == -np.inf:
            raise InvalidLevel(f"{_where(k, name, 'upper')}: contains -inf")
        lower, upper = _absent_bounds(lower, upper, k, name)
        if (lower > upper).any():
            bad = np.flatnonzero(lower > upper)
            i = int(bad[0])
            raise InvalidLevel(
                f"{_where(k, name, 'lower/upper')}: lower > upper at row {i} "
                f"({lower[i]:g} > {upper[i]:g}); {bad.size} such row(s)"
            )
        # max(1, |bound|), and a huge finite scale for infinite bounds (whose
        # tolerance never matters: nothing is near an infinite bound)
        lo_s = np.minimum(np.maximum(np.abs(lower), 1.0), 1e300)
        up_s = np.minimum(np.maximum(np.abs(upper), 1.0), 1e300)
        bounded = (lower > -np.inf) | (upper < np.inf)
    a_scale = float(np.abs(A).max()) if A.shape[0] and A.shape[1] else 0.0
    c_scale = float(np.abs(C).max()) if C.shape[0] and C.shape[1] else 0.0
    weak = check_weak_threshold(level.weak_threshold, k, name)
    return CheckedLevel(A, b, C, lower, upper, name, lo_s, up_s, bounded, a_scale, c_scale,
                        weak)


def check_weak_threshold(value: Any, k: int, name: str) -> float:
    """Return a level's ``weak_threshold`` as a float, or raise :class:`InvalidLevel`."""
    if isinstance(value, bool):
        raise InvalidLevel(f"{_where(k, name, 'weak_threshold')}: expected a float, got "
                           f"{value!r}")
    try:
        weak = float(value)
    except (TypeError, ValueError):
        raise InvalidLevel(f"{_where(k, name, 'weak_threshold')}: expected a float, got "
                           f"{value!r}") from None
    if not (0.0 <= weak < np.inf):
        raise InvalidLevel(f"{_where(k, name, 'weak_threshold')}: expected a finite value "
                           f">= 0, got {value!r}")
    return weak


_EMPTY = np.zeros(0)
_NO_BOOL = np.zeros(0, dtype=bool)


def trusted_level(level: Level, n: int) -> CheckedLevel:
    """Convert a level that its builder guarantees well formed (no checks).

    The same result as :func:`check_level` on a valid level, in fewer
    operations: float arrays of consistent shapes, finite ``A``, ``b``, ``C``
    and ``lower <= upper`` are assumed (``None`` fields allowed).

    Args:
        level: The level.
        n: Number of variables.

    """
    A = level.A
    if A is None:
        A = np.zeros((0, n))
        b = _EMPTY
    else:
        A = np.asarray(A, dtype=float)
        if A.ndim == 1:
            A = A[None, :]
        b = _constant(A.shape[0], 0.0) if level.b is None else np.asarray(level.b, dtype=float)
    C = level.C
    if C is None:
        C = np.zeros((0, n))
        lower = upper = lo_s = up_s = _EMPTY
        bounded = _NO_BOOL
    else:
        C = np.asarray(C, dtype=float)
        if C.ndim == 1:
            C = C[None, :]
        m = C.shape[0]
        lower = _constant(m, -np.inf) if level.lower is None else np.asarray(level.lower,
                                                                             dtype=float)
        upper = _constant(m, np.inf) if level.upper is None else np.asarray(level.upper,
                                                                            dtype=float)
        lo_s = np.minimum(np.maximum(np.abs(lower), 1.0), 1e300)
        up_s = np.minimum(np.maximum(np.abs(upper), 1.0), 1e300)
        bounded = (lower > -np.inf) | (upper < np.inf)
    a_scale = float(np.abs(A).max()) if A.size else 0.0
    c_scale = float(np.abs(C).max()) if C.size else 0.0
    return CheckedLevel(A, b, C, lower, upper, str(level.name), lo_s, up_s, bounded, a_scale,
                        c_scale, float(level.weak_threshold))
