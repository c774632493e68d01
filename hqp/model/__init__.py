"""The robot model layer: the pinocchio wrapper and what the control primitives read besides.

- :mod:`hqp.model.model`: :class:`RobotModel` (kinematics, dynamics, frames; one
  :meth:`~RobotModel.update` per control step) and :class:`RobotState` (``q``, ``v`` in
  pinocchio's convention);
- :mod:`hqp.model.layout`: the decision-variable layout ``x = [qdd | f_1 | ... | f_k]``
  (:class:`~hqp.model.layout.Layout`, :class:`~hqp.model.layout.ContactType`);
- :mod:`hqp.model.world`: obstacles (spheres, capsules, boxes) for collision rows and scenes;
- :mod:`hqp.model.geometry`: the plane convex hull of the support polygons.

The bundled robots stay in :mod:`hqp.robots` (``hqp.robots.load``, package data paths).
"""

from hqp.model.model import LWA, RobotModel, RobotState

__all__ = ["LWA", "RobotModel", "RobotState"]
