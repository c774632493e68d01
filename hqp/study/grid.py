"""The ``grid`` study: every combination of the swept parameters, for every controller.

All simulations are independent: :class:`GridPlan` hands them out at once. The summary
holds one row per simulation (its swept values, its status and its metrics).
"""

from __future__ import annotations

import itertools
from typing import Any

from hqp.study.spec import Params, Study, simulation_id


class GridPlan:
    """The simulations of a ``grid`` study (the Cartesian product of ``study.grid``)."""

    def __init__(self, study: Study) -> None:
        self.study = study
        names = list(study.grid)
        self.simulations: list[tuple[Params, dict[str, Any]]] = []
        for controller in study.controllers:
            for values in itertools.product(*(study.grid[n] for n in names)):
                swept = dict(zip(names, values))
                self.simulations.append(({**study.base_params(controller), **swept},
                                         {"group": controller, "swept": swept}))
        self.handed = False
        self.records: list[dict[str, Any]] = []

    def first_params(self) -> list[Params]:
        """Return every simulation's params (checked before anything runs)."""
        return [p for p, _ in self.simulations]

    def ready(self) -> list[tuple[Params, dict[str, Any]]]:
        """Return every simulation, once."""
        if self.handed:
            return []
        self.handed = True
        return list(self.simulations)

    def feed(self, record: dict[str, Any]) -> None:
        """Keep a finished simulation's record."""
        self.records.append(record)

    def expected(self) -> int:
        """Return the number of simulations."""
        return len(self.simulations)

    def summary(self) -> dict[str, Any]:
        """Return one row per simulation, in the grid's order."""
        by_id = {r["id"]: r for r in self.records}
        rows = []
        for params, notes in self.simulations:
            record = by_id.get(simulation_id(params))
            rows.append({"controller": params["controller"], **notes["swept"],
                         "id": None if record is None else record["id"],
                         "status": "missing" if record is None else record["status"],
                         **({} if record is None else record["metrics"])})
        return {"parameters": list(self.study.grid), "rows": rows}
