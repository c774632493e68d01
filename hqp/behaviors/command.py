"""The ``hqp run`` and ``hqp behaviors`` subcommands (wired into :mod:`hqp.cli`)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from hqp.console import stdout_to_stderr


def add_run_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``hqp run`` to the CLI's subparsers.

    ``hqp run BEHAVIOR [--robot] [--controller] [--backend] [--duration] [--inputs] [--set]
    [--json] [--video] [--plot]``.
    """
    p = subparsers.add_parser(
        "run", help="run a behavior (library name or .toml file) in MuJoCo",
        description="Run a behavior in closed loop with MuJoCo and report what happened: "
                    "phases visited, fall, footsteps, feasibility events.")
    p.add_argument("behavior", help="library name (see `hqp behaviors`) or a .toml file")
    p.add_argument("--robot", default=None, help="robot (default: the behavior's)")
    p.add_argument("--controller", default="hqp", choices=("hqp", "nullspace"))
    p.add_argument("--backend", default=None,
                   help="QP backend of the HQP controller: proxsuite, daqp, quadprog, osqp "
                        "(default: the behavior's, else proxsuite)")
    p.add_argument("--duration", type=float, default=None,
                   help="simulated time [s] (default: the behavior's)")
    p.add_argument("--inputs", default=None,
                   help="runtime inputs, JSON Lines of {\"t\": ..., \"<input>\": ...}")
    p.add_argument("--set", action="append", default=[], metavar="INPUT=JSON",
                   help="replace an input's default, e.g. --set takeoff_height=1.2")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--video", default=None, help="write an MP4 of the run")
    p.add_argument("--plot", default=None,
                   help="write a PNG of the run (CoG height and velocity, feet heights, "
                        "normal forces, torque ratio; phase changes as vertical lines)")
    p.set_defaults(func=run_command)
    return p


def add_behaviors_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``hqp behaviors [--json]`` (list the behavior library)."""
    p = subparsers.add_parser("behaviors", help="list the behavior library",
                              description="List the bundled behaviors and their phases.")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=behaviors_command)
    return p


def run_command(args: argparse.Namespace) -> int:
    """Run ``hqp run``; print JSON (``--json``) or a short summary. Returns 0, or 1 on a fall."""
    from hqp.behaviors.runner import run_behavior

    overrides: dict[str, Any] = {}
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep:
            print(f"hqp run: --set expects INPUT=JSON, got {item!r}", file=sys.stderr)
            return 2
        try:
            overrides[key] = json.loads(value)
        except json.JSONDecodeError as exc:
            print(f"hqp run: --set {key}: not JSON ({exc})", file=sys.stderr)
            return 2

    def progress(t: float, total: float) -> None:
        if int(round(t * 10)) % 10 == 0:
            print(f"\r{args.behavior}: t = {t:5.1f} / {total:.1f} s", end="", file=sys.stderr,
                  flush=True)

    # C libraries (PlaCo) print to stdout: keep stdout for the one JSON object
    with stdout_to_stderr() as out:
        result = run_behavior(args.behavior, robot=args.robot, controller=args.controller,
                              duration=args.duration, inputs=args.inputs, overrides=overrides,
                              video=args.video, progress=progress, backend=args.backend,
                              plot=args.plot)
        print(file=sys.stderr)
        data = result.as_json()
        if args.json:
            out.write(json.dumps(data) + "\n")
    if not args.json:
        outcome = f"FELL ({data['fall_reason']})" if data["fell"] else "did not fall"
        print(f"behavior {data['behavior']} on {data['robot']} ({data['controller']}), "
              f"{data['duration_s']:.2f} s: {outcome}")
        print(f"  phases: {' -> '.join(data['phases'])}")
        print(f"  footsteps: {data['steps']}, longest flight: {data['flight_time_s']:.3f} s, "
              f"max |tau|/tau_max: {data['max_torque_ratio']:.2f}, largest torque change in "
              f"one step: {data['max_torque_jump_nm']:.1f} N m")
        if "mean_speed_m_s" in data:
            print(f"  mean speed {data['mean_speed_m_s']:.3f} m/s, CoM tracking error max "
                  f"{1e3 * data['com_tracking_error_max_m']:.1f} mm")
        print(f"  feasibility events: {len(data['feasibility_events'])}")
    return 1 if data["fell"] else 0


def behaviors_command(args: argparse.Namespace) -> int:
    """List the library (``hqp behaviors``)."""
    from hqp.behaviors.loader import library_names, load_behavior

    rows = []
    for name in library_names():
        spec = load_behavior(name)
        rows.append({"name": name, "description": spec.description, "phases": list(spec.phases),
                     "inputs": list(spec.inputs), "file": str(spec.path)})
    if args.json:
        print(json.dumps({"behaviors": rows}))
    else:
        width = max(len(r["name"]) for r in rows)
        for r in rows:
            print(f"{r['name']:<{width}}  {r['description']}")
            print(f"{'':<{width}}  phases: {', '.join(r['phases'])}"
                  + (f"; inputs: {', '.join(r['inputs'])}" if r["inputs"] else ""))
    return 0
