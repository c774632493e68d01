"""Behavior description files (TOML): the seed's behavior editor made declarative.

A file declares a behavior's runtime inputs, its tasks (control primitives
with a priority level and parameters), optional action primitives (named
task sets), its phases (the states of the machine: an action primitive, the
supporting contacts, goal overrides, transitions with conditions, an optional
safety phase) and an optional trajectory planner. See
``hqp/behaviors/library/*.toml`` for complete examples and
:func:`load_behavior` for the keys.

Every mistake raises :class:`hqp.BehaviorFileError` whose message reads
``<file>:<line>: <key>: <what was expected>``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import tomllib

from hqp.behaviors.expressions import Expression, ExpressionError, parse
from hqp.behaviors.planners import OUTPUT_NAMES as WALK_OUTPUTS
from hqp.behaviors.planners import PLANNER_TYPES as WALK_TYPES
from hqp.behaviors.schema import SCHEMAS, TaskSchema
from hqp.behaviors.spec import (
    ActionPrimitive,
    BehaviorSpec,
    InputSpec,
    PhaseSpec,
    PlannerSpec,
    TaskSpec,
    Transition,
)
from hqp.errors import BehaviorFileError, UnknownName
from hqp.robots.robot import DIMENSIONS
from hqp.solver.backends import known_backends
from hqp.tasks.base import Category

LIBRARY = Path(__file__).resolve().parent / "library"
"""Folder of the bundled behavior files."""

SENSED_NAMES = frozenset(
    {
        "t", "phase_time", "com", "com_velocity", "com0", "feet_center", "contact", "contacts",
        "error", "conflict", "infeasible", "joint", "joint_margin", "input", "plan", "frame",
        "robot",
    }
)
"""Names a condition may read (see :class:`hqp.behaviors.behavior.Behavior`); ``robot.<name>``
are the robot's dimensions (:data:`hqp.robots.robot.DIMENSIONS`), fixed for a run."""

GOAL_NAMES = SENSED_NAMES | {"initial", "standing", "pose"}
"""Names a goal expression may read: the sensed ones, the task's value when its phase
began (``initial``), the robot's standing configuration (``standing``) and the captured
poses of the file (``pose.<name>``: the standing configuration with the pose's joints)."""

PLANNER_OUTPUTS: dict[str, frozenset[str]] = {name: frozenset(WALK_OUTPUTS) for name in WALK_TYPES}
"""Planner types and the ``plan.<name>`` values each provides (``placo_walk``: an alias of
``walk``, the type's name when PlaCo planned the walk)."""

_LEVEL_NAMES = {c.name.lower(): c for c in Category}
_TOP = {"behavior", "inputs", "tasks", "actions", "phases", "planner", "contacts", "poses"}


class _Ctx:
    """The file being read: its path and text, to name keys and find their lines."""

    def __init__(self, path: Path | None, text: str) -> None:
        self.path = path
        self.lines = text.splitlines()

    def error(self, key: tuple[str | int, ...], message: str) -> BehaviorFileError:
        name = str(self.path) if self.path is not None else "<behavior>"
        line = self.locate(key)
        dotted = ".".join(str(k) if isinstance(k, str) else f"[{k}]" for k in key)
        dotted = dotted.replace(".[", "[")
        where = f"{name}:{line}" if line is not None else name
        return BehaviorFileError(f"{where}: {dotted}: {message}" if key else f"{where}: {message}")

    def locate(self, key: tuple[str | int, ...]) -> int | None:
        """Line (1-based) of the deepest table header or key that is a prefix of ``key``."""
        want = [k for k in key if isinstance(k, str)]
        header: list[str] = []
        best, best_len = None, 0
        for i, raw in enumerate(self.lines, 1):
            s = raw.split("#", 1)[0].strip()
            if not s:
                continue
            if s.startswith("["):
                header = [p.strip().strip('"') for p in s.strip("[] ").split(".")]
                path = header
            elif "=" in s:
                path = header + [p.strip().strip('"') for p in s.split("=", 1)[0].split(".")]
            else:
                continue
            n = len(path)
            if n > best_len and path == want[:n]:
                best, best_len = i, n
        return best


def file_error(path: Path | None, key: tuple[str | int, ...], message: str
               ) -> BehaviorFileError:
    """Return the error of a key of a behavior file found wrong after loading.

    For checks that need the robot or the controller (see
    :func:`hqp.behaviors.setup.prepare`); the message reads ``<file>:<line>: <key>: ...``.
    """
    text = path.read_text() if path is not None and path.is_file() else ""
    return _Ctx(path, text).error(key, message)


def library_names() -> list[str]:
    """Names of the bundled behaviors (``hqp/behaviors/library/*.toml``)."""
    return sorted(p.stem for p in LIBRARY.glob("*.toml"))


def resolve(source: str | Path) -> Path:
    """Path of a behavior: a library name (``"walk"``) or a file path.

    Raises:
        UnknownName: Neither an existing file nor a library name.

    """
    p = Path(source)
    if p.suffix == ".toml" or p.exists():
        if not p.is_file():
            raise BehaviorFileError(f"{p}: no such behavior file")
        return p
    candidate = LIBRARY / f"{source}.toml"
    if candidate.is_file():
        return candidate

    raise UnknownName("behavior", str(source), library_names())


def load_behavior(
    source: str | Path,
    *,
    frames: Iterable[str] | None = None,
    joints: Iterable[str] | None = None,
    contacts: Iterable[str] | None = None,
) -> BehaviorSpec:
    """Read a behavior file (a path or a library name) into a :class:`BehaviorSpec`.

    Args:
        source: Path of a ``.toml`` file, or the name of a bundled behavior.
        frames: Frames of the robot (when given, every frame key is checked).
        joints: Actuated joint names (checks ``joint.<name>`` and posture ``joints``).
        contacts: Contact names of the robot (checks ``contacts`` of phases).

    Returns:
        The behavior description.

    Raises:
        BehaviorFileError: The file is malformed; the message names the file,
            the line where it can, the key, and what was expected.

    """
    path = resolve(source)
    text = path.read_text()
    return parse_behavior(text, path=path, frames=frames, joints=joints, contacts=contacts)


def parse_behavior(
    text: str,
    *,
    path: Path | None = None,
    frames: Iterable[str] | None = None,
    joints: Iterable[str] | None = None,
    contacts: Iterable[str] | None = None,
) -> BehaviorSpec:
    """Parse the text of a behavior file (see :func:`load_behavior`).

    File layout (every key of a table is checked; unknown keys are errors)::

        [behavior]      name, description, initial (phase), duration [s], robot,
                        ramp_time [s], unload_time [s], safety (default safety phase),
                        inputs_file (default inputs, relative to the file),
                        backend (QP backend of the HQP controller),
                        max_joint_acceleration [rad/s^2] (HQP joint-acceleration clip),
                        max_torque_rate [N m/s] (HQP torque-rate level; 0: none)
        [contacts]      optional: contact name = frame (default: the robot's contacts)
        [inputs.NAME]   shape, default (numbers, or an expression of robot.<name>),
                        interpolate, description   -> input.NAME
        [tasks.NAME]    type, level (int or category), weight, then the type's
                        frames, goals (numbers or expressions) and parameters
        [actions.NAME]  tasks = [...], levels = {task = level}      (action primitives)
        [phases.NAME]   action or tasks, contacts, goals = {task = expr},
                        final, safety, watch, ramp_time, unload_time, blend_time [s],
                        joint_braking ("contacts" or "airborne"),
                        [[phases.NAME.transitions]] to, when
        [poses.NAME]    joint = position [rad], ...   -> pose.NAME (captured poses)
        [planner]       type = "walk", then the planner's parameters -> plan.*
    """
    ctx = _Ctx(path, text)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        name = str(path) if path is not None else "<behavior>"
        raise BehaviorFileError(f"{name}: not valid TOML: {exc}") from None
    except RecursionError:
        name = str(path) if path is not None else "<behavior>"
        raise BehaviorFileError(f"{name}: arrays or tables nested too deeply") from None
    for key in data:
        if key not in _TOP:
            raise ctx.error((key,), f"unknown section; expected one of {', '.join(sorted(_TOP))}")
    frame_set = None if frames is None else set(frames)
    joint_set = None if joints is None else set(joints)
    head = _head(ctx, data, path)
    contact_frames = _contacts(ctx, data, frame_set)
    contact_set: set[str] | None
    if contact_frames:
        contact_set = set(contact_frames)
    else:
        contact_set = None if contacts is None else set(contacts)
    inputs = {iname: _input(ctx, iname, itab)
              for iname, itab in _table(ctx, data, ("inputs",)).items()}
    planner = _planner(ctx, data)
    plan_names = PLANNER_OUTPUTS[planner.type] if planner else frozenset()
    poses = {pose_name: _pose(ctx, pose_name, ptab, joint_set)
             for pose_name, ptab in _table(ctx, data, ("poses",)).items()}
    task_names = set(_table(ctx, data, ("tasks",)))
    env = _NameCheck(ctx, inputs, task_names, contact_set, plan_names, frame_set, joint_set,
                     set(poses))
    tasks = {tname: _task(ctx, env, tname, ttab, frame_set, joint_set, contact_set)
             for tname, ttab in _table(ctx, data, ("tasks",), required=True).items()}
    actions: dict[str, ActionPrimitive] = {}
    for aname, atab in _table(ctx, data, ("actions",)).items():
        key = ("actions", aname)
        if not isinstance(atab, dict):
            raise ctx.error(key, "expected a table with 'tasks' and optional 'levels'")
        _check_keys(ctx, atab, key, {"tasks", "levels"})
        actions[aname] = _action(ctx, key, aname, atab, tasks)
    ptabs = _table(ctx, data, ("phases",), required=True)
    _check_phase_names(ctx, ptabs, head["initial"], head["safety"])
    phases = {pname: _phase(ctx, env, pname, ptab, tasks, actions, set(ptabs), contact_set,
                            head["safety"])
              for pname, ptab in ptabs.items()}
    _check_reachable(ctx, phases, head["initial"])
    return BehaviorSpec(
        name=head["name"], description=head["description"], initial=head["initial"],
        phases=phases, tasks=tasks, inputs=inputs, planner=planner, duration=head["duration"],
        robot=head["robot"], ramp_time=head["ramp_time"], unload_time=head["unload_time"],
        path=path, contact_frames=contact_frames, poses=poses, inputs_file=head["inputs_file"],
        backend=head["backend"], max_joint_acceleration=head["max_joint_acceleration"],
        max_torque_rate=head["max_torque_rate"],
    )


# -- sections --------------------------------------------------------------------------------


def _head(ctx: _Ctx, data: Mapping[str, Any], path: Path | None) -> dict[str, Any]:
    """Read the ``[behavior]`` table (the inputs file resolved, the backend checked)."""
    head = _table(ctx, data, ("behavior",), required=True)
    _check_keys(ctx, head, ("behavior",), {
        "name", "description", "initial", "duration", "robot", "ramp_time", "unload_time",
        "safety", "inputs_file", "backend", "max_joint_acceleration", "max_torque_rate",
    })
    out: dict[str, Any] = {
        "name": _get(ctx, head, ("behavior", "name"), str,
                     default=path.stem if path else "behavior"),
        "description": _get(ctx, head, ("behavior", "description"), str, default=""),
        "initial": _get(ctx, head, ("behavior", "initial"), str, required=True),
        "duration": _positive(ctx, head, ("behavior", "duration"), 5.0),
        "robot": _get(ctx, head, ("behavior", "robot"), str, default="paper-humanoid"),
        "ramp_time": _positive(ctx, head, ("behavior", "ramp_time"), 0.2, allow_zero=True),
        "unload_time": _positive(ctx, head, ("behavior", "unload_time"), 0.1, allow_zero=True),
        "safety": _get(ctx, head, ("behavior", "safety"), str, default=None),
    }
    inputs_file = _get(ctx, head, ("behavior", "inputs_file"), str, default=None)
    backend = _get(ctx, head, ("behavior", "backend"), str, default=None)
    max_qdd = None
    if "max_joint_acceleration" in head:
        max_qdd = _positive(ctx, head, ("behavior", "max_joint_acceleration"), 50.0)
        if max_qdd < 5.0:
            raise ctx.error(("behavior", "max_joint_acceleration"),
                            f"expected at least 5 rad/s^2, got {max_qdd}")
    max_rate = None
    if "max_torque_rate" in head:
        max_rate = _positive(ctx, head, ("behavior", "max_torque_rate"), 0.0, allow_zero=True)
    if backend is not None:
        if backend not in known_backends():
            raise ctx.error(("behavior", "backend"), f"unknown QP backend {backend!r}; "
                            f"expected one of {', '.join(known_backends())}")
    inputs_path = None
    if inputs_file is not None:
        base = path.parent if path is not None else Path.cwd()
        inputs_path = (base / inputs_file).resolve()
        if not inputs_path.is_file():
            raise ctx.error(("behavior", "inputs_file"), f"no such file {str(inputs_path)!r}; "
                            "expected a JSON Lines file of timed inputs")
    out.update(inputs_file=inputs_path, backend=backend, max_joint_acceleration=max_qdd,
               max_torque_rate=max_rate)
    return out


def _contacts(ctx: _Ctx, data: Mapping[str, Any], frame_set: set[str] | None
              ) -> dict[str, str]:
    """Read the ``[contacts]`` table: contact name -> frame."""
    contact_frames: dict[str, str] = {}
    for cname, cframe in _table(ctx, data, ("contacts",)).items():
        if not isinstance(cframe, str):
            raise ctx.error(("contacts", cname), "expected a frame name (string)")
        _check_frame(ctx, ("contacts", cname), cframe, frame_set)
        contact_frames[cname] = cframe
    return contact_frames


def _input(ctx: _Ctx, iname: str, itab: Any) -> InputSpec:
    """Read one ``[inputs.NAME]`` table."""
    key = ("inputs", iname)
    if not isinstance(itab, dict):
        raise ctx.error(key, "expected a table with shape, default, interpolate")
    _check_keys(ctx, itab, key, {"shape", "default", "interpolate", "description"})
    default = itab.get("default")
    shape_raw = itab.get("shape")
    default_expr = None
    if isinstance(default, str):  # an expression of the robot's dimensions
        if shape_raw is None:
            raise ctx.error((*key, "shape"), "missing key: an expression default needs a shape")
        try:
            default_expr = parse(default, {"robot"})
        except ExpressionError as exc:
            raise ctx.error((*key, "default"), f"{exc} (a default may read robot.<name> "
                            "only)") from None
        for _, attr in default_expr.attributes:
            if attr not in DIMENSIONS and attr not in ("x", "y", "z"):
                raise ctx.error((*key, "default"), f"robot.{attr}: unknown robot dimension; "
                                f"expected one of {', '.join(DIMENSIONS)}")
        default = None
    if default is not None:
        try:
            default_arr = np.array(default, dtype=float)
        except (TypeError, ValueError):
            raise ctx.error((*key, "default"),
                            "expected a number or a list of numbers") from None
        if not np.isfinite(default_arr).all():
            raise ctx.error((*key, "default"), "expected finite numbers")
    else:
        default_arr = None
    if shape_raw is None:
        if default_arr is None:
            raise ctx.error(key, "expected 'shape' or 'default'")
        shape = tuple(default_arr.shape)
    else:
        if not (isinstance(shape_raw, list) and all(isinstance(s, int) and s > 0
                                                    for s in shape_raw)):
            raise ctx.error((*key, "shape"), "expected a list of positive integers, e.g. [3]")
        shape = tuple(shape_raw)
        if default_arr is not None and default_arr.shape != shape:
            raise ctx.error((*key, "default"),
                            f"expected shape {list(shape)}, got {list(default_arr.shape)}")
    return InputSpec(
        iname, shape, default_arr,
        bool(_get(ctx, itab, (*key, "interpolate"), bool, default=False)),
        _get(ctx, itab, (*key, "description"), str, default=""),
        default_expr,
    )


def _planner(ctx: _Ctx, data: Mapping[str, Any]) -> PlannerSpec | None:
    """Read the ``[planner]`` table (``None``: no planner)."""
    if "planner" not in data:
        return None
    ptab = _table(ctx, data, ("planner",))
    ptype = _get(ctx, ptab, ("planner", "type"), str, required=True)
    if ptype not in PLANNER_OUTPUTS:
        raise ctx.error(("planner", "type"),
                        f"unknown planner {ptype!r}; expected one of "
                        f"{', '.join(sorted(PLANNER_OUTPUTS))}")
    return PlannerSpec(ptype, {k: v for k, v in ptab.items() if k != "type"})


def _pose(ctx: _Ctx, pose_name: str, ptab: Any, joint_set: set[str] | None
          ) -> dict[str, float]:
    """Read one ``[poses.NAME]`` table: joint -> position [rad]."""
    key = ("poses", pose_name)
    if not isinstance(ptab, dict) or not ptab:
        raise ctx.error(key, "expected a table of joint = position [rad]")
    for joint, value in ptab.items():
        if joint_set is not None and joint not in joint_set:
            raise ctx.error((*key, joint), f"unknown joint {joint!r}; expected one of "
                            f"{', '.join(sorted(joint_set))}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not np.isfinite(value):
            raise ctx.error((*key, joint), f"expected a joint position [rad], got {value!r}")
    return {j: float(v) for j, v in ptab.items()}


def _check_phase_names(ctx: _Ctx, ptabs: Mapping[str, Any], initial: str,
                       default_safety: str | None) -> None:
    """At least one phase; the initial and the default safety phase are phases."""
    if not ptabs:
        raise ctx.error(("phases",), "expected at least one phase")
    phase_names = set(ptabs)
    if initial not in phase_names:
        raise ctx.error(("behavior", "initial"),
                        f"initial phase {initial!r} is not a phase; phases: "
                        f"{', '.join(sorted(phase_names))}")
    if default_safety is not None and default_safety not in phase_names:
        raise ctx.error(("behavior", "safety"),
                        f"safety phase {default_safety!r} is not a phase; phases: "
                        f"{', '.join(sorted(phase_names))}")


def _check_reachable(ctx: _Ctx, phases: Mapping[str, PhaseSpec], initial: str) -> None:
    """Every phase is reached from the initial one (by transitions or safety)."""
    seen, todo = {initial}, [initial]
    while todo:
        p = phases[todo.pop()]
        for nxt in [tr.to for tr in p.transitions] + ([p.safety] if p.safety else []):
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    for pname in phases:
        if pname not in seen:
            raise ctx.error(("phases", pname),
                            f"phase {pname!r} cannot be reached from the initial phase "
                            f"{initial!r}; expected a transition to it")


# -- helpers ---------------------------------------------------------------------------------


class _NameCheck:
    """Checks the names an expression reads against what the behavior declares."""

    def __init__(
        self, ctx: _Ctx, inputs: Mapping[str, InputSpec], tasks: set[str],
        contacts: set[str] | None, plan: frozenset[str], frames: set[str] | None,
        joints: set[str] | None, poses: set[str],
    ) -> None:
        self.ctx = ctx
        self.known: dict[str, set[str] | None] = {
            "input": set(inputs), "error": tasks, "conflict": tasks, "infeasible": tasks,
            "contact": contacts,
            "plan": set(plan), "frame": frames, "joint": joints, "joint_margin": joints,
            "pose": poses, "robot": set(DIMENSIONS),
        }

    def expression(self, key: tuple[str | int, ...], value: Any, goal: bool) -> Expression:
        if not isinstance(value, str):
            raise self.ctx.error(key, "expected an expression string")
        try:
            expr = parse(value, GOAL_NAMES if goal else SENSED_NAMES)
        except ExpressionError as exc:
            raise self.ctx.error(key, str(exc)) from None
        for ns, attr in expr.attributes:
            valid = self.known.get(ns)
            if ns in self.known and valid is not None and attr not in valid:
                what = {"input": "input", "error": "task", "conflict": "task",
                        "infeasible": "task",
                        "contact": "contact", "plan": "planner output", "frame": "frame",
                        "joint": "joint", "joint_margin": "joint", "pose": "pose",
                        "robot": "robot dimension"}[ns]
                hint = ("; declare it under [planner]" if ns == "plan" and not valid else "")
                raise self.ctx.error(
                    key, f"{ns}.{attr}: unknown {what} {attr!r}; expected one of "
                    f"{', '.join(sorted(valid)) or 'none'}{hint}")
        return expr


def _table(ctx: _Ctx, data: Mapping[str, Any], key: tuple[str, ...], required: bool = False
           ) -> dict[str, Any]:
    value = data.get(key[-1])
    if value is None:
        if required:
            raise ctx.error(key, "missing table")
        return {}
    if not isinstance(value, dict):
        raise ctx.error(key, "expected a table")
    return value


def _check_keys(ctx: _Ctx, table: Mapping[str, Any], key: tuple[str | int, ...],
                allowed: Iterable[str]) -> None:
    allowed = set(allowed)
    for k in table:
        if k not in allowed:
            raise ctx.error((*key, k), f"unknown key; expected one of {', '.join(sorted(allowed))}")


def _get(ctx: _Ctx, table: Mapping[str, Any], key: tuple[str | int, ...], kind: type | tuple,
         default: Any = None, required: bool = False) -> Any:
    name = key[-1]
    if name not in table:
        if required:
            raise ctx.error(key, "missing key")
        return default
    value = table[name]
    numeric = kind in (int, float, (int, float))
    if numeric and isinstance(value, bool) or not isinstance(value, kind):
        kinds = kind if isinstance(kind, tuple) else (kind,)
        want = " or ".join(k.__name__ for k in kinds)
        raise ctx.error(key, f"expected {want}, got {type(value).__name__} {value!r}")
    return value


def _positive(ctx: _Ctx, table: Mapping[str, Any], key: tuple[str | int, ...], default: float,
              allow_zero: bool = False) -> float:
    value = float(_get(ctx, table, key, (int, float), default=default))
    if not np.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise ctx.error(key, f"expected a {'non-negative' if allow_zero else 'positive'} "
                        f"number, got {value}")
    return value


def _check_frame(ctx: _Ctx, key: tuple[str | int, ...], frame: str,
                 frames: set[str] | None) -> None:
    if frames is not None and frame not in frames:
        raise ctx.error(key, f"unknown frame {frame!r}; expected one of "
                        f"{', '.join(sorted(frames))}")


def _level(ctx: _Ctx, key: tuple[str | int, ...], value: Any) -> int | Category:
    if isinstance(value, bool):
        raise ctx.error(key, f"expected a level index or a category, got {value!r}")
    if isinstance(value, int):
        if value < 0:
            raise ctx.error(key, f"expected a non-negative level index, got {value}")
        return value
    if isinstance(value, str) and value.lower() in _LEVEL_NAMES:
        return _LEVEL_NAMES[value.lower()]
    raise ctx.error(key, f"expected a level index or one of {', '.join(_LEVEL_NAMES)}, "
                    f"got {value!r}")


def _task(ctx: _Ctx, env: _NameCheck, tname: str, ttab: Any, frames: set[str] | None,
          joints: set[str] | None, contacts: set[str] | None) -> TaskSpec:
    key = ("tasks", tname)
    if not isinstance(ttab, dict):
        raise ctx.error(key, "expected a table with 'type' and the task's parameters")
    ttype = _get(ctx, ttab, (*key, "type"), str, required=True)
    schema: TaskSchema | None = SCHEMAS.get(ttype)
    if schema is None:
        raise ctx.error((*key, "type"), f"unknown task type {ttype!r}; expected one of "
                        f"{', '.join(sorted(SCHEMAS))}")
    _check_keys(ctx, ttab, key, {"type", "level", "weight", *schema.keys()})
    for r in schema.required:
        if r not in ttab:
            raise ctx.error((*key, r), f"missing key (required by task type {ttype!r})")
    level = _level(ctx, (*key, "level"), ttab.get("level", schema.category.name.lower()))
    weight = _positive(ctx, ttab, (*key, "weight"), 1.0)
    task_frames: dict[str, str] = {}
    for f in schema.frames:
        if f in ttab:
            v = _get(ctx, ttab, (*key, f), str)
            _check_frame(ctx, (*key, f), v, frames)
            task_frames[f] = v
    goals: dict[str, Expression] = {}
    for g in schema.goals:
        if g in ttab:
            goals[g] = _goal(ctx, env, (*key, g), ttab[g])
    params: dict[str, Any] = {}
    for p, kind in schema.params.items():
        if p in ttab:
            params[p] = _get(ctx, ttab, (*key, p), kind)
            if p in ("kp", "kv", "max_velocity", "max_acceleration", "d_safe", "radius") and (
                not np.isfinite(params[p]) or params[p] < 0
            ):
                raise ctx.error((*key, p), f"expected a non-negative number, got {params[p]}")
    if "axes" in params and (not params["axes"] or set(params["axes"]) - set("xyz")):
        raise ctx.error((*key, "axes"), f"expected a subset of 'xyz', got {params['axes']!r}")
    if "joints" in params and joints is not None:
        for j in params["joints"]:
            if j not in joints:
                raise ctx.error((*key, "joints"), f"unknown joint {j!r}; expected one of "
                                f"{', '.join(sorted(joints))}")
    if "contacts" in params and contacts is not None:
        for c in params["contacts"]:
            if c not in contacts:
                raise ctx.error((*key, "contacts"), f"unknown contact {c!r}; expected one of "
                                f"{', '.join(sorted(contacts))}")
    return TaskSpec(tname, ttype, level, weight, task_frames, params, goals)


def _goal(ctx: _Ctx, env: _NameCheck, key: tuple[str | int, ...], value: Any) -> Expression:
    """Parse a goal: a number, a list of numbers (constant) or an expression string."""
    if isinstance(value, str):
        return env.expression(key, value, goal=True)
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ctx.error(key, "expected a number, a list of numbers or an expression") from None
    if not np.isfinite(arr).all():
        raise ctx.error(key, "expected finite numbers")
    return parse(repr(arr.tolist()))


def _action(ctx: _Ctx, key: tuple[str | int, ...], name: str, table: Mapping[str, Any],
            tasks: Mapping[str, TaskSpec]) -> ActionPrimitive:
    names = _get(ctx, table, (*key, "tasks"), list, required=True)
    levels = _get(ctx, table, (*key, "levels"), dict, default={})
    out = []
    for i, t in enumerate(names):
        if t not in tasks:
            raise ctx.error((*key, "tasks", i), f"unknown task {t!r}; expected one of "
                            f"{', '.join(sorted(tasks))}")
        spec = tasks[t]
        if t in levels:
            spec = TaskSpec(spec.name, spec.type, _level(ctx, (*key, "levels", t), levels[t]),
                            spec.weight, spec.frames, spec.params, spec.goals)
        out.append(spec)
    for t in levels:
        if t not in names:
            raise ctx.error((*key, "levels", t), f"task {t!r} is not in this action's tasks")
    if len(set(names)) != len(names):
        raise ctx.error((*key, "tasks"), "a task is listed twice")
    return ActionPrimitive(name, tuple(out))


def _phase_contacts(ctx: _Ctx, key: tuple[str, ...], ptab: Mapping[str, Any],
                    contacts: set[str] | None) -> tuple[str, ...]:
    """Read a phase's supporting contacts (``contacts = [...]``)."""
    cl = _get(ctx, ptab, (*key, "contacts"), list, default=None)
    if cl is None:
        if contacts is None:
            raise ctx.error((*key, "contacts"),
                            "missing key: list the supporting contacts (e.g. "
                            "[\"left_foot\", \"right_foot\"], or [] for a flight phase)")
        return tuple(sorted(contacts))
    for i, c in enumerate(cl):
        if not isinstance(c, str) or (contacts is not None and c not in contacts):
            raise ctx.error((*key, "contacts", i), f"unknown contact {c!r}; expected one of "
                            f"{', '.join(sorted(contacts or []))}")
    return tuple(cl)


def _phase_goals(ctx: _Ctx, env: _NameCheck, key: tuple[str, ...], ptab: Mapping[str, Any],
                 tasks: Mapping[str, TaskSpec], action: ActionPrimitive
                 ) -> dict[str, dict[str, Expression]]:
    """Read a phase's ``goals = {task = expr or {goal = expr}}``."""
    goals: dict[str, dict[str, Expression]] = {}
    for tname, gv in _get(ctx, ptab, (*key, "goals"), dict, default={}).items():
        gkey = (*key, "goals", tname)
        if tname not in action.task_names:
            raise ctx.error(gkey, f"task {tname!r} is not active in this phase; active: "
                            f"{', '.join(action.task_names)}")
        schema = SCHEMAS[tasks[tname].type]
        if not schema.goals:
            raise ctx.error(gkey, f"task type {schema.type!r} has no goal")
        if isinstance(gv, dict):
            for g, v in gv.items():
                if g not in schema.goals:
                    raise ctx.error((*gkey, g), f"unknown goal; expected one of "
                                    f"{', '.join(schema.goals)}")
                goals.setdefault(tname, {})[g] = _goal(ctx, env, (*gkey, g), v)
        else:
            goals[tname] = {schema.goals[0]: _goal(ctx, env, gkey, gv)}
    return goals


def _transitions(ctx: _Ctx, env: _NameCheck, key: tuple[str, ...], ptab: Mapping[str, Any],
                 phase_names: set[str]) -> list[Transition]:
    """Read a phase's ``[[transitions]]`` (to, when)."""
    transitions = []
    raw = _get(ctx, ptab, (*key, "transitions"), list, default=[])
    for i, tr in enumerate(raw):
        tkey = (*key, "transitions", i)
        if not isinstance(tr, dict):
            raise ctx.error(tkey, "expected a table with 'to' and 'when'")
        _check_keys(ctx, tr, tkey, {"to", "when"})
        to = _get(ctx, tr, (*tkey, "to"), str, required=True)
        if to not in phase_names:
            raise ctx.error((*tkey, "to"), f"transition to a missing phase {to!r}; phases: "
                            f"{', '.join(sorted(phase_names))}")
        when = env.expression((*tkey, "when"), _get(ctx, tr, (*tkey, "when"), str, required=True),
                              goal=False)
        transitions.append(Transition(to, when))
    return transitions


def _phase(ctx: _Ctx, env: _NameCheck, pname: str, ptab: Any, tasks: Mapping[str, TaskSpec],
           actions: Mapping[str, ActionPrimitive], phase_names: set[str],
           contacts: set[str] | None, default_safety: str | None) -> PhaseSpec:
    key = ("phases", pname)
    if not isinstance(ptab, dict):
        raise ctx.error(key, "expected a table")
    _check_keys(ctx, ptab, key, {"action", "tasks", "contacts", "goals", "final", "safety",
                                 "watch", "ramp_time", "unload_time", "blend_time",
                                 "joint_braking", "transitions", "levels"})
    if ("action" in ptab) == ("tasks" in ptab):
        raise ctx.error(key, "expected exactly one of 'action' (an [actions] name) or 'tasks'")
    if "action" in ptab:
        aname = _get(ctx, ptab, (*key, "action"), str)
        if aname not in actions:
            raise ctx.error((*key, "action"), f"unknown action {aname!r}; expected one of "
                            f"{', '.join(sorted(actions)) or 'none (no [actions] table)'}")
        action = actions[aname]
        if "levels" in ptab:
            raise ctx.error((*key, "levels"), "put level overrides in the action")
    else:
        action = _action(ctx, key, pname, ptab, tasks)
    phase_contacts = _phase_contacts(ctx, key, ptab, contacts)
    goals = _phase_goals(ctx, env, key, ptab, tasks, action)
    final = _get(ctx, ptab, (*key, "final"), bool, default=False)
    safety = _get(ctx, ptab, (*key, "safety"), str, default=default_safety)
    if safety == pname:
        safety = None
    if safety is not None and safety not in phase_names:
        raise ctx.error((*key, "safety"), f"transition to a missing phase {safety!r}; phases: "
                        f"{', '.join(sorted(phase_names))}")
    watch = tuple(_get(ctx, ptab, (*key, "watch"), list, default=[]))
    for i, w in enumerate(watch):
        if w not in action.task_names:
            raise ctx.error((*key, "watch", i), f"task {w!r} is not active in this phase; "
                            f"active: {', '.join(action.task_names)}")
    if safety is not None and not watch and "watch" not in ptab:
        watch = tuple(t.name for t in action.tasks if t.type in
                      ("com", "position", "orientation", "pose"))
    ramp_time = ptab.get("ramp_time")
    if ramp_time is not None:
        ramp_time = _positive(ctx, ptab, (*key, "ramp_time"), 0.0, allow_zero=True)
    unload_time = ptab.get("unload_time")
    if unload_time is not None:
        unload_time = _positive(ctx, ptab, (*key, "unload_time"), 0.0, allow_zero=True)
    blend_time = ptab.get("blend_time")
    if blend_time is not None:
        blend_time = _positive(ctx, ptab, (*key, "blend_time"), 0.0, allow_zero=True)
    joint_braking = _get(ctx, ptab, (*key, "joint_braking"), str, default="contacts")
    if joint_braking not in ("contacts", "airborne"):
        raise ctx.error((*key, "joint_braking"), f"expected \"contacts\" or \"airborne\", "
                        f"got {joint_braking!r}")
    transitions = _transitions(ctx, env, key, ptab, phase_names)
    if not final and not transitions:
        raise ctx.error(key, "phase has no exit: expected [[phases."
                        f"{pname}.transitions]] (to, when) or final = true")
    return PhaseSpec(pname, action, phase_contacts, tuple(transitions), goals, final, safety,
                     watch, ramp_time, unload_time, blend_time, joint_braking)
