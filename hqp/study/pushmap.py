"""The ``push-map`` study: the largest push survived per direction, by bisection.

For every controller and direction, a :class:`Bisection` on the push force: the largest
force first (``max_force``); while the bracket ``[survived, fell]`` is wider than
``tolerance``, its middle; and when nothing above ``min_force`` survived, ``min_force``
itself, so that the reported largest survived force is always one that a run survived and
the smallest fallen force one under which a run fell. Each direction is a chain of
simulations that depend on each other; the directions (and controllers) are independent and
run in parallel (:class:`PushMapPlan`).

Near a direction's threshold, whether a push is survived is not a function of the force: it
flips with rounding (another CPU, another import order) and with initial perturbations far
below any sensor's resolution (docs/results/push-recovery.md). ``repeats`` (``[push]``) makes
each probe ``repeats`` simulations, seeds ``0 .. repeats-1`` of a perturbation the study sets
(``init_q_std``, ``init_v_std`` or measurement noise): a force counts as survived only when
every repeat survived, as fallen when any repeat fell, so the bracket is that of a
conservative threshold, and the repeats of a probe run in parallel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from hqp.study.spec import Params, Study


@dataclass
class Bisection:
    """The bisection of one direction on the push force [N].

    Attributes:
        max_force: Upper end, tried first [N].
        tolerance: Width of the bracket at which the search stops [N].
        min_force: Lower end [N], tried last when nothing above it survived.
        survived: Largest force a run survived so far (``None``: none yet) [N].
        fell: Smallest force a run fell under so far (``None``: none yet) [N].
        failed: A simulation of the chain failed (error, timeout, crash): the search stops.

    """

    max_force: float
    tolerance: float
    min_force: float = 0.0
    survived: float | None = None
    fell: float | None = None
    failed: bool = False
    probes: list[float] = field(default_factory=list)

    def next_force(self) -> float | None:
        """Return the next force to try (``None``: the search is over)."""
        if self.failed:
            return None
        if self.fell is None:
            return self.max_force if self.survived is None else None
        if self.fell <= self.min_force:
            return None
        lo = self.min_force if self.survived is None else self.survived
        if self.fell - lo > self.tolerance:
            return 0.5 * (lo + self.fell)
        return self.min_force if self.survived is None else None

    def feed(self, force: float, fell: bool | None) -> None:
        """Record the outcome of a run at ``force`` (``fell=None``: the run failed)."""
        self.probes.append(force)
        if fell is None:
            self.failed = True
        elif fell:
            self.fell = force if self.fell is None else min(self.fell, force)
        else:
            self.survived = force if self.survived is None else max(self.survived, force)

    @property
    def done(self) -> bool:
        """Whether the search is over."""
        return self.next_force() is None

    def expected_probes(self) -> int:
        """Upper bound of the number of runs of a search [runs] (progress bars)."""
        return 2 + max(0, math.ceil(math.log2(max(self.max_force - self.min_force, 1e-9)
                                              / self.tolerance)))


def group_name(controller: str, angle: float) -> str:
    """Return the name of the chain of one controller and direction: ``hqp/90``."""
    return f"{controller}/{angle:g}"


@dataclass
class _Probe:
    """The outcome so far of one probe's repeats."""

    force: float
    left: int
    fell: bool = False
    failed: bool = False


class PushMapPlan:
    """The simulations of a ``push-map`` study, handed out as the bisections advance."""

    def __init__(self, study: Study) -> None:
        self.study = study
        self.chains: dict[str, tuple[str, float, Bisection]] = {}
        for controller in study.controllers:
            for angle in study.push.directions:
                search = Bisection(study.push.max_force, study.push.tolerance,
                                   study.push.min_force)
                self.chains[group_name(controller, angle)] = (controller, angle, search)
        self.pending: dict[str, _Probe] = {}
        self.records: dict[str, list[dict[str, Any]]] = {g: [] for g in self.chains}

    @property
    def repeats(self) -> int:
        """Simulations per probed force (the study's ``[push] repeats``)."""
        return self.study.push.repeats

    def params(self, group: str, force: float, repeat: int = 0) -> Params:
        """Return the params of one repeat of one probe of a chain.

        With ``repeats > 1`` each repeat sets its own ``seed`` (``repeat``); with one repeat
        the params are those of a study without repeats (their records are reused).
        """
        controller, angle, _ = self.chains[group]
        params = {**self.study.base_params(controller), "push_force": force,
                  "push_angle_deg": angle}
        if self.repeats > 1:
            params["seed"] = repeat
        return params

    def first_params(self) -> list[Params]:
        """Return the first probe of every chain (checked before anything runs)."""
        return [self.params(g, c[2].max_force, k) for g, c in self.chains.items()
                for k in range(self.repeats)]

    def ready(self) -> list[tuple[Params, dict[str, Any]]]:
        """Return the simulations that can start now, each with its record's annotations."""
        out = []
        for group, (_, _, search) in self.chains.items():
            force = search.next_force()
            if force is None or group in self.pending:
                continue
            self.pending[group] = _Probe(force, self.repeats)
            for k in range(self.repeats):
                out.append((self.params(group, force, k),
                            {"group": group, "probe": len(search.probes), "repeat": k}))
        return out

    def feed(self, record: dict[str, Any]) -> None:
        """Record one repeat of a chain's pending probe; the last one advances the chain."""
        group = record["group"]
        search = self.chains[group][2]
        probe = self.pending[group]
        if record["status"] != "ok":
            probe.failed = True
        elif record["metrics"].get("fell"):
            probe.fell = True
        probe.left -= 1
        self.records[group].append(record)
        if probe.left == 0:
            del self.pending[group]
            search.feed(probe.force, None if probe.failed else probe.fell)

    def expected(self) -> int:
        """Upper bound of the number of simulations (progress bar)."""
        return self.repeats * sum(search.expected_probes()
                                  for _, _, search in self.chains.values())

    def summary(self) -> dict[str, Any]:
        """Return the push map: one row per controller and direction."""
        duration = float(self.study.fixed.get("push_duration", 0.1))
        rows = []
        for group, (controller, angle, search) in self.chains.items():
            failures = [r for r in self.records[group] if r["status"] != "ok"]
            by_force: dict[float, str] = {}  # a record at each force, one that fell if any
            for r in self.records[group]:
                force = r["params"]["push_force"]
                if force not in by_force or r["metrics"].get("fell"):
                    by_force[force] = r["id"]
            rows.append({
                "controller": controller, "angle_deg": angle,
                "largest_survived_n": search.survived,
                "largest_survived_impulse_ns": (None if search.survived is None
                                                else round(search.survived * duration, 6)),
                "smallest_fallen_n": search.fell,
                "survived_id": by_force.get(search.survived),
                "fallen_id": by_force.get(search.fell),
                "probes": len(search.probes),
                "repeats": self.repeats,
                "status": "failed" if search.failed else "done" if search.done else "open",
                "errors": [f"{r['status']}: {r['error']}" for r in failures],
            })
        return {"push_duration_s": duration, "directions": rows}
