"""Plane geometry shared by the layers (support polygons of the law and of the simulator)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def monotone_chain(points: Sequence[tuple[float, float]]) -> np.ndarray:
    """Counter-clockwise convex hull ``(k, 2)`` of points sorted by ``(x, y)`` (Andrew).

    Collinear and repeated points are dropped; two points or fewer are returned as given.
    """
    pts = list(points)
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o: tuple, a: tuple, b: tuple) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple] = []
    for q in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], q) <= 0.0:
            lower.pop()
        lower.append(q)
    upper: list[tuple] = []
    for q in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], q) <= 0.0:
            upper.pop()
        upper.append(q)
    return np.array(lower[:-1] + upper[:-1])


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product ``a x b`` of two 3-vectors (arrays or sequences) ``(3,)``.

    The same products and differences as ``np.cross`` (bit for bit), without its
    broadcasting machinery (about 40 times slower on one pair of 3-vectors).
    """
    a0, a1, a2 = a.tolist() if isinstance(a, np.ndarray) else map(float, a)
    b0, b1, b2 = b.tolist() if isinstance(b, np.ndarray) else map(float, b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
