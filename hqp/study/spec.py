"""A study's definition: what is simulated, over which parameters, and what is measured.

A study is a set of simulations, each given by a flat dictionary of parameters (its
*params*: target, robot, controller, duration, push, noise, gains, ...). The params alone
decide the simulation (noise and initial perturbations are seeded), so a simulation's
:func:`simulation_id` names its result: a resumed study reuses every finished result whose
params it asks for again.

Two kinds of study (:data:`KINDS`):

- ``push-map``: per controller and push direction, the largest push survived, found by
  bisection on the force (:mod:`hqp.study.pushmap`); the directions run in parallel.
- ``grid``: the Cartesian product of the swept parameters, per controller
  (:mod:`hqp.study.grid`).

A study is read from a TOML file (:func:`load_study`) or built from flags; both go through
:func:`study_from_dict`, which checks everything before any simulation starts.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import tomllib

from comparisons import CONTROLLERS
from hqp.errors import InvalidInput, UnknownName

KINDS = ("push-map", "grid")
"""The built-in studies."""

PERTURBATIONS = ("init_q_std", "init_v_std", "noise_q_std", "noise_v_std")
"""The seeded perturbations of a standing simulation (:mod:`hqp.study.simulation`): what
makes the repeats of a push map's probe differ."""

Params = dict[str, Any]
"""The parameters of one simulation (JSON scalars)."""


@dataclass(frozen=True)
class PushSearch:
    """The bisection of a push map, the same for every direction.

    Attributes:
        directions: Push directions [deg] (0: forward +x, 90: left +y).
        max_force: Upper end of the search [N] (tried first).
        tolerance: The search stops when the bracket is this narrow [N].
        min_force: Lower end [N] (tried last when nothing above it survived).
        repeats: Simulations per probed force, seeds ``0 .. repeats-1`` of the study's
            perturbation; a force is survived when every repeat survived
            (:mod:`hqp.study.pushmap`).

    """

    directions: tuple[float, ...] = tuple(22.5 * k for k in range(16))
    max_force: float = 800.0
    tolerance: float = 10.0
    min_force: float = 0.0
    repeats: int = 1


@dataclass(frozen=True)
class Study:
    """A study (see the module docstring).

    Attributes:
        kind: One of :data:`KINDS`.
        name: Name of the study (records, default results file).
        controllers: Controllers compared (names of the controller registry; ``placo`` too
            for a scenario).
        fixed: Parameters shared by every simulation (target, robot, duration, push timing,
            noise, gains, backend, ...): see :mod:`hqp.study.simulation`.
        grid: Swept parameters of a ``grid`` study: name -> values.
        push: The bisection of a ``push-map`` study.
        metrics: Metrics kept in each record (empty: all of them).
        timeout: Wall-clock limit of one simulation [s] (0: none).

    """

    kind: str
    name: str
    controllers: tuple[str, ...] = ("hqp",)
    fixed: Mapping[str, Any] = field(default_factory=dict)
    grid: Mapping[str, tuple[Any, ...]] = field(default_factory=dict)
    push: PushSearch = field(default_factory=PushSearch)
    metrics: tuple[str, ...] = ()
    timeout: float = 0.0

    def base_params(self, controller: str) -> Params:
        """Return the parameters every simulation of ``controller`` starts from."""
        return {**self.fixed, "controller": controller}

    def as_dict(self) -> dict[str, Any]:
        """Return the study as JSON data (the summary's ``definition``)."""
        data = asdict(self)
        data["fixed"] = dict(self.fixed)
        data["grid"] = {k: list(v) for k, v in self.grid.items()}
        return data


def simulation_id(params: Mapping[str, Any]) -> str:
    """Return the name of a simulation: a hash of its canonical params (12 hex digits)."""
    text = json.dumps(dict(params), sort_keys=True, separators=(",", ":"))
    return hashlib.sha1(text.encode()).hexdigest()[:12]


def directions(value: int | float | Sequence[float]) -> tuple[float, ...]:
    """Return push directions [deg]: ``n`` evenly spaced from 0, or the listed angles.

    Raises:
        InvalidInput: Fewer than one direction, or a non-finite angle.

    """
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        n = int(value)
        if n != value or n < 1:
            raise InvalidInput(f"study: directions must be a positive count or a list of "
                               f"angles [deg], got {value!r}")
        return tuple(360.0 * k / n for k in range(n))
    angles = tuple(float(a) for a in value)
    if not angles or not all(math.isfinite(a) for a in angles):
        raise InvalidInput(f"study: directions must be finite angles [deg], got {value!r}")
    return angles


def _positive(data: Mapping[str, Any], key: str, default: float, *, zero: bool = False) -> float:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or value < 0.0 or (value == 0.0 and not zero):
        raise InvalidInput(f"study: {key} must be a {'non-negative' if zero else 'positive'} "
                           f"number, got {value!r}")
    return float(value)


def _push_search(data: Mapping[str, Any]) -> PushSearch:
    unknown = set(data) - {"directions", "max_force", "tolerance", "min_force", "at",
                           "duration", "repeats"}
    if unknown:
        raise InvalidInput(f"study: unknown keys in [push]: {sorted(unknown)} (known: "
                           "directions, max_force, tolerance, min_force, at, duration, "
                           "repeats)")
    default = PushSearch()
    repeats = data.get("repeats", default.repeats)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or not 1 <= repeats <= 1000:
        raise InvalidInput(f"study: [push] repeats must be an integer from 1 to 1000, got "
                           f"{repeats!r}")
    search = PushSearch(
        directions=directions(data.get("directions", default.directions)),
        max_force=_positive(data, "max_force", default.max_force),
        tolerance=_positive(data, "tolerance", default.tolerance),
        min_force=_positive(data, "min_force", default.min_force, zero=True),
        repeats=repeats,
    )
    if search.min_force >= search.max_force:
        raise InvalidInput(f"study: min_force ({search.min_force} N) must be below max_force "
                           f"({search.max_force} N)")
    return search


def _scalar(key: str, value: Any) -> Any:
    if isinstance(value, (bool, int, float, str)) or value is None:
        return value
    if isinstance(value, (list, tuple)) and all(isinstance(v, (int, float)) for v in value):
        return [float(v) for v in value]
    raise InvalidInput(f"study: parameter {key} must be a number, a string or a list of "
                       f"numbers, got {value!r}")


def study_from_dict(data: Mapping[str, Any], *, kind: str | None = None) -> Study:
    """Build and check a study from its TOML tables (or the flags' equivalent).

    Keys: ``study`` (the kind, unless given), ``name``, ``controllers``, ``timeout`` [s],
    ``metrics``; the table ``[fixed]`` (and the top-level keys ``target``, ``robot``,
    ``duration``, ``backend``, which go to it); ``[push]`` (``directions``: a count or a
    list [deg], ``max_force`` [N], ``tolerance`` [N], ``min_force`` [N], ``at`` [s] and
    ``duration`` [s] of the push); ``[grid]``: parameter -> list of values.

    Raises:
        InvalidInput: A malformed or inconsistent definition.
        UnknownName: Unknown kind or controller.

    """
    kind = kind or data.get("study")
    if kind not in KINDS:
        raise UnknownName("study", str(kind), KINDS)
    known = {"study", "name", "controllers", "timeout", "metrics", "fixed", "push", "grid",
             "target", "robot", "duration", "backend"}
    unknown = set(data) - known
    if unknown:
        raise InvalidInput(f"study: unknown keys {sorted(unknown)} (known: {sorted(known)})")
    controllers = data.get("controllers", ("hqp",))
    if isinstance(controllers, str):
        controllers = (controllers,)
    controllers = tuple(controllers)
    if not controllers:
        raise InvalidInput("study: at least one controller is needed")
    for c in controllers:
        if c not in CONTROLLERS:
            raise UnknownName("controller", c, CONTROLLERS)
    fixed = {k: _scalar(k, v) for k, v in dict(data.get("fixed", {})).items()}
    for key in ("target", "robot", "duration", "backend"):
        if data.get(key) is not None:
            fixed[key] = _scalar(key, data[key])
    fixed.setdefault("target", "standing")
    push = dict(data.get("push", {}))
    for key in ("at", "duration"):
        if key in push:
            fixed[f"push_{key}"] = _positive(push, key, 0.0, zero=key == "at")
    grid = {k: tuple(_scalar(k, x) for x in (v if isinstance(v, list) else [v]))
            for k, v in dict(data.get("grid", {})).items()}
    if any(not values for values in grid.values()):
        raise InvalidInput("study: every [grid] parameter needs at least one value")
    if "controller" in grid or "controller" in fixed:
        raise InvalidInput("study: give the controllers as `controllers`, not as a parameter")
    if kind == "grid" and not grid:
        raise InvalidInput("study: a grid study needs at least one parameter in [grid]")
    if kind == "push-map" and grid:
        raise InvalidInput("study: a push-map study sweeps pushes itself; [grid] is for grids")
    search = _push_search(push)
    if kind == "push-map" and search.repeats > 1:
        if "seed" in fixed:
            raise InvalidInput("study: [push] repeats set the seed of each repeat; remove "
                               "`seed` from the fixed parameters")
        if not any(isinstance(fixed.get(k), (int, float)) and fixed[k] > 0
                   for k in PERTURBATIONS):
            raise InvalidInput(f"study: [push] repeats = {search.repeats} would run the same "
                               f"simulation {search.repeats} times: set a perturbation, one "
                               f"of {', '.join(PERTURBATIONS)} (e.g. init_q_std = 1e-4)")
    metrics = data.get("metrics", ())
    metrics = (metrics,) if isinstance(metrics, str) else tuple(metrics)
    study = Study(
        kind=kind, name=str(data.get("name", kind)), controllers=controllers, fixed=fixed,
        grid=grid, push=search, metrics=metrics,
        timeout=_positive(data, "timeout", 0.0, zero=True))
    return study


def read_study_file(path: str | Path) -> dict[str, Any]:
    """Return a study file's TOML tables, unchecked (``name`` defaults to the file's stem).

    Raises:
        InvalidInput: Missing file or TOML syntax error.

    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InvalidInput(f"study file {path}: {exc.strerror}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InvalidInput(f"study file {path}: {exc}") from None
    data.setdefault("name", path.stem)
    return data


def load_study(path: str | Path, *, kind: str | None = None) -> Study:
    """Read a study from a TOML file (see :func:`study_from_dict`).

    Raises:
        InvalidInput: Missing file, TOML syntax error, or a bad definition.

    """
    return study_from_dict(read_study_file(path), kind=kind)
