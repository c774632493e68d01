"""The action layer (seed 001): action primitives and behaviors as state machines.

* :class:`ActionPrimitive`: a named task set, each task with its priority level and
  parameters; goals written ``input.<name>`` are runtime inputs.
* :class:`Behavior`: a state machine over action primitives whose phases form an
  :class:`enum.Enum`; transitions read simulated time, sensed state and the servo's
  feasibility flags; a safety phase is entered when a watched task becomes infeasible.
* Behavior description files (TOML, :func:`load_behavior`), and the bundled library
  (:func:`library_names`): ``stand``, ``reach``, ``mimic``, ``screwgun``, ``squat-jump``,
  ``walk``.
* The walk planner (:class:`~hqp.behaviors.planners.WalkPlanner`, ``[planner] type = "walk"``):
  naive footsteps at the robot's own foot spacing, single and double supports, and the
  centre of mass by ZMP preview control of the cart-table model
  (:mod:`hqp.behaviors.lipm`), as ``plan.*`` values.
* :func:`~hqp.behaviors.setup.prepare`: a behavior loaded for a robot, on a controller of
  its own, ready to be driven like a controller (:meth:`Behavior.step`).

This layer imports neither the simulator nor the command line: ``hqp run``
(:func:`hqp.app.run.run_behavior`) drives a behavior in MuJoCo through
:func:`hqp.sim.closed_loop`.
"""

from hqp.behaviors.behavior import Behavior, FeasibilityEvent
from hqp.behaviors.inputs import InputStream
from hqp.behaviors.loader import LIBRARY, library_names, load_behavior, parse_behavior
from hqp.behaviors.spec import (
    ActionPrimitive,
    BehaviorSpec,
    InputSpec,
    PhaseSpec,
    PlannerSpec,
    TaskSpec,
    Transition,
)

__all__ = [
    "LIBRARY",
    "ActionPrimitive",
    "Behavior",
    "BehaviorSpec",
    "FeasibilityEvent",
    "InputSpec",
    "InputStream",
    "PhaseSpec",
    "PlannerSpec",
    "TaskSpec",
    "Transition",
    "library_names",
    "load_behavior",
    "parse_behavior",
]
