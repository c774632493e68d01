"""Re-record the benchmark's control problems (``python -m hqp.app.record``).

The sources and the capture are :mod:`hqp.bench.record`'s; the scenario source
(``hand-reach``, a paper scenario of :mod:`comparisons`) is run here, the layer that may
import the experiments package.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import comparisons
from comparisons.base import RunSpec
from comparisons.common import make_controller
from hqp.app.console import output_path_problem
from hqp.bench.record import BACKEND, SOURCES, Runner, Source, record_source, run_behavior_source
from hqp.bench.recorded import DATA_DIR
from hqp.sim.loop import Push
from hqp.sim.run import simulate
from hqp.solver import HierarchicalSolver


def run_scenario_source(source: Source, robot: str,
                        on_step: Callable[[Any, float], None]) -> str:
    """Run a scenario source (:data:`hqp.bench.record.Runner`), hierarchy ``cog-first``."""
    scenario = comparisons.get_scenario(source.name)
    spec = RunSpec(controller="hqp", hierarchy="cog-first")
    rob, model, hierarchy, _ = scenario.build(robot, spec)
    ctrl = make_controller("hqp", rob, model, hierarchy)
    ctrl.solver = HierarchicalSolver(BACKEND, "basis")
    pushes = [Push(t0, f, d) for t0, f, d in source.pushes]
    log = simulate(rob, ctrl, source.duration, pushes,
                   on_step=lambda sim, cmd: on_step(ctrl, cmd.t))
    return "" if log.fell_at is None else f"fell at t = {log.fell_at:.3f} s"


RUNNERS: dict[str, Runner] = {"behavior": run_behavior_source, "scenario": run_scenario_source}
"""Runner by source kind."""


def main(argv: list[str] | None = None) -> int:
    """Record every source (or those named) on every robot (or those named)."""
    parser = argparse.ArgumentParser(prog="python -m hqp.app.record", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--source", action="append", choices=[s.name for s in SOURCES],
                        help="record this source only (repeatable)")
    parser.add_argument("--robot", action="append", help="this robot only (repeatable)")
    parser.add_argument("--out", type=Path, default=DATA_DIR, help="output directory")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    robots = sorted({r for s in SOURCES for r in s.robots})
    unknown = sorted(set(args.robot or ()) - set(robots))
    why = output_path_problem(args.out / "probe.npz")
    if unknown or why:  # before any run
        message = (f"unknown robot {unknown[0]!r}; robots of the sources: {', '.join(robots)}"
                   if unknown else f"--out {str(args.out)!r}: {why}")
        print(f"python -m hqp.app.record: error: {message}", file=sys.stderr)
        return 2
    for source in SOURCES:
        if args.source and source.name not in args.source:
            continue
        for robot in source.robots:
            if args.robot and robot not in args.robot:
                continue
            t0 = time.perf_counter()
            path, note = record_source(source, robot, args.out, RUNNERS)
            size = f"{path.stat().st_size / 1024:.0f} kB" if path else "-"
            print(f"{source.name:>10} {robot:>15}: {path.name if path else 'skipped':<28} "
                  f"{size:>7} {time.perf_counter() - t0:6.1f} s {note}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
