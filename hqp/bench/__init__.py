"""Benchmarks: the shared measuring method and a registry of suites.

A suite is a function ``suite(*, quick: bool, progress: Callable[[str], None])
-> list[dict]`` returning one row per configuration (at least ``robot``,
``solver``, ``levels``, ``n``, ``median_ms``, ``p95_ms``; docs/reference/contracts.md,
the JSON sections). Suites are listed in :data:`SUITE_MODULES`
(imported lazily, so a suite's heavy dependencies load only when it runs) or
registered with :func:`register_suite`.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable, Sequence

from hqp.bench.method import Timing, measure
from hqp.errors import InvalidInput, UnknownName

Row = dict
Suite = Callable[..., list[Row]]

_SUITES: dict[str, Suite] = {}

SUITE_MODULES: dict[str, tuple[str, str]] = {
    "solver": ("hqp.bench.solver_suite", "solver_suite"),
    "controller": ("hqp.bench.suite_controller", "run"),
    "recorded": ("hqp.bench.suite_recorded", "run"),
    "all": ("hqp.bench.suite_all", "run"),
}
"""Suite name -> (module, function), imported on first use. Each function
accepts the keywords ``quick`` and ``progress`` and returns the rows."""


def register_suite(name: str) -> Callable[[Suite], Suite]:
    """Register ``fn`` as the suite called ``name`` (decorator)."""

    def deco(fn: Suite) -> Suite:
        _SUITES[name] = fn
        return fn

    return deco


def suite_names() -> list[str]:
    """Names of the known suites."""
    return sorted(set(_SUITES) | set(SUITE_MODULES))


def get_suite(name: str) -> Suite:
    """Return the suite called ``name``, importing its module if needed.

    Raises:
        UnknownName: No such suite.

    """
    if name not in _SUITES and name in SUITE_MODULES:
        module, function = SUITE_MODULES[name]
        _SUITES[name] = getattr(importlib.import_module(module), function)
    if name not in _SUITES:
        raise UnknownName("suite", name, suite_names())
    return _SUITES[name]


def run_suite(
    name: str, quick: bool = False, progress: Callable[[str], None] | None = None,
    robots: Sequence[str] | None = None,
) -> dict:
    """Run a suite; return ``{"suite": name, "rows": [...], "skipped": [...]}``.

    ``rows`` holds the configurations measured in the run (the contract: one row per measured
    configuration, each with its times); a configuration the suite could not measure on this
    machine (TSID without its environment) is listed in ``skipped`` with the reason instead.
    ``robots`` (bundled names or robot TOML files) replaces the suite's robots.

    Raises:
        InvalidInput: ``robots`` given to a suite that runs on no robot.

    """
    suite = get_suite(name)
    if robots:
        if "robots" not in inspect.signature(suite).parameters:
            raise InvalidInput(f"hqp bench: suite {name!r} runs on no robot; --robot applies "
                               "to the controller suite")
        rows = suite(quick=quick, progress=progress or (lambda _msg: None), robots=robots)
    else:
        rows = suite(quick=quick, progress=progress or (lambda _msg: None))
    return {"suite": name, "rows": [r for r in rows if "skipped" not in r],
            "skipped": [r for r in rows if "skipped" in r]}


__all__ = ["Timing", "get_suite", "measure", "register_suite", "run_suite", "suite_names"]
