"""Bundled robots: ``hqp.robots.load(name)`` for ``paper-humanoid``, ``g1`` and ``talos``.

Every robot gives the same frame names for the common roles: ``left_foot``,
``right_foot`` (sole centres on the sole surface, z normal to the sole),
``left_hand``, ``right_hand``, ``trunk`` (the chest, after the torso joints),
``pelvis`` (the floating base) and ``head`` where the robot has one; the same
points are sites of the same names in the MuJoCo model.
"""

from __future__ import annotations

import functools

from hqp.errors import UnknownName
from hqp.robots.robot import BodyCapsule, ContactSurface, Robot

NAMES = ("paper-humanoid", "g1", "talos")
"""Names accepted by :func:`load`."""


@functools.lru_cache(maxsize=None)
def load(name: str) -> Robot:
    """Return the bundled robot of that name.

    Robots are immutable records; :meth:`Robot.model` and
    :meth:`Robot.mujoco_model` return fresh models on every call.

    Raises:
        UnknownName: ``name`` is not one of :data:`NAMES` (lists them).

    """
    if name == "paper-humanoid":
        from hqp.robots import _paper

        return _paper.robot()
    if name in ("g1", "talos"):
        from hqp.robots import erd

        return erd.robot(name)
    raise UnknownName("robot", name, NAMES)


__all__ = ["NAMES", "BodyCapsule", "ContactSurface", "Robot", "load"]
