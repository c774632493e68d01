"""Re-exports of the control layer, which now lives in :mod:`hqp.control`.

``Command``, ``Feasibility``, ``TaskStatus``, ``FeasibilityReport``: :mod:`hqp.control.command`;
``Controller``, ``WholeBodyController`` (the servo): :mod:`hqp.control.servo`; the feasibility
report's computation: :mod:`hqp.control.diagnostics`; ``standing_stack``,
``standing_controller`` and the controllers by name: :mod:`hqp.control.presets`.
"""

from hqp.control.command import Command, Feasibility, FeasibilityReport, TaskStatus
from hqp.control.presets import standing_controller, standing_stack
from hqp.control.servo import Controller, WholeBodyController

__all__ = [
    "Command",
    "Controller",
    "Feasibility",
    "FeasibilityReport",
    "TaskStatus",
    "WholeBodyController",
    "standing_controller",
    "standing_stack",
]
