"""Record the level matrices of real control steps (``python -m hqp.app.record``).

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

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hqp.behaviors.setup import prepare
from hqp.bench.recorded import RecordedStep, capture, save
from hqp.sim.loop import Push, closed_loop
from hqp.sim.simulator import Simulator
from hqp.solver import HierarchicalSolver

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
        kind: ``"scenario"`` (:mod:`comparisons`, run by :mod:`hqp.app.record`) or
            ``"behavior"`` (:mod:`hqp.behaviors`).

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


Runner = Callable[[Source, str, Callable[[Any, float], None]], str]
"""Runs one source on one robot, calling ``on_step(controller, t)`` after each control step;
returns a note ("" or why the run ended early)."""


def _pushes(source: Source, mass: float) -> list[Push]:
    """Return the source's pushes, scaled to the robot's mass (the forces are for 70 kg)."""
    return [Push(t0, tuple(np.asarray(force, dtype=float) * mass / 70.0), d)  # type: ignore[arg-type]
            for t0, force, d in source.pushes]


def run_behavior_source(source: Source, robot: str,
                        on_step: Callable[[Any, float], None]) -> str:
    """Run a behavior source (:data:`Runner`) in :func:`hqp.sim.closed_loop`."""
    behavior, ctrl, rob = prepare(source.name, robot=robot, controller="hqp")
    ctrl.solver = HierarchicalSolver(BACKEND, "basis")
    sim = Simulator(rob)
    ctrl.dt = sim.dt
    mass = float(sum(i.mass for i in ctrl.model.model.inertias))
    behavior.start(sim.state(), 0.0)
    outcome = closed_loop(sim, behavior, source.duration, _pushes(source, mass),
                          before_step=lambda step: on_step(ctrl, step.t), clock="steps")
    return "" if outcome.fell_at is None else f"fell at t = {outcome.fell_at:.3f} s"


def record_source(source: Source, robot: str, out: Path,
                  runners: dict[str, Runner] | None = None) -> tuple[Path | None, str]:
    """Run one source on one robot and write its captured steps.

    Args:
        source: The source.
        robot: The robot.
        out: Output directory.
        runners: Runner by source kind (default: behaviors only; the scenario runner lives
            in :mod:`hqp.app.record`, the layer that may import :mod:`comparisons`).

    Returns:
        ``(path or None, note)``; no file when nothing was captured.

    """
    steps: list[RecordedStep] = []
    pending = list(source.captures)

    def on_step(ctrl: Any, t: float) -> None:
        if pending and t >= pending[0] - 1e-9:
            pending.pop(0)
            steps.append(capture(ctrl, source.name, robot, t))

    run = (runners or {"behavior": run_behavior_source}).get(source.kind)
    if run is None:
        return None, f"no runner for a {source.kind} source"
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
