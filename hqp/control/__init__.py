"""The control layer: robot state -> levels -> resolver -> torques, and its report.

- :mod:`~hqp.control.command`: :class:`Command` and the feasibility report;
- :mod:`~hqp.control.servo`: the step skeleton (:class:`WholeBodyController`);
- :mod:`~hqp.control.resolver`: what solves the built levels (:class:`HQPResolver`);
- :mod:`~hqp.control.diagnostics`: the per-task feasibility report;
- :mod:`~hqp.control.presets`: the standing constraint set and the controllers by name;
- :mod:`~hqp.control.nullspace`: the papers' null-space law as a resolver.
"""

from hqp.control.command import Command, Feasibility, FeasibilityReport, TaskStatus
from hqp.control.nullspace import NullSpaceController, NullSpaceResolver
from hqp.control.presets import (
    CONTROLLER_NAMES,
    CONTROLLERS,
    constraint_controller,
    constraint_stack,
    make_controller,
    make_standing_controller,
    standing_controller,
    standing_nullspace_controller,
    standing_stack,
)
from hqp.control.resolver import HQPResolver, Resolver
from hqp.control.servo import Controller, WholeBodyController

__all__ = [
    "CONTROLLERS",
    "CONTROLLER_NAMES",
    "Command",
    "Controller",
    "Feasibility",
    "FeasibilityReport",
    "HQPResolver",
    "NullSpaceController",
    "NullSpaceResolver",
    "Resolver",
    "TaskStatus",
    "WholeBodyController",
    "constraint_controller",
    "constraint_stack",
    "make_controller",
    "make_standing_controller",
    "standing_controller",
    "standing_nullspace_controller",
    "standing_stack",
]
