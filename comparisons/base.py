"""What every paper scenario shares: its runs, its result, its report.

A scenario (one module of :mod:`comparisons`) builds the robot, the task sets
of each hierarchy it compares, and the events of the experiment; runs every
requested controller in MuJoCo through :mod:`hqp.sim`; and turns each run's
:class:`~comparisons.metrics.Trace` into the metrics of the command-line
contract and into the panels of a figure drawn like the hierarchy paper's
Figures 4 and 5.
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from comparisons.metrics import Trace, run_metrics
from hqp.bench.worker import PeerUnavailable
from hqp.control.presets import CONTROLLER_NAMES
from hqp.errors import InvalidInput, UnknownName
from hqp.plots import Panel
from hqp.sim.simulator import CONTACT_MODES

CONTROLLERS: tuple[str, ...] = (*CONTROLLER_NAMES, "placo")
"""Every controller a scenario may run: hqp's registry (:data:`hqp.control.presets.CONTROLLERS`)
and ``placo`` (PlaCo's ``DynamicsSolver``)."""

Progress = Callable[[str], None]
"""A callback that receives progress messages (the CLI prints them on stderr)."""


def _quiet(message: str) -> None:
    """Default progress callback: say nothing."""


@dataclass(frozen=True)
class RunSpec:
    """One run of a scenario: a controller on a hierarchy of tasks.

    Attributes:
        controller: ``"hqp"``, ``"nullspace"`` or ``"placo"``.
        hierarchy: Name of the task hierarchy (``"shared"``, ``"cog-first"``, ...).

    """

    controller: str
    hierarchy: str


@dataclass
class RunResult:
    """What one run produced.

    Attributes:
        spec: The controller and hierarchy.
        metrics: Metrics of :func:`comparisons.metrics.run_metrics` plus the
            scenario's own (JSON-ready scalars).
        trace: The recorded run.
        panels: Panels of its figure.
        note: What the controller could not express of the hierarchy ("" if nothing).

    """

    spec: RunSpec
    metrics: dict[str, Any]
    trace: Trace
    panels: list[Panel]
    note: str = ""

    def row(self) -> dict[str, Any]:
        """Return the run's JSON object: controller, hierarchy, metrics (and note)."""
        row: dict[str, Any] = {"controller": self.spec.controller, "hierarchy": self.spec.hierarchy}
        row.update(self.metrics)
        if self.note:
            row["note"] = self.note
        return row


@dataclass
class ScenarioResult:
    """All runs of one scenario on one robot.

    Attributes:
        scenario: The scenario's name.
        robot: The robot's name.
        runs: The runs made.
        skipped: Controllers requested but not run on this machine (a peer without its
            environment): ``{"controller", "hierarchies", "skipped"}``, the last saying why
            and how to add it.

    """

    scenario: str
    robot: str
    runs: list[RunResult] = field(default_factory=list)
    skipped: list[dict[str, Any]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """Return the contract's object ``{"scenario", "robot", "runs": [...]}``.

        A controller that was not run is not a run: it is listed under ``"skipped"``, a key
        present only when something was skipped.
        """
        out: dict[str, Any] = {
            "scenario": self.scenario,
            "robot": self.robot,
            "runs": [r.row() for r in self.runs],
        }
        if self.skipped:
            out["skipped"] = [dict(s) for s in self.skipped]
        return out


class Scenario(abc.ABC):
    """A paper experiment that every controller runs on several hierarchies.

    Class attributes name the scenario, the figure it reproduces, the robots
    it supports, its hierarchies and its full duration.
    """

    name: str = ""
    """Registry name (``hqp compare NAME``)."""
    title: str = ""
    """One-line description."""
    paper: str = ""
    """Which figure or table of which seed paper it reproduces."""
    robots: tuple[str, ...] = ("paper-humanoid",)
    """Robots it supports, the first being the default."""
    hierarchies: tuple[str, ...] = ("default",)
    """Names of the task hierarchies it compares."""
    duration: float = 3.0
    """Full duration of a run [s] (the README's figures)."""
    controllers: tuple[str, ...] = CONTROLLERS
    """Controllers it can run."""
    contacts: str = CONTACT_MODES[0]
    """How the feet touch the floor in the runs: ``"unilateral"`` or ``"welded"`` (set by
    :meth:`run`; the scenarios hand it to :func:`comparisons.common.run_controller`)."""

    @property
    def default_robot(self) -> str:
        """The robot used when none is given."""
        return self.robots[0]

    def check_robot(self, robot: str | None) -> str:
        """Return the robot name to use.

        Raises:
            UnknownName: A robot the scenario does not support (lists those it does).

        """
        if robot is None:
            return self.default_robot
        if robot not in self.robots:
            raise UnknownName("robot", robot, self.robots)
        return robot

    def specs(self, controllers: Sequence[str] | None = None) -> list[RunSpec]:
        """Return the runs for the given controllers (default: all), every hierarchy each.

        Raises:
            UnknownName: A controller the scenario cannot run (lists those it can).

        """
        chosen = list(self.controllers if controllers is None else controllers)
        for c in chosen:
            if c not in self.controllers:
                raise UnknownName("controller", c, self.controllers)
        return [RunSpec(c, h) for c in chosen for h in self.hierarchies]

    @abc.abstractmethod
    def simulate(self, robot: str, spec: RunSpec, duration: float, progress: Progress) -> RunResult:
        """Run one controller on one hierarchy in MuJoCo and compute its metrics."""

    def run(
        self,
        *,
        robot: str | None = None,
        controllers: Sequence[str] | None = None,
        duration: float | None = None,
        progress: Progress = _quiet,
        contacts: str = CONTACT_MODES[0],
        unavailable: Mapping[str, str] | None = None,
    ) -> ScenarioResult:
        """Run every requested controller on every hierarchy.

        A peer whose environment is missing (``placo``: :class:`hqp.bench.worker.PeerUnavailable`)
        is not run: the result lists it under ``skipped`` with the reason.

        Args:
            robot: Robot name (default: the scenario's first).
            controllers: Controllers to run (default: every one the scenario supports).
            duration: Simulated duration of each run [s] (default: the full one).
            progress: Receives one message per run (and the simulator's progress).
            contacts: ``"unilateral"`` (MuJoCo's floor contacts, the default) or ``"welded"``
                (the papers' rigid feet: weld equalities hold the soles).
            unavailable: Controllers known not to run here, with why (skipped, not tried).

        Raises:
            UnknownName: Unknown robot, controller or contact mode (lists the valid ones).
            InvalidInput: Non-positive duration.

        """
        robot = self.check_robot(robot)
        specs = self.specs(controllers)
        if contacts not in CONTACT_MODES:
            raise UnknownName("contact mode", contacts, CONTACT_MODES)
        self.contacts = contacts
        duration = self.duration if duration is None else float(duration)
        if not duration > 0.0:
            raise InvalidInput(f"scenario {self.name!r}: duration must be positive, got {duration}")
        result = ScenarioResult(self.name, robot)
        skipped = dict(unavailable or {})
        for k, spec in enumerate(specs):
            if spec.controller not in skipped:
                progress(
                    f"[{self.name}] run {k + 1}/{len(specs)}: controller {spec.controller}, "
                    f"hierarchy {spec.hierarchy}, {duration:g} s on {robot}, {contacts} contacts"
                )
                try:
                    res = self.simulate(robot, spec, duration, progress)
                except PeerUnavailable as exc:
                    skipped[spec.controller] = str(exc)
            if spec.controller in skipped:
                _skip(result, spec, skipped[spec.controller], progress)
                continue
            res.trace.contacts = contacts
            res.metrics = {**run_metrics(res.trace), **res.metrics}
            result.runs.append(res)
        return result


def _skip(result: ScenarioResult, spec: RunSpec, reason: str, progress: Progress) -> None:
    """List a run that was not made under its controller's ``skipped`` entry."""
    entry = next((e for e in result.skipped if e["controller"] == spec.controller), None)
    if entry is None:
        progress(f"[{result.scenario}] {spec.controller} skipped: {reason}")
        entry = {"controller": spec.controller, "hierarchies": [], "skipped": reason}
        result.skipped.append(entry)
    entry["hierarchies"].append(spec.hierarchy)
