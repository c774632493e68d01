"""MuJoCo execution: the simulator, the closed loop, rendering.

* :class:`Simulator`: the robot's MJCF, motors, contact sensing, no silent torque clipping,
  the fall check.
* :func:`closed_loop`: the one closed loop (pushes, timed events, noise and delay, hooks).
* :func:`simulate`: a controller in that loop, with a :class:`Log` of the run.
* :func:`render_png`, :func:`record`: offscreen rendering where the machine supports it.

The pinocchio/MuJoCo state conversion lives in :mod:`hqp.sim.convert` (one place).
"""

from hqp.sim.loop import Event, Noise, Outcome, Push, Step, closed_loop
from hqp.sim.render import RenderUnavailable, record, render_png, rendering_available
from hqp.sim.run import Log, simulate
from hqp.sim.simulator import FALL_HEIGHT_RATIO, ContactReading, Simulator, inside_polygon

__all__ = [
    "FALL_HEIGHT_RATIO",
    "ContactReading",
    "Event",
    "Log",
    "Noise",
    "Outcome",
    "Push",
    "RenderUnavailable",
    "Simulator",
    "Step",
    "closed_loop",
    "inside_polygon",
    "record",
    "render_png",
    "rendering_available",
    "simulate",
]
