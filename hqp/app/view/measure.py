"""Measure ``hqp view`` in a headless Chromium: page frame rate and the loop's real-time factor.

``python -m hqp.app.view.measure --robot g1 --seconds 20 --screenshot docs/figures/view.png``
starts ``hqp view stand --no-browser`` (with ``--fast``: ``hqp view stand --fast``) on a free
port, opens its page in Debian's ``chromium`` through Playwright (software WebGL where there
is no GPU), clicks *reach*, drags the hand goal's handle with the mouse, up and down by 60 px
one drag after the other, and reports, as one JSON object on stdout: the page's frames per
second (browser ``requestAnimationFrame`` callbacks), the scene updates the server sent per
second and the loop's real-time factor (both as the page shows them), the reach run's
real-time factor, the loop thread's CPU time per simulated second and its share of the
loop's wall time (a loop that waits on nothing, the GIL included, runs all of its wall time
when ``--fast``), the drawing thread's share of a core, the viewer process's CPU time, and
where it wrote the screenshot.
The browser helpers are shared with ``tests/test_view.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from hqp.app.view.page import CAMERA_FOV_DEG, CAMERA_LOOK_AT, CAMERA_POSITION, GOAL_HANDLE_SCALE

try:  # test extra only: `pip install playwright`, and a chromium from the system
    from playwright.sync_api import TimeoutError as PageTimeout
    from playwright.sync_api import sync_playwright
except ImportError:  # pragma: no cover - depends on the environment
    sync_playwright = None
    PageTimeout = TimeoutError

HAND_GOAL = "hand_goal (hand)"
"""Label of the reach behavior's goal field in the page."""

CHROMIUM_CANDIDATES = ("chromium", "chromium-browser", "google-chrome")
CHROMIUM_ARGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox")
"""Software WebGL (no GPU needed); no sandbox (CI containers run as root)."""
DRAG_PIXELS = 60
"""Length of each mouse drag of the goal handle's vertical arrow [px] (up, then down)."""
SCREENSHOT_HEIGHT = 1750
"""Height of the screenshot's viewport [px] (the measurement runs at ``--height``)."""
FPS_SCRIPT = """() => { window.hqpFrames = 0;
    const frame = () => { window.hqpFrames++; requestAnimationFrame(frame); };
    requestAnimationFrame(frame); }"""
"""Counts the frames the browser draws (``requestAnimationFrame`` callbacks) in ``hqpFrames``."""


def chromium() -> str | None:
    """Return the path of a system Chromium, or ``None``."""
    for name in CHROMIUM_CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


def free_port() -> int:
    """Return a free TCP port on localhost."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def start_view(port: int, log: Path, record: Path | None = None, behavior: str = "stand",
               robot: str | None = None, timeout: float = 180.0,
               fast: bool = False) -> subprocess.Popen:
    """Start ``hqp view BEHAVIOR --no-browser`` (``--fast``) as a process; return once it serves.

    Its stderr goes to the file ``log`` (a pipe left unread would fill and block it).
    """
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-m", "hqp.app.cli", "view", behavior, "--no-browser",
           "--port", str(port)]
    if record is not None:
        cmd += ["--record", str(record)]
    if robot is not None:
        cmd += ["--robot", robot]
    if fast:
        cmd += ["--fast"]
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("w") as err:
        proc = subprocess.Popen(cmd, stderr=err, stdout=subprocess.DEVNULL, env=env)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if "Ctrl-C stops" in log.read_text():
            return proc
        time.sleep(0.2)
    proc.kill()
    raise RuntimeError(f"hqp view did not start: {' '.join(cmd)}\n{log.read_text()}")


def stop_view(proc: subprocess.Popen, timeout: float = 60.0) -> int:
    """Ctrl-C the viewer; return its exit status (killed, and raises, past ``timeout``)."""
    proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise


def launch(p: Any, executable: str) -> Any:
    """Launch a headless Chromium with software WebGL."""
    return p.chromium.launch(executable_path=executable, headless=True, args=list(CHROMIUM_ARGS))


def vector_inputs(page: Any, label: str) -> list[Any]:
    """Return the three number fields of a viser vector control, by its label."""
    page.evaluate("""(label) => {
        const l = [...document.querySelectorAll('label')].find(e => e.textContent === label);
        let row = l;
        while (row && row.querySelectorAll('input').length < 3) row = row.parentElement;
        row.querySelectorAll('input').forEach((e, i) => e.setAttribute('data-hqp', label + i));
    }""", label)
    return [page.locator(f"[data-hqp='{label}{i}']") for i in range(3)]


def set_vector(fields: list[Any], values: Any) -> None:
    """Type a vector into a viser vector control (each number, then Enter)."""
    for f, v in zip(fields, values):
        f.fill(f"{v:.3f}")
        f.press("Enter")


def screen_point(point: Any, width: int, height: int) -> tuple[float, float]:
    """Return the pixel ``(x, y)`` of a world point ``(3,)`` [m] seen by the page's camera.

    The camera the page starts with (:data:`~hqp.app.view.page.CAMERA_POSITION`, looking at
    :data:`~hqp.app.view.page.CAMERA_LOOK_AT`, z up, vertical field of view
    :data:`~hqp.app.view.page.CAMERA_FOV_DEG`) on a canvas filling the viewport.
    """
    cam = np.asarray(CAMERA_POSITION, dtype=float)
    forward = np.asarray(CAMERA_LOOK_AT, dtype=float) - cam
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    d = np.asarray(point, dtype=float) - cam
    scale = 0.5 * height / np.tan(np.radians(CAMERA_FOV_DEG) / 2)
    return (0.5 * width + scale * (d @ right) / (d @ forward),
            0.5 * height - scale * (d @ up) / (d @ forward))


def drag_goal_up(page: Any, goal: Any, pixels: float, width: int, height: int,
                 steps: int = 10) -> None:
    """Drag the vertical arrow of a goal handle at ``goal`` ``(3,)`` [m] up by ``pixels``.

    A real mouse drag (press on the arrow, move in ``steps``, release), the way a user moves
    the seed's red sphere; negative ``pixels`` drag it down. The camera must not have moved.
    """
    x, y = screen_point(np.asarray(goal, dtype=float) + [0.0, 0.0, 0.4 * GOAL_HANDLE_SCALE],
                        width, height)
    page.mouse.move(x, y)
    page.wait_for_timeout(300)
    page.mouse.down()
    page.wait_for_timeout(300)
    for k in range(1, steps + 1):
        page.mouse.move(x, y - pixels * k / steps)
        page.wait_for_timeout(100)
    page.mouse.up()


def drag_goal(page: Any, pixels: float, width: int, height: int, attempts: int = 3,
              timeout_ms: float = 60000) -> tuple[list[float], list[float]]:
    """Drag the hand goal's vertical arrow by ``pixels``; return the goal before and after.

    A drag that misses the arrow turns the camera instead; the page is then reloaded (the
    camera back to its start) and the drag tried again, ``attempts`` times in all.

    Raises:
        RuntimeError: No drag moved the goal (by 3 cm at least, in the dragged direction).

    """
    sign = 1.0 if pixels > 0 else -1.0
    for _ in range(attempts):
        before = [float(f.input_value()) for f in vector_inputs(page, HAND_GOAL)]
        drag_goal_up(page, before, pixels, width, height)
        try:
            page.wait_for_function(
                "([id, z, s]) => s * (parseFloat("
                "document.querySelector(`[data-hqp='${id}']`).value) - z) > 0.03",
                arg=[f"{HAND_GOAL}2", before[2], sign], timeout=timeout_ms)
        except PageTimeout:
            page.reload()
            page.get_by_text(re.compile(r"hand: [0-9.]+ m from hand_goal")).wait_for(
                timeout=timeout_ms)
            continue
        return before, [float(f.input_value()) for f in vector_inputs(page, HAND_GOAL)]
    raise RuntimeError(f"{attempts} drags of the hand goal's arrow did not move it")


def page_number(page: Any, pattern: str) -> float:
    """Return the first number captured by ``pattern`` in the page's text."""
    match = re.search(pattern, page.inner_text("body"))
    if match is None:
        raise RuntimeError(f"not in the page: {pattern!r}")
    return float(match.group(1))


def hand_distance(page: Any) -> float:
    """Return the hand's distance to its goal as the page's Goals panel shows it [m]."""
    return page_number(page, r"hand: ([0-9.]+) m from hand_goal")


def open_reach(page: Any, url: str, timeout_ms: float = 180000) -> list[Any]:
    """Open the page, click ``reach``, wait for its reach phase; return its goal fields."""
    page.goto(url)
    page.get_by_role("button", name="reach").click(timeout=timeout_ms)
    page.get_by_text(re.compile(r"reach · phase reach")).wait_for(timeout=timeout_ms)
    page.get_by_text(re.compile(r"hand: [0-9.]+ m from hand_goal")).wait_for(timeout=timeout_ms)
    return vector_inputs(page, HAND_GOAL)


def measure(robot: str | None, seconds: float, screenshot: Path | None,
            width: int = 1280, height: int = 800, fast: bool = False) -> dict[str, Any]:
    """Drag the hand goal for ``seconds`` and measure (see the module docstring)."""
    if sync_playwright is None:
        raise RuntimeError("needs Playwright (pip install playwright)")
    exe = chromium()
    if exe is None:
        raise RuntimeError("needs a system chromium (apt-get install chromium)")
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "view.log"
        proc = start_view(port, log, Path(tmp), behavior="stand", robot=robot, fast=fast)
        try:
            with sync_playwright() as p:
                browser = launch(p, exe)
                page = browser.new_page(viewport={"width": width, "height": height})
                open_reach(page, f"http://127.0.0.1:{port}")
                rtf, ups = [], []
                t0 = time.monotonic()
                k = moved = frames = 0
                page.evaluate(FPS_SCRIPT)
                while time.monotonic() - t0 < seconds:
                    # frames since the counter was (re)installed: a reload loses that count
                    frames += page.evaluate("() => window.hqpFrames || 0")
                    page.evaluate(FPS_SCRIPT)
                    try:
                        drag_goal(page, DRAG_PIXELS * (1 if k % 2 == 0 else -1), width, height,
                                  attempts=1)
                        moved += 1
                    except RuntimeError:
                        pass  # missed: the page was reloaded, the camera is back
                    k += 1
                    rtf.append(page_number(page, r"real-time factor ([0-9.]+)"))
                    ups.append(page_number(page, r"([0-9.]+) scene updates/s"))
                frames += page.evaluate("() => window.hqpFrames || 0")
                elapsed = time.monotonic() - t0
                if screenshot is not None:  # tall enough for the task panel and the charts
                    close = page.locator("button.mantine-Notification-closeButton")
                    if close.count():
                        close.first.click()
                    page.set_viewport_size({"width": width, "height": SCREENSHOT_HEIGHT})
                    time.sleep(3.0)
                    screenshot.parent.mkdir(parents=True, exist_ok=True)
                    page.screenshot(path=str(screenshot))
                distance = hand_distance(page)
                browser.close()
        finally:
            rc = stop_view(proc)
        record = json.loads((Path(tmp) / "run.json").read_text())
        problems = [line for line in log.read_text().splitlines()
                    if line.startswith(("ERROR", "Traceback", "hqp view: the simulation"))]
    reach = record["runs"][-1]
    page_figures = record["viewer"]["page"]
    wall = reach["duration_s"] / reach["realtime_factor"] if reach["realtime_factor"] else 0.0

    def median(xs: list[float]) -> float | None:
        return round(float(sorted(xs)[len(xs) // 2]), 3) if xs else None

    return {"robot": record["viewer"]["robot"], "seconds": round(elapsed, 1),
            "viewport": [width, height], "drags": k, "drags_that_moved_the_goal": moved,
            "page_fps": round(frames / elapsed, 3),
            "scene_updates_per_s_median": median(ups),
            "realtime_factor_median": median(rtf),
            "fast": fast, "loop_realtime_factor": reach["realtime_factor"],
            "loop_cpu_per_simulated_s": (round(reach["loop_cpu_s"] / reach["duration_s"], 3)
                                         if reach["duration_s"] else None),
            "loop_cpu_share_of_wall": round(reach["loop_cpu_s"] / wall, 3) if wall else None,
            "page_draw_cpu_share": round(page_figures["draw_cpu_s"] / page_figures["seconds"], 3),
            "viewer_process_cpu_s": page_figures["process_cpu_s"],
            "reach_loop_cpu_s": reach["loop_cpu_s"], "reach_wall_s": round(wall, 3),
            "scene_updates_sent_per_s": round(page_figures["frames_sent"]
                                              / page_figures["seconds"], 1),
            "step_time_median_ms": reach["step_time_median_ms"],
            "hand_distance_at_end_m": distance, "fell": reach["fell"], "exit_status": rc,
            "viewer_errors": problems,
            "screenshot": None if screenshot is None else str(screenshot)}


def main(argv: list[str] | None = None) -> int:
    """Command line of the measurement (see the module docstring)."""
    parser = argparse.ArgumentParser(prog="python -m hqp.app.view.measure",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default=None, help="robot (default: the behaviors')")
    parser.add_argument("--seconds", type=float, default=20.0, help="wall-clock seconds")
    parser.add_argument("--screenshot", type=Path, default=None, help="PNG written at the end")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=800)
    parser.add_argument("--fast", action="store_true",
                        help="run the viewer as fast as it goes (hqp view --fast)")
    args = parser.parse_args(argv)
    result = measure(args.robot, args.seconds, args.screenshot, args.width, args.height,
                     args.fast)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
