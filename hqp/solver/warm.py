"""The warm start's memory: each level slot's last active set and point, and its rest counts.

Before a level's QP, both algorithms try the active set of the previous solve of that
level (:mod:`hqp.solver.active_set`); after a backend's QP they polish its point on its
active set. This module keeps what they need between solves.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hqp.solver.active_set import Guess

ACTIVE_TOL = 1e-7
"""A carried row within this (times ``max(1, |bound|)``) of a bound at a
backend's QP point is held at that bound in the polishing solve."""

POLISH_ITER = 2
"""Active-set updates tried when polishing a backend's QP point."""

WARM_SKIP = 50
"""Solves of a level slot that go straight to the backend after neither the
warm-start guess nor the active set of the backend's QP point verified. On
the nearly degenerate levels of real whole-body stacks (more carried rows
held than free directions, some nearly dependent) the active-set solve is
too ill-conditioned to pass the checks, and each failed attempt costs
several factorisations; such a level usually stays so for a while."""


class WarmStart:
    """Active sets (carried rows keyed by their index in the hierarchy) and points per slot."""

    def __init__(self) -> None:
        self.guesses: dict[Any, tuple[np.ndarray, np.ndarray]] = {}
        self.points: dict[Any, np.ndarray] = {}
        self.skip: dict[Any, int] = {}
        self.anchor: np.ndarray | None = None
        """The last solve's solution: where the least squares of the next one start."""

    def reset(self) -> None:
        """Forget everything (the next solves start cold)."""
        self.guesses.clear()
        self.points.clear()
        self.skip.clear()
        self.anchor = None

    def use(self, slot: Any) -> bool:
        """Whether the slot uses the warm start in this solve (see :data:`WARM_SKIP`)."""
        skip = self.skip.get(slot)
        if not skip:
            return True
        if skip <= 1:
            del self.skip[slot]
        else:
            self.skip[slot] = skip - 1
        return False

    def failed(self, slot: Any) -> None:
        """Neither the guess nor the QP point's active set verified: rest the slot."""
        self.skip[slot] = WARM_SKIP
        self.guesses.pop(slot, None)

    def guess(self, slot: Any, mi: int, gid: np.ndarray, total_in: int, n: int) -> Guess | None:
        """Return the active set of the slot's previous solve, if the hierarchy's shapes held."""
        memo = self.guesses.get(slot)
        if memo is None or memo[0].size != mi or memo[1].size != total_in:
            return None
        point = self.points.get(slot)
        if point is None or point.shape != (n,):
            return None
        return Guess(memo[0], memo[1][gid])

    def remember(self, slot: Any, guess: Guess, gid: np.ndarray, total_in: int,
                 point: np.ndarray) -> None:
        """Keep the slot's active set (carried rows by their index in the hierarchy) and point."""
        wmap = np.zeros(total_in, dtype=np.int8)
        if gid.size:
            wmap[gid] = guess.w
        self.guesses[slot] = (guess.s, wmap)
        self.points[slot] = point
