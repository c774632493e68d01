"""Re-export of :mod:`hqp.model.geometry` (the plane convex hull), its old path."""

from hqp.model.geometry import monotone_chain

__all__ = ["monotone_chain"]
