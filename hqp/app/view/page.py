"""The web page of ``hqp view``: a viser server drawing a :class:`ViewSession`.

viser (``pip install viser``) serves a built three.js client over a websocket and lets
Python add scene objects, transform handles and GUI controls; mjviser draws a MuJoCo model's
geoms in it (:class:`mjviser.ViserMujocoScene`, from the MuJoCo developers). The page holds:

* the robot, drawn from the simulator's body poses at up to :data:`FRAME_RATE` Hz;
* a transform handle on each goal of the active position, orientation and pose tasks that
  reads a runtime input (the red sphere of the seed's Figure 14), and the same goal as three
  numbers; both send the goal to :meth:`ViewSession.set_goal` (the runtime-input path);
* the task panel: active tasks by level with status, the level a conflict yields to, the
  residual, the error and the smallest singular value (seed 001, Figure 10);
* a button per library behavior, pause / resume, single step, reset, and a push of a
  chosen force and duration (Figure 15);
* strip charts of the centre-of-gravity error, the torque ratio to the limits and the
  per-step torque change.

The page runs on its own thread (:meth:`ViewerPage.serve`) and only reads the session's
published snapshots and sends it commands, so neither waits on the other.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from typing import Any

import numpy as np

from hqp.app.view.session import (
    CHART_SIGNALS,
    PANEL_PERIOD,
    PUBLISH_PERIOD,
    GoalHandle,
    Snapshot,
    TaskRow,
    ViewSession,
    rpy_to_wxyz,
    wxyz_to_rpy,
)
from hqp.errors import HQPError

try:  # the optional extra `view`: `pip install -e ".[view]"`
    import mjviser
    import viser
except ImportError as _exc:  # pragma: no cover - depends on the environment
    viser = None
    mjviser = None
    _IMPORT_ERROR: str | None = str(_exc)
else:
    _IMPORT_ERROR = None

logger = logging.getLogger(__name__)

FRAME_RATE = 1.0 / PUBLISH_PERIOD
"""Scene updates sent to the page per second (at most) [Hz]: the rate the loop publishes at."""
DRAG_HOLD = 0.5
"""After the user moves a goal, the page leaves its handle alone this long [s]."""
CHART_LABELS = {
    "cog_error_mm": ("CoG error [mm]", "#d62728"),
    "torque_ratio": ("max |tau| / tau_max", "#1f77b4"),
    "torque_change_nm": ("torque change per step [N m]", "#2ca02c"),
}
CAMERA_POSITION = (1.9, -1.7, 1.45)
"""Initial camera position [m], world frame (z up)."""
CAMERA_LOOK_AT = (0.15, 0.0, 0.85)
"""Point the initial camera looks at [m]."""
CAMERA_FOV_DEG = 75.0
"""Vertical field of view of the camera [deg]."""
GOAL_HANDLE_SCALE = 0.25
"""Size of the goal handles [m]."""
STATUS_MARK = {"satisfied": "ok", "conflict": "CONFLICT", "singular": "SINGULAR",
               "inactive": "inactive"}


class ViewError(HQPError):
    """The viewer cannot start (missing extra, port in use)."""


def require_viser() -> None:
    """Raise :class:`ViewError` when the ``view`` extra is not installed."""
    if _IMPORT_ERROR is not None:
        raise ViewError(f"hqp view needs the view extra (pip install -e \".[view]\"): "
                        f"{_IMPORT_ERROR}")


def check_port(host: str, port: int) -> None:
    """Raise :class:`ViewError` when ``port`` is not in 1-65535 or cannot be bound on ``host``."""
    if not 0 < port < 65536:
        raise ViewError(f"port must be in 1-65535, got {port}")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        try:
            sock.bind((host, port))
        except OSError as exc:
            raise ViewError(f"port {port} on {host} is in use (another hqp view?): "
                            f"{exc.strerror}; pick another with --port") from None


def task_table(rows: tuple[TaskRow, ...]) -> str:
    """Return the task panel as a markdown table (level, status, residual, error, sigma)."""
    lines = ["| lvl | task | status | residual | error | σ_min |",
             "|---:|---|---|---:|---:|---:|"]
    for r in rows:
        status = STATUS_MARK.get(r.status, r.status)
        if r.status == "conflict" and r.yields_to is not None:
            status += f" → {r.yields_to}"
        err = "" if not np.isfinite(r.error) else f"{r.error:.2g}"
        sig = "" if not np.isfinite(r.sigma_min) else f"{r.sigma_min:.2g}"
        lines.append(f"| {r.level} | {r.name} | {status} | {r.residual:.2g} | {err} | {sig} |")
    return "\n".join(lines)


def goal_text(snap: Snapshot) -> str:
    """Return the distance of each position goal's task frame to the goal [m], one line per goal."""
    lines = []
    for g in snap.goals:
        frame = snap.frames.get(g.task)
        if g.kind == "position" and frame is not None:
            d = float(np.linalg.norm(np.subtract(frame, g.value)))
            lines.append(f"`{g.task}`: {d:.3f} m from `{g.input}`")
    return "  \n".join(lines) or "no goal to move in this phase"


class ViewerPage:
    """The viser server and page of a :class:`ViewSession` (see the module docstring).

    Args:
        session: The running session.
        host: Interface to serve on.
        port: Port to serve on (refused when in use: :class:`ViewError`).

    Raises:
        ViewError: viser missing, or the port in use.

    """

    def __init__(self, session: ViewSession, host: str = "127.0.0.1", port: int = 8080) -> None:
        require_viser()
        check_port(host, port)
        self.session = session
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        if self.server.get_port() != port:  # viser moves on to the next free port
            self.server.stop()
            raise ViewError(f"port {port} on {host} is in use (another hqp view?); "
                            "pick another with --port")
        self.url = f"http://{host}:{port}"
        self.frames_sent = 0
        self.draw_cpu = 0.0  # CPU time of the drawing thread [s]
        self._started = time.monotonic()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._pending: dict[str, np.ndarray] = {}
        self._touched: dict[str, float] = {}
        self._pending_lock = threading.Lock()
        self._goal_key: tuple[tuple[str, str], ...] | None = None
        self._goal_handles: dict[str, Any] = {}
        self._goal_inputs: dict[str, Any] = {}
        self._last_panel = 0.0
        self._fps: list[float] = []
        model = session.robot.mujoco_model()
        self.scene = mjviser.ViserMujocoScene(self.server, model, num_envs=1)
        self.scene.camera_tracking_enabled = False  # world coordinates for the handles
        self.server.initial_camera.position = CAMERA_POSITION
        self.server.initial_camera.look_at = CAMERA_LOOK_AT
        self.server.initial_camera.fov = np.radians(CAMERA_FOV_DEG)
        self.server.gui.configure_theme(control_width="large")
        self._build_gui()

    # -- the page ---------------------------------------------------------------------------

    def _build_gui(self) -> None:
        gui = self.server.gui
        s = self.session
        self.status = gui.add_markdown("starting…")
        with gui.add_folder("Behaviors"):
            for name in s.behaviors:
                button = gui.add_button(name)
                button.on_click(lambda _e, n=name: s.select(n))
        with gui.add_folder("Simulation"):
            self.pause_button = gui.add_button("Pause")
            self.pause_button.on_click(lambda _e: self._toggle_pause())
            gui.add_button("Step").on_click(lambda _e: s.single_step())
            gui.add_button("Reset").on_click(lambda _e: s.reset())
            self.push_force = gui.add_vector3("Push force [N]", initial_value=(60.0, 0.0, 0.0),
                                              step=10.0)
            self.push_duration = gui.add_number("Push duration [s]", initial_value=0.1,
                                                min=0.001, max=2.0, step=0.05)
            gui.add_button("Push").on_click(
                lambda _e: s.push(self.push_force.value, float(self.push_duration.value)))
        self.goal_folder = gui.add_folder("Goals")
        with self.goal_folder:
            self.goal_text = gui.add_markdown("")
        with gui.add_folder("Tasks"):
            self.tasks = gui.add_markdown("")
        with gui.add_folder("Signals"):
            self.charts = {}
            empty = np.zeros(2)
            for signal in CHART_SIGNALS:
                label, color = CHART_LABELS[signal]
                self.charts[signal] = gui.add_uplot(
                    data=(np.array([0.0, 1e-3]), empty), title=label,
                    series=({"label": "t [s]"}, {"label": label, "stroke": color, "width": 2}),
                    scales={"x": {"time": False}}, aspect=2.5)

    def _toggle_pause(self) -> None:
        snap = self.session.snapshot()
        if snap is not None and snap.paused:
            self.session.resume()
        else:
            self.session.pause()

    def _rebuild_goals(self, goals: tuple[GoalHandle, ...]) -> None:
        """Make handles and number fields for the goals of the active tasks (set changed)."""
        for h in self._goal_handles.values():
            h.remove()
        for h in self._goal_inputs.values():
            h.remove()
        self._goal_handles, self._goal_inputs = {}, {}
        for g in goals:
            orientation = g.kind == "orientation"
            handle = self.server.scene.add_transform_controls(
                f"/goals/{g.input}", scale=GOAL_HANDLE_SCALE, disable_rotations=not orientation,
                disable_axes=orientation, disable_sliders=orientation,
                position=g.value if not orientation else (0.0, 0.0, 0.0),
                wxyz=rpy_to_wxyz(g.value) if orientation else (1.0, 0.0, 0.0, 0.0))
            if not orientation:
                self.server.scene.add_icosphere(f"/goals/{g.input}/sphere", radius=0.04,
                                                color=(220, 30, 30))
            handle.on_update(lambda _e, g=g, h=handle: self._moved(
                g.input, wxyz_to_rpy(h.wxyz) if g.kind == "orientation" else h.position))
            with self.goal_folder:
                field = self.server.gui.add_vector3(
                    f"{g.input} ({g.task})", initial_value=g.value, step=0.01)
            field.on_update(lambda _e, g=g, f=field: self._moved(g.input, f.value))
            self._goal_handles[g.input] = handle
            self._goal_inputs[g.input] = field

    def _moved(self, name: str, value: Any) -> None:
        with self._pending_lock:
            self._pending[name] = np.asarray(value, dtype=float)
            self._touched[name] = time.monotonic()

    # -- the drawing thread -----------------------------------------------------------------

    def serve(self) -> None:
        """Start the drawing thread."""
        self._thread = threading.Thread(target=self._main, name="hqp-view-page", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop drawing and the server."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
        self.server.stop()

    @property
    def updates_per_second(self) -> float:
        """Scene updates sent per second over the last two seconds."""
        now = time.monotonic()
        recent = [t for t in self._fps if t > now - 2.0]
        return len(recent) / 2.0

    def figures(self) -> dict[str, float]:
        """Return the drawing thread's figures: seconds served, frames sent, CPU times [s].

        ``draw_cpu_s`` is the drawing thread's, ``process_cpu_s`` the whole process's (the
        loop, the drawing, viser's server threads).
        """
        return {"seconds": round(time.monotonic() - self._started, 3),
                "frames_sent": self.frames_sent, "draw_cpu_s": round(self.draw_cpu, 3),
                "process_cpu_s": round(time.process_time(), 3)}

    def _main(self) -> None:
        last: Snapshot | None = None
        period = 1.0 / FRAME_RATE
        self._started = time.monotonic()
        cpu0 = time.thread_time()
        while not self._stop.is_set():
            self.draw_cpu = time.thread_time() - cpu0
            t0 = time.monotonic()
            self._send_goals()
            snap = self.session.snapshot()
            if snap is not None and snap is not last:
                try:
                    self._draw(snap)
                except Exception:  # noqa: BLE001 - a client gone mid-update must not end it
                    logger.exception("view: drawing failed")
                last = snap
            self._stop.wait(max(0.0, period - (time.monotonic() - t0)))

    def _send_goals(self) -> None:
        with self._pending_lock:
            pending, self._pending = self._pending, {}
        for name, value in pending.items():
            self.session.set_goal(name, value)

    def _draw(self, snap: Snapshot) -> None:
        self.scene.update_from_arrays(snap.xpos[None], snap.xmat.reshape(-1, 3, 3)[None])
        now = time.monotonic()
        self.frames_sent += 1
        self._fps = [t for t in self._fps if t > now - 2.0] + [now]
        key = tuple((g.input, g.kind) for g in snap.goals)
        if key != self._goal_key:
            self._rebuild_goals(snap.goals)
            self._goal_key = key
        for g in snap.goals:
            if now - self._touched.get(g.input, -1e9) < DRAG_HOLD:
                continue  # the user is moving it
            handle = self._goal_handles[g.input]
            if g.kind == "orientation":
                handle.wxyz = rpy_to_wxyz(g.value)
                frame = snap.frames.get(g.task)
                if frame is not None:
                    handle.position = frame
            else:
                handle.position = g.value
            field = self._goal_inputs[g.input]
            if not np.allclose(field.value, g.value, atol=1e-6):
                field.value = g.value
        if now - self._last_panel >= PANEL_PERIOD:
            self._last_panel = now
            self._panel(snap)

    def _panel(self, snap: Snapshot) -> None:
        state = "paused" if snap.paused else "running"
        fell = f" — **fell** ({snap.fell})" if snap.fell else ""
        self.status.content = (
            f"**{snap.behavior}** · phase `{snap.phase}` · t = {snap.t:.2f} s · {state}{fell}  \n"
            f"real-time factor {snap.realtime_factor:.2f} · "
            f"{self.updates_per_second:.0f} scene updates/s")
        self.pause_button.label = "Resume" if snap.paused else "Pause"
        self.tasks.content = task_table(snap.tasks)
        self.goal_text.content = goal_text(snap)
        if snap.chart_t.size >= 2:
            for signal, chart in self.charts.items():
                y = snap.charts[signal]
                chart.data = (snap.chart_t, np.where(np.isfinite(y), y, 0.0))
