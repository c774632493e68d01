"""Re-export of :mod:`hqp.model.world` (obstacles), its old path."""

from hqp.model.world import Box, Capsule, Sphere, World

__all__ = ["Box", "Capsule", "Sphere", "World"]
