"""The interface every QP backend implements, and the registry of backends.

A backend solves one convex QP

    min_v 0.5 v^T H v + g^T v   s.t.   E v = e,   lo <= C v <= up

with ``H`` symmetric positive semidefinite ``(nv, nv)``, ``E`` ``(neq, nv)``
(or ``None``), ``C`` ``(nin, nv)`` (or ``None``) and bounds that may hold
``±inf``. The hierarchical solver calls it once per level that needs a QP; the
``slot`` argument names the level so that a backend can keep one persistent
problem per level and warm start it while the dimensions hold.
"""

from __future__ import annotations

import abc
import importlib
from collections.abc import Callable, Hashable

import numpy as np

from hqp.errors import UnknownBackend

_INF = 1e20
"""Finite stand-in for ``±inf`` bounds where a backend needs one."""


class QPBackend(abc.ABC):
    """A QP backend (one instance per :class:`~hqp.solver.HierarchicalSolver`)."""

    name: str = ""

    @abc.abstractmethod
    def solve(
        self,
        slot: Hashable,
        H: np.ndarray,
        g: np.ndarray,
        E: np.ndarray | None,
        e: np.ndarray | None,
        C: np.ndarray | None,
        lo: np.ndarray | None,
        up: np.ndarray | None,
    ) -> tuple[np.ndarray, bool]:
        """Solve the QP; return the primal solution ``(nv,)`` and whether it converged.

        Args:
            slot: Identifies the caller's persistent problem (e.g. ``(level, role)``).
            H: Hessian ``(nv, nv)``, symmetric positive semidefinite.
            g: Linear term ``(nv,)``.
            E: Equality matrix ``(neq, nv)`` or ``None``.
            e: Equality right-hand side ``(neq,)`` or ``None``.
            C: Inequality matrix ``(nin, nv)`` or ``None``.
            lo: Lower bounds ``(nin,)``, may hold ``-inf``.
            up: Upper bounds ``(nin,)``, may hold ``+inf``.

        """

    def solve_quick(self, slot: Hashable, H: np.ndarray, g: np.ndarray, E: np.ndarray | None,
                    e: np.ndarray | None, C: np.ndarray | None, lo: np.ndarray | None,
                    up: np.ndarray | None) -> tuple[np.ndarray, bool]:
        """Solve as :meth:`solve` does, with the backend's cheap attempts only.

        Called by :func:`hqp.solver.qp.solve_qp` with ``quick`` (the basis algorithm's first
        pass); by default :meth:`solve`.
        """
        return self.solve(slot, H, g, E, e, C, lo, up)

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget persistent problems (the next solves start cold)."""


def one_sided(
    C: np.ndarray | None, lo: np.ndarray | None, up: np.ndarray | None
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Turn ``lo <= C v <= up`` into ``G v <= h`` keeping finite bounds only.

    Returns:
        ``(G, h)`` with ``G`` ``(k, nv)`` or ``(None, None)`` when no bound is finite.

    """
    if C is None or C.shape[0] == 0:
        return None, None
    fu = np.isfinite(up)
    fl = np.isfinite(lo)
    G = np.concatenate([C[fu], -C[fl]])
    if G.shape[0] == 0:
        return None, None
    h = np.concatenate([up[fu], -lo[fl]])
    return G, h


_REGISTRY: dict[str, tuple[str, str]] = {
    "proxsuite": ("hqp.solver.backends.proxsuite", "ProxsuiteBackend"),
    "osqp": ("hqp.solver.backends.osqp", "OsqpBackend"),
    "daqp": ("hqp.solver.backends.daqp", "DaqpBackend"),
    "quadprog": ("hqp.solver.backends.quadprog", "QuadprogBackend"),
    "native": ("hqp.solver.backends.native", "NativeBackend"),
}
"""Backend name -> (module, class). Modules import their QP library lazily."""

_REQUIRES = {
    "proxsuite": "hqp.solver.backends.proxsuite",  # pins proxsuite's portable build
    "osqp": "osqp",
    "daqp": "daqp",
    "quadprog": "quadprog",
    "native": "hqp._core._ext",
}


def known_backends() -> list[str]:
    """Names of every registered backend, installed or not."""
    return list(_REGISTRY)


def available_backends() -> list[str]:
    """Names of the registered backends whose QP library imports here."""
    names = []
    for name in _REGISTRY:
        try:
            importlib.import_module(_REQUIRES[name])
        except ImportError:
            continue
        names.append(name)
    return names


def supports(backend: str, algorithm: str) -> bool:
    """Whether ``HierarchicalSolver(backend, algorithm)`` exists (``native`` is basis only)."""
    return backend != "native" or algorithm == "basis"


def make_backend(name: str) -> QPBackend:
    """Instantiate the backend called ``name``.

    Raises:
        UnknownBackend: ``name`` is not registered or its library is not installed.

    """
    if not isinstance(name, str) or name not in _REGISTRY:
        raise UnknownBackend(str(name), available_backends())
    if name not in available_backends():
        raise UnknownBackend(name, available_backends())
    module, cls = _REGISTRY[name]
    factory: Callable[[], QPBackend] = getattr(importlib.import_module(module), cls)
    return factory()
