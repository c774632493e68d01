"""Offscreen rendering of a simulation to PNG frames or an MP4 video.

Rendering needs an offscreen OpenGL context: ``MUJOCO_GL=egl`` (GPU or Mesa EGL) or
``MUJOCO_GL=osmesa`` (software). :func:`rendering_available` checks that one works here;
:func:`render_png` and :func:`record` raise :class:`RenderUnavailable` with the reason when it
does not, so callers can skip with a clear message. MP4 output needs ``imageio`` with its
ffmpeg plugin (``pip install imageio imageio-ffmpeg``); without it :func:`record` writes PNG
frames and says so.
"""

from __future__ import annotations

import functools
import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hqp.errors import HQPError
from hqp.sim.run import Log, simulate
from hqp.sim.simulator import Simulator

if TYPE_CHECKING:
    from hqp.robots import Robot
    from hqp.sim.loop import Event, Push

logger = logging.getLogger(__name__)


class RenderUnavailable(HQPError):
    """No offscreen OpenGL context on this machine (the message says why and what to try)."""


@functools.lru_cache(maxsize=1)
def rendering_available() -> tuple[bool, str]:
    """Whether MuJoCo can render offscreen here, and a message saying how or why not."""
    import mujoco

    backend = os.environ.get("MUJOCO_GL", "(unset)")
    xml = ('<mujoco><worldbody><light pos="0 0 3"/><geom type="plane" size="1 1 .1"/>'
           "</worldbody></mujoco>")
    try:
        m = mujoco.MjModel.from_xml_string(xml)
        d = mujoco.MjData(m)
        r = mujoco.Renderer(m, 16, 16)
        mujoco.mj_forward(m, d)
        r.update_scene(d)
        r.render()
        r.close()
    except Exception as exc:  # noqa: BLE001 - any GL failure means "not available"
        return False, (f"offscreen rendering unavailable with MUJOCO_GL={backend}: {exc}; "
                       "set MUJOCO_GL=egl or MUJOCO_GL=osmesa before importing mujoco")
    return True, f"offscreen rendering with MUJOCO_GL={backend}"


def _require() -> None:
    ok, message = rendering_available()
    if not ok:
        raise RenderUnavailable(message)


class _Camera:
    """A renderer with a free camera that follows the robot's base."""

    def __init__(self, sim: Simulator, width: int, height: int, distance: float,
                 azimuth: float, elevation: float) -> None:
        import mujoco

        _require()
        self.sim = sim
        self.renderer = mujoco.Renderer(sim.mj_model, height, width)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.distance = distance
        self.camera.azimuth = azimuth
        self.camera.elevation = elevation

    def frame(self) -> np.ndarray:
        self.camera.lookat[:] = self.sim.mj_data.xpos[1]
        self.renderer.update_scene(self.sim.mj_data, self.camera)
        return self.renderer.render().copy()

    def close(self) -> None:
        self.renderer.close()


def render_png(sim: Simulator, path: str | Path, *, width: int = 640, height: int = 480,
               distance: float = 3.0, azimuth: float = 135.0, elevation: float = -15.0) -> Path:
    """Render the current state of a simulation to a PNG file.

    Raises:
        RenderUnavailable: No offscreen OpenGL context (the message says what to try).

    """
    import matplotlib.pyplot as plt

    cam = _Camera(sim, width, height, distance, azimuth, elevation)
    try:
        image = cam.frame()
    finally:
        cam.close()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    plt.imsave(path, image)
    return path


class Video:
    """Offscreen frames at ``fps`` of simulated time, written as an MP4 or PNG frames.

    ``path`` ending in ``.mp4`` asks for a video (needs imageio with its ffmpeg plugin; a
    warning says when PNG frames are written instead); otherwise ``path`` is a directory of
    PNG frames.

    Raises:
        RenderUnavailable: No offscreen OpenGL context.

    """

    def __init__(self, sim: Simulator, path: str | Path, *, fps: int = 30, width: int = 640,
                 height: int = 480, distance: float = 3.0, azimuth: float = 135.0,
                 elevation: float = -15.0) -> None:
        self.camera = _Camera(sim, width, height, distance, azimuth, elevation)
        self.path = Path(path)
        self.fps = fps
        self.next_t = 0.0
        self.frames: list[np.ndarray] = []

    def capture(self, t: float) -> None:
        """Grab a frame when one is due at simulated time ``t`` [s]."""
        if t + 1e-9 < self.next_t:
            return
        self.next_t += 1.0 / self.fps
        self.frames.append(self.camera.frame())

    def close(self) -> Path:
        """Write the frames; return the path written (the MP4, or the folder of PNGs)."""
        import matplotlib.pyplot as plt

        self.camera.close()
        path = self.path
        if path.suffix == ".mp4":
            try:
                import imageio.v2 as imageio

                path.parent.mkdir(parents=True, exist_ok=True)
                imageio.mimwrite(path, self.frames, fps=self.fps)
                return path
            except ImportError:
                logger.warning("imageio (with imageio-ffmpeg) is not installed: writing PNG "
                               "frames instead of %s", path)
            except Exception as exc:  # noqa: BLE001 - a missing ffmpeg plugin
                logger.warning("MP4 writing failed (%s): writing PNG frames instead", exc)
            path = path.with_suffix("")
        path.mkdir(parents=True, exist_ok=True)
        for i, image in enumerate(self.frames):
            plt.imsave(path / f"frame_{i:05d}.png", image)
        return path


def record(
    robot: Robot,
    controller: Any,
    duration: float,
    path: str | Path,
    events: Sequence[Event | Push] = (),
    *,
    fps: int = 30,
    width: int = 640,
    height: int = 480,
    **kwargs: Any,
) -> tuple[Log, Path]:
    """Run :func:`~hqp.sim.simulate` and record it (:class:`Video`).

    Returns:
        The log and the path written (the MP4 file, or the directory of PNG frames).

    Raises:
        RenderUnavailable: No offscreen OpenGL context.

    """
    _require()
    sim = kwargs.pop("sim", None) or Simulator(robot, dt=getattr(controller, "dt", 0.001))
    video = Video(sim, path, fps=fps, width=width, height=height)
    try:
        log = simulate(robot, controller, duration, events, sim=sim,
                       on_step=lambda s, cmd: video.capture(s.time), **kwargs)
    finally:
        written = video.close()
    return log, written
