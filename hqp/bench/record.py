"""Record the level matrices of real control steps (``python -m hqp.bench.record``).

Each *source* runs one closed loop in MuJoCo with the HQP controller
(:class:`~hqp.controller.WholeBodyController`, basis algorithm on :data:`BACKEND`) and
captures, at evenly spaced times, what the controller handed to its solver
(:func:`hqp.bench.recorded.capture`). Sources:

- ``hand-reach`` on ``paper-humanoid``: the hierarchy paper's experiment
  (:mod:`comparisons.hand_reach`, hierarchy ``cog-first``), joint limits reached;
- ``reach``, ``screwgun``, ``stand``, ``walk`` behaviors from the behavior library
  (:mod:`hqp.behaviors`) on ``paper-humanoid``, ``g1`` and ``talos``; ``stand`` with two
  horizontal pushes on the pelvis (the steps are taken during and after them).

A source that fails on a robot (behavior not available for it, fall before the first capture)
is reported and skipped. The files go to :data:`hqp.bench.recorded.DATA_DIR` (or ``--out``),
one per source and robot, a few hundred kB each.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hqp.bench.recorded import DATA_DIR, RecordedStep, capture, save

logger = logging.getLogger(__name__)

BACKEND = "daqp"
"""Backend of the recorded controllers (the recorded matrices do not depend on it beyond the
solver's round-off along the trajectory; DAQP is the fastest here)."""


@dataclass(frozen=True)
class Source:
    """One recorded closed loop.

    Attributes:
        name: Source name (file stem prefix).
        robots: Robots it runs on.
        duration: Simulated duration [s].
        captures: Times of the captured steps [s].
        pushes: ``(t [s], force (3,) [N], duration [s])`` on the pelvis.
        kind: ``"scenario"`` (:mod:`comparisons`) or ``"behavior"`` (:mod:`hqp.behaviors`).

    """

    name: str
    robots: tuple[str, ...]
    duration: float
    captures: tuple[float, ...]
    pushes: tuple[tuple[float, tuple[float, float, float], float], ...] = ()
    kind: str = "behavior"


def _even(start: float, stop: float, count: int) -> tuple[float, ...]:
    return tuple(round(float(t), 3) for t in np.linspace(start, stop, count))


SOURCES: tuple[Source, ...] = (
    Source("hand-reach", ("paper-humanoid",), 2.0, _even(0.1, 2.0, 6), kind="scenario"),
    Source("reach", ("paper-humanoid", "g1", "talos"), 2.0, _even(0.1, 2.0, 5)),
    Source("screwgun", ("paper-humanoid", "g1", "talos"), 2.0, _even(0.1, 2.0, 5)),
    Source("stand", ("paper-humanoid", "g1", "talos"), 1.6,
           (0.1, 0.35, 0.45, 0.7, 1.05, 1.15, 1.5),
           pushes=((0.3, (40.0, 0.0, 0.0), 0.15), (1.0, (0.0, 30.0, 0.0), 0.15))),
    Source("walk", ("paper-humanoid", "g1", "talos"), 3.0, _even(0.2, 3.0, 6)),
)
"""The recorded sources (the steps are replayed by ``hqp bench --suite recorded``)."""


def _push_force(source: Source, t: float, mass: float) -> np.ndarray | None:
    f = np.zeros(3)
    for t0, force, d in source.pushes:
        if t0 <= t < t0 + d:
            f += np.asarray(force, dtype=float) * mass / 70.0  # scaled to the robot's mass
    return f if np.any(f) else None


def _run_behavior(source: Source, robot: str, on_step: Callable[[Any, float], None]) -> str:
    from hqp.behaviors.runner import prepare
    from hqp.sim.simulator import FALL_HEIGHT_RATIO, Simulator
    from hqp.solver import HierarchicalSolver

    behavior, ctrl, rob = prepare(source.name, robot=robot, controller="hqp")
    ctrl.solver = HierarchicalSolver(BACKEND, "basis")
    sim = Simulator(rob)
    ctrl.dt = sim.dt
    mass = float(sum(i.mass for i in ctrl.model.model.inertias))
    state = sim.state()
    behavior.start(state, 0.0)
    n = int(round(source.duration / sim.dt))
    for k in range(n):
        t = k * sim.dt
        cmd = ctrl.step(state, t)
        behavior.update(state, t, cmd.report)
        on_step(ctrl, t)
        sim.step(cmd.tau, _push_force(source, t, mass))
        state = sim.state()
        if sim.base_height() < FALL_HEIGHT_RATIO * rob.standing_height:
            return f"fell at t = {t:.3f} s"
    return ""


def _run_scenario(source: Source, robot: str, on_step: Callable[[Any, float], None]) -> str:
    import importlib

    from comparisons.base import RunSpec
    from comparisons.common import make_controller
    from hqp.sim.run import Push, simulate

    # the scenario's own module (the registry imports every scenario)
    module = importlib.import_module("comparisons." + source.name.replace("-", "_"))
    cls = next(c for c in vars(module).values()
               if isinstance(c, type) and getattr(c, "name", None) == source.name)
    scenario = cls()
    spec = RunSpec(controller="hqp", hierarchy="cog-first")
    rob, model, hierarchy, _ = scenario.build(robot, spec)
    ctrl = make_controller("hqp", rob, model, hierarchy)
    from hqp.solver import HierarchicalSolver

    ctrl.solver = HierarchicalSolver(BACKEND, "basis")
    pushes = [Push(t0, f, d) for t0, f, d in source.pushes]
    log = simulate(rob, ctrl, source.duration, pushes,
                   on_step=lambda sim, cmd: on_step(ctrl, cmd.t))
    return "" if log.fell_at is None else f"fell at t = {log.fell_at:.3f} s"


def record_source(source: Source, robot: str, out: Path) -> tuple[Path | None, str]:
    """Run one source on one robot and write its captured steps.

    Returns:
        ``(path or None, note)``; no file when nothing was captured.

    """
    steps: list[RecordedStep] = []
    pending = list(source.captures)

    def on_step(ctrl: Any, t: float) -> None:
        if pending and t >= pending[0] - 1e-9:
            pending.pop(0)
            steps.append(capture(ctrl, source.name, robot, t))

    run = _run_scenario if source.kind == "scenario" else _run_behavior
    try:
        note = run(source, robot, on_step)
    except Exception as exc:  # noqa: BLE001 - a source that cannot run is reported, not fatal
        logger.exception("%s on %s failed", source.name, robot)
        note = f"failed: {type(exc).__name__}: {exc}"
    if not steps:
        return None, note or "nothing captured"
    path = save(out / f"{source.name}_{robot}.npz", steps, duration=source.duration,
                pushes=[list(map(float, (p[0], *p[1], p[2]))) for p in source.pushes],
                note=note)
    return path, note


def main(argv: list[str] | None = None) -> int:
    """Record every source (or those named) on every robot (or those named)."""
    parser = argparse.ArgumentParser(prog="python -m hqp.bench.record", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--source", action="append", choices=[s.name for s in SOURCES],
                        help="record this source only (repeatable)")
    parser.add_argument("--robot", action="append", help="this robot only (repeatable)")
    parser.add_argument("--out", type=Path, default=DATA_DIR, help="output directory")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    for source in SOURCES:
        if args.source and source.name not in args.source:
            continue
        for robot in source.robots:
            if args.robot and robot not in args.robot:
                continue
            t0 = time.perf_counter()
            path, note = record_source(source, robot, args.out)
            size = f"{path.stat().st_size / 1024:.0f} kB" if path else "-"
            print(f"{source.name:>10} {robot:>15}: {path.name if path else 'skipped':<28} "
                  f"{size:>7} {time.perf_counter() - t0:6.1f} s {note}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
