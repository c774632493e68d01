"""hqp: whole-body control of humanoid robots with a strict lexicographic hierarchy of QPs.

The names a user starts from, imported on first use (``import hqp`` stays light)::

    import hqp
    robot = hqp.robots.load("g1")                 # a bundled robot
    controller = hqp.standing_controller(robot)   # constraints, balance, posture
    log = hqp.simulate(robot, controller, 1.0)    # one second in MuJoCo
    solution = hqp.solve([hqp.Level(A=A, b=b)])   # the solver alone
"""

import importlib
from typing import Any

from hqp.errors import (
    BehaviorFileError,
    HQPError,
    InvalidFrame,
    InvalidGain,
    InvalidInput,
    InvalidLevel,
    SolverFailure,
    UnknownBackend,
    UnknownName,
)

__version__ = "0.1.0"

_LAZY = {
    "robots": ("hqp.robots", None),
    "standing_controller": ("hqp.control.presets", "standing_controller"),
    "WholeBodyController": ("hqp.control.servo", "WholeBodyController"),
    "Command": ("hqp.control.command", "Command"),
    "simulate": ("hqp.sim.run", "simulate"),
    "Simulator": ("hqp.sim.simulator", "Simulator"),
    "Push": ("hqp.sim.loop", "Push"),
    "Level": ("hqp.solver.level", "Level"),
    "solve": ("hqp.solver.hierarchy", "solve"),
    "HierarchicalSolver": ("hqp.solver.hierarchy", "HierarchicalSolver"),
}
"""Public name -> (module, attribute; ``None``: the module itself)."""


def __getattr__(name: str) -> Any:
    try:
        module, attribute = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'hqp' has no attribute {name!r}") from None
    value = importlib.import_module(module)
    if attribute is not None:
        value = getattr(value, attribute)
    globals()[name] = value
    return value

__all__ = [
    "BehaviorFileError",
    "HQPError",
    "InvalidFrame",
    "InvalidGain",
    "InvalidInput",
    "InvalidLevel",
    "SolverFailure",
    "UnknownBackend",
    "UnknownName",
    "__version__",
    *_LAZY,
]
