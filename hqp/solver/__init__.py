"""The strict lexicographic HQP solver over plain matrices, and its QP backends.

>>> from hqp.solver import Level, solve
>>> import numpy as np
>>> sol = solve([Level(A=np.eye(2)[:1], b=[1.0])])
>>> np.allclose(sol.x, [1.0, 0.0])
True
"""

from hqp.solver.backends import (
    QPBackend,
    available_backends,
    known_backends,
    make_backend,
    supports,
)
from hqp.solver.hierarchy import ALGORITHMS, HierarchicalSolver, solve
from hqp.solver.level import Level
from hqp.solver.solution import ROW_TOL, SATISFIED_COST, LevelReport, Solution

__all__ = [
    "ALGORITHMS",
    "ROW_TOL",
    "SATISFIED_COST",
    "HierarchicalSolver",
    "Level",
    "LevelReport",
    "QPBackend",
    "Solution",
    "available_backends",
    "known_backends",
    "make_backend",
    "solve",
    "supports",
]
