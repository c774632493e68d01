"""Random hierarchies for the solver benchmark (and for tests that need many problems).

Each level is drawn from a :class:`LevelSpec`: equality rows, inequality rows
(one- or two-sided), and optionally *conflicting* rows (targets inconsistent
with the levels above, so the level is not satisfied) or *rank-deficient*
rows (rows that repeat combinations of other rows, so the projected matrix
loses rank).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hqp.solver import Level


@dataclass(frozen=True)
class LevelSpec:
    """Shape and character of one random level.

    Attributes:
        m_eq: Number of equality rows.
        m_in: Number of inequality rows.
        two_sided: Inequalities bounded on both sides (else upper bound only).
        conflicting: Draw targets that the levels above make unreachable: equality
            targets far from the feasible point, and inequality bands that exclude it.
        rank_deficient: Half of the rows are linear combinations of the other half.
        band: Scale of the inequality half widths (``band >> 1``: few active rows).

    """

    m_eq: int = 0
    m_in: int = 0
    two_sided: bool = True
    conflicting: bool = False
    rank_deficient: bool = False
    band: float = 1.0
    """Scale of the inequality bands' half widths (large: few rows active)."""


def _rows(rng: np.random.Generator, m: int, n: int, deficient: bool) -> np.ndarray:
    M = rng.standard_normal((m, n))
    if deficient and m >= 2:
        half = max(1, m // 2)
        M[half:] = rng.standard_normal((m - half, half)) @ M[:half]
    return M


def _conflict(rng: np.random.Generator, M: np.ndarray, above: np.ndarray | None) -> None:
    """Replace half of the rows of ``M`` by combinations of the rows ``above`` (in place)."""
    if above is None or above.shape[0] == 0 or M.shape[0] == 0:
        return
    h = max(1, M.shape[0] // 2)
    M[:h] = rng.standard_normal((h, above.shape[0])) @ above


def random_level(
    rng: np.random.Generator,
    n: int,
    spec: LevelSpec,
    x_ref: np.ndarray,
    name: str = "",
    above: np.ndarray | None = None,
) -> Level:
    """Draw one level over ``n`` variables around a reference point ``x_ref`` ``(n,)``.

    ``above`` stacks the rows of the levels above ``(k, n)``: conflicting levels
    reuse combinations of them with other targets, so the conflict is real
    whatever the number of free variables.
    """
    A = b = C = lower = upper = None
    if spec.m_eq:
        A = _rows(rng, spec.m_eq, n, spec.rank_deficient)
        if spec.conflicting:
            _conflict(rng, A, above)
        b = A @ x_ref
        if spec.conflicting:
            b = b + 3.0 * rng.standard_normal(spec.m_eq)
        else:
            b = b + 0.1 * rng.standard_normal(spec.m_eq)
    if spec.m_in:
        C = _rows(rng, spec.m_in, n, spec.rank_deficient)
        if spec.conflicting:
            _conflict(rng, C, above)
        cx = C @ x_ref
        shift = 2.0 if spec.conflicting else 0.0
        # bands around the reference, some of them excluding it
        centre = cx + rng.uniform(-1.0, 1.0, spec.m_in) + shift * np.sign(
            rng.standard_normal(spec.m_in))
        half = spec.band * rng.uniform(0.2, 1.5, spec.m_in)
        upper = centre + half
        lower = centre - half if spec.two_sided else None
    return Level(A=A, b=b, C=C, lower=lower, upper=upper, name=name)


def random_hierarchy(
    rng: np.random.Generator, n: int, specs: list[LevelSpec]
) -> list[Level]:
    """Draw a hierarchy: one level per spec, highest priority first."""
    x_ref = rng.standard_normal(n)
    levels: list[Level] = []
    rows: list[np.ndarray] = []
    for k, spec in enumerate(specs):
        above = np.concatenate(rows) if rows else None
        lv = random_level(rng, n, spec, x_ref, name=f"L{k}", above=above)
        rows += [m for m in (lv.A, lv.C) if m is not None]
        levels.append(lv)
    return levels


def reference_specs(n: int) -> list[LevelSpec]:
    """Return the issue's reference shape: 4 levels, two holding inequalities.

    Level 0: ``n/8`` equality rows (physics-like, always consistent); level 1:
    ``n/2`` two-sided inequalities (limits; some bands exclude the least-squares
    point); level 2: ``n/4`` equality rows (an operational task, conflicting);
    level 3: ``n/4`` one-sided inequalities and ``n/4`` equality rows (posture
    with bounds, rank deficient).
    """
    q = max(1, n // 4)
    return [
        LevelSpec(m_eq=max(1, n // 8)),
        LevelSpec(m_in=max(1, n // 2), two_sided=True),
        LevelSpec(m_eq=q, conflicting=True),
        LevelSpec(m_eq=q, m_in=q, two_sided=False, rank_deficient=True),
    ]
