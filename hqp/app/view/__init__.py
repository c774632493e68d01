"""``hqp view [BEHAVIOR]``: the seeds' interactive interface, in a web browser.

A behavior runs in closed loop with MuJoCo (:class:`~hqp.app.view.session.ViewSession`, on
its own thread, paced to the wall clock) and a viser page on localhost
(:class:`~hqp.app.view.page.ViewerPage`) shows the robot, the goals of the active tasks as
handles to drag, the task panel with each task's feasibility, buttons for the library
behaviors, pause, single step, reset and push, and strip charts. Ctrl-C (or SIGTERM) stops
the server and the loop; ``--record DIR`` then writes what was done in the page as the run
JSON (``DIR/run.json``), the goals as replayable inputs files, and ``DIR/view.mp4`` where
offscreen rendering is available. Needs the optional extra ``view``
(``pip install -e ".[view]"``).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import webbrowser
from typing import Any

from hqp.app.view.page import ViewerPage, check_port, require_viser
from hqp.app.view.session import ViewSession
from hqp.behaviors.loader import library_names
from hqp.control.presets import CONTROLLER_NAMES
from hqp.errors import UnknownName


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``hqp view [BEHAVIOR] [--robot] [--controller] [--port] [--no-browser] ...``."""
    p = subparsers.add_parser(
        "view", help="interactive viewer in a web browser (needs the view extra)",
        description="Serve a page on localhost that shows a behavior simulated in MuJoCo in "
                    "real time: drag the goals, watch the task panel, pick behaviors, pause, "
                    "step, reset, push. Ctrl-C stops it.")
    p.add_argument("behavior", nargs="?", default="stand",
                   help="library behavior to start with (default: stand)")
    p.add_argument("--robot", default=None,
                   help="robot name or robot TOML file (default: the behavior's)")
    p.add_argument("--controller", default="hqp", choices=CONTROLLER_NAMES)
    p.add_argument("--host", default="127.0.0.1", help="interface to serve on")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    p.add_argument("--fast", action="store_true",
                   help="step as fast as possible instead of pacing to the wall clock")
    p.add_argument("--record", default=None, metavar="DIR",
                   help="on exit write DIR/run.json (what was done in the page), the goals as "
                        "inputs files, and DIR/view.mp4 where offscreen rendering works")
    p.set_defaults(func=command)
    return p


def command(args: argparse.Namespace) -> int:
    """Run ``hqp view`` until Ctrl-C; return 0."""
    require_viser()
    names = library_names()
    if args.behavior not in names:
        raise UnknownName("behavior", args.behavior, names)
    check_port(args.host, args.port)
    session = ViewSession(args.behavior, robot=args.robot, controller=args.controller,
                          realtime=not args.fast, record_dir=args.record,
                          video=args.record is not None)
    page = ViewerPage(session, host=args.host, port=args.port)
    done = threading.Event()
    # Ctrl-C and SIGTERM end the wait below (SIGINT too where the shell started us ignoring it)
    previous = {sig: signal.signal(sig, lambda *_: done.set())
                for sig in (signal.SIGINT, signal.SIGTERM)}
    session.start()
    page.serve()
    print(f"hqp view: {page.url} ({args.behavior} on {session.robot.name}, "
          f"{args.controller}); Ctrl-C stops", file=sys.stderr, flush=True)
    if not args.no_browser:
        webbrowser.open(page.url)
    try:
        while not done.wait(0.2):
            if session.error is not None:
                print(f"hqp view: the simulation stopped: {session.error}", file=sys.stderr)
                break
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        page.stop()
        session.page_figures = page.figures()
        session.stop()
        written = session.write_record()
        session.close()
    if written is not None:
        print(f"hqp view: wrote {written}", file=sys.stderr)
    print("hqp view: stopped", file=sys.stderr, flush=True)
    return 0 if session.error is None else 1
