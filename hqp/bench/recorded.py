"""Recorded control problems: the level matrices of real control steps, stored and replayed.

A :class:`RecordedStep` holds what one step of a :class:`~hqp.controller.WholeBodyController`
handed to its solver (the built levels ``A, b, C, lower, upper``, highest priority first),
the same step's rows in the null-space law's form (:func:`hqp.nullspace.law_problem`: support
rows and per-level ``(J_k, a_k)`` on ``qdd``), and the dynamics the law needs (``M``, ``h``,
the actuation selection). Replaying them times the solve alone, level matrices fixed, for
every algorithm and backend, DAQP's hierarchy and the law, on exactly the same numbers.

Files are compressed ``.npz`` archives, one per source (behavior or scenario on one robot),
written by :mod:`hqp.bench.record` (``python -m hqp.app.record``) into :data:`DATA_DIR`.
Keys: ``meta`` (a JSON string: source, robot, per-step times and level names), and per step
``i`` and level ``j``:
``s{i}_L{j}_{A,b,C,lower,upper}`` (absent fields were ``None``), ``s{i}_{M,h,S,q,v}``,
``s{i}_support_{J,b}``, ``s{i}_law{j}_{J,a}``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hqp.errors import HQPError
from hqp.nullspace import law_problem
from hqp.solver import Level

DATA_DIR = Path(__file__).resolve().parent / "data"
"""Directory of the recorded problem files shipped with the package."""

_FIELDS = ("A", "b", "C", "lower", "upper")


class RecordingError(HQPError):
    """A recorded problem file is missing, malformed or of an unknown version."""


@dataclass(frozen=True)
class RecordedStep:
    """One control step's problem, as the solver and the null-space law saw it.

    Attributes:
        source: Behavior or scenario name (e.g. ``"hand-reach"``, ``"walk"``).
        robot: Robot name.
        t: Control time of the step [s].
        levels: The built solver levels, highest priority first.
        n: Number of decision variables ``x = [qdd | f_1 | ... | f_k]``.
        nv: Number of joint velocities (the ``qdd`` part of ``x``).
        M: Joint-space inertia ``(nv, nv)``.
        h: Nonlinear effects ``(nv,)`` [N m].
        S: Actuation selection ``(na, nv)``.
        support: Support rows ``(J_s (ns, nv), b_s (ns,))`` of the law, or ``None``.
        law_levels: The law's ``(J_k (m_k, nv), a_k (m_k,))`` per task level.
        q: Configuration ``(nq,)`` of the step (pinocchio convention).
        v: Velocity ``(nv,)``.

    """

    source: str
    robot: str
    t: float
    levels: tuple[Level, ...]
    n: int
    nv: int
    M: np.ndarray
    h: np.ndarray
    S: np.ndarray
    support: tuple[np.ndarray, np.ndarray] | None
    law_levels: tuple[tuple[np.ndarray, np.ndarray], ...]
    q: np.ndarray = field(default_factory=lambda: np.zeros(0))
    v: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def rows(self) -> int:
        """Total number of rows (equalities and inequalities) over all levels."""
        return sum(_nrows(lv.A) + _nrows(lv.C) for lv in self.levels)

    @property
    def label(self) -> str:
        """``source@robot``."""
        return f"{self.source}@{self.robot}"


def _nrows(M: Any) -> int:
    return 0 if M is None else int(np.shape(M)[0])


def capture(controller: Any, source: str, robot: str, t: float) -> RecordedStep:
    """Capture the last step of a controller as a :class:`RecordedStep`.

    Args:
        controller: A :class:`~hqp.controller.WholeBodyController` right after ``step``
            (its ``last_built`` levels and its model updated at the step's state).
        source: Behavior or scenario name.
        robot: Robot name.
        t: Control time of the step [s].

    Raises:
        RecordingError: The controller has not stepped yet.

    """
    built = controller.last_built
    if built is None:
        raise RecordingError("capture: the controller has not made a step yet")
    m = controller.model
    levels = tuple(
        Level(
            A=None if lv.A is None else np.array(lv.A, dtype=float),
            b=None if lv.b is None else np.array(lv.b, dtype=float),
            C=None if lv.C is None else np.array(lv.C, dtype=float),
            lower=None if lv.lower is None else np.array(lv.lower, dtype=float),
            upper=None if lv.upper is None else np.array(lv.upper, dtype=float),
            name=str(lv.name),
        )
        for lv in built.levels
    )
    law = law_problem(built, controller.stack, m.nv)
    support = None if law.support is None else (law.support[0].copy(), law.support[1].copy())
    return RecordedStep(
        source=source, robot=robot, t=float(t), levels=levels, n=int(built.n), nv=int(m.nv),
        M=np.array(m.M), h=np.array(m.h), S=np.array(m.selection()), support=support,
        law_levels=tuple((J.copy(), a.copy()) for J, a in law.levels),
        q=np.array(m.q) if hasattr(m, "q") else np.zeros(0), v=np.array(m.v),
    )


def save(path: str | Path, steps: Sequence[RecordedStep], **info: Any) -> Path:
    """Write steps of one source to a compressed ``.npz`` file.

    Args:
        path: Output file (``.npz`` appended by numpy when missing).
        steps: The steps (same source and robot).
        **info: Extra metadata stored in ``meta`` (e.g. pushes, duration).

    Returns:
        The path written.

    """
    arrays: dict[str, np.ndarray] = {}
    meta_steps = []
    for i, s in enumerate(steps):
        names = []
        for j, lv in enumerate(s.levels):
            names.append(lv.name)
            for f in _FIELDS:
                value = getattr(lv, f)
                if value is not None:
                    arrays[f"s{i}_L{j}_{f}"] = np.asarray(value, dtype=float)
        for key in ("M", "h", "S", "q", "v"):
            arrays[f"s{i}_{key}"] = np.asarray(getattr(s, key), dtype=float)
        if s.support is not None:
            arrays[f"s{i}_support_J"], arrays[f"s{i}_support_b"] = s.support
        for j, (J, a) in enumerate(s.law_levels):
            arrays[f"s{i}_law{j}_J"] = J
            arrays[f"s{i}_law{j}_a"] = a
        meta_steps.append({"t": s.t, "levels": names, "n": s.n, "nv": s.nv,
                           "law_levels": len(s.law_levels)})
    src = steps[0].source if steps else ""
    rob = steps[0].robot if steps else ""
    meta = {"version": 1, "source": src, "robot": rob, "steps": meta_steps, **info}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, meta=np.array(json.dumps(meta)), **arrays)
    return path if path.suffix == ".npz" else path.with_suffix(path.suffix + ".npz")


def load(path: str | Path) -> list[RecordedStep]:
    """Read the steps of one recorded file.

    Raises:
        RecordingError: Missing file, no ``meta``, or an unknown version.

    """
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"recorded problem file not found: {path}")
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    if "meta" not in data:
        raise RecordingError(f"{path}: no 'meta' entry (not a recorded problem file)")
    meta = json.loads(str(data["meta"]))
    if meta.get("version") != 1:
        raise RecordingError(f"{path}: unknown version {meta.get('version')!r}")
    out = []
    for i, ms in enumerate(meta["steps"]):
        levels = []
        for j, name in enumerate(ms["levels"]):
            kw = {f: data.get(f"s{i}_L{j}_{f}") for f in _FIELDS}
            levels.append(Level(name=name, **kw))
        support = None
        if f"s{i}_support_J" in data:
            support = (data[f"s{i}_support_J"], data[f"s{i}_support_b"])
        law = tuple((data[f"s{i}_law{j}_J"], data[f"s{i}_law{j}_a"])
                    for j in range(ms["law_levels"]))
        out.append(RecordedStep(
            source=meta["source"], robot=meta["robot"], t=float(ms["t"]), levels=tuple(levels),
            n=int(ms["n"]), nv=int(ms["nv"]), M=data[f"s{i}_M"], h=data[f"s{i}_h"],
            S=data[f"s{i}_S"], support=support, law_levels=law, q=data[f"s{i}_q"],
            v=data[f"s{i}_v"],
        ))
    return out


def available(directory: str | Path | None = None) -> list[Path]:
    """List the recorded problem files in ``directory`` (default :data:`DATA_DIR`), sorted."""
    d = DATA_DIR if directory is None else Path(directory)
    return sorted(d.glob("*.npz")) if d.is_dir() else []


def load_all(directory: str | Path | None = None) -> list[RecordedStep]:
    """Every step of every recorded file in ``directory`` (default :data:`DATA_DIR`)."""
    out: list[RecordedStep] = []
    for p in available(directory):
        out.extend(load(p))
    return out
