"""MuJoCo execution: the simulator, the closed loop, rendering.

* :class:`Simulator`: the robot's MJCF, motors, contact sensing, no silent torque clipping.
* :func:`simulate`: controller in closed loop with pushes, timed events, noise and delay; a
  :class:`Log` of the run.
* :func:`render_png`, :func:`record`: offscreen rendering where the machine supports it.

The pinocchio/MuJoCo state conversion lives in :mod:`hqp.sim.convert` (one place).
"""

from hqp.sim.render import RenderUnavailable, record, render_png, rendering_available
from hqp.sim.run import Event, Log, Noise, Push, simulate
from hqp.sim.simulator import FALL_HEIGHT_RATIO, ContactReading, Simulator, inside_polygon

__all__ = [
    "FALL_HEIGHT_RATIO",
    "ContactReading",
    "Event",
    "Log",
    "Noise",
    "Push",
    "RenderUnavailable",
    "Simulator",
    "inside_polygon",
    "record",
    "render_png",
    "rendering_available",
    "simulate",
]
