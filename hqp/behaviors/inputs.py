"""Runtime inputs of a behavior, streamed from a file (the seed's sensory layer).

An inputs file is JSON Lines: one object per line, each with a time ``t``
[s] (simulated time) and values of some inputs, e.g.::

    {"t": 0.0, "hand_goal": [0.35, -0.25, 1.05]}
    {"t": 2.0, "hand_goal": [0.40, -0.10, 1.20]}

A value applies from its time on (zero-order hold), or is interpolated
linearly to the next sample when the input is declared ``interpolate = true``.
The file is read as simulated time advances, so another process may append
lines while a behavior runs. A ``.json`` file holding a list of the same
objects (or an object with a ``"samples"`` list) is read at once.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import IO

import numpy as np

from hqp.behaviors.spec import InputSpec
from hqp.errors import InvalidInput


class InputStream:
    """Values of a behavior's runtime inputs over simulated time.

    Args:
        specs: The behavior's inputs by name.
        path: Inputs file (JSON Lines); ``None``: the defaults only.

    Raises:
        InvalidInput: A line that is not JSON, has no finite ``t`` or a time before the
            last, names an unknown input, or holds a value of the wrong shape (the message
            names the file and line: every line the file holds when the stream opens is
            checked then, before a run); or an input without default and without samples.

    """

    def __init__(self, specs: Mapping[str, InputSpec], path: str | Path | None = None) -> None:
        self.specs = dict(specs)
        self.path = None if path is None else Path(path)
        self._samples: dict[str, list[tuple[float, np.ndarray]]] = {k: [] for k in specs}
        self._file: IO[str] | None = None
        self._line = 0
        self._last_t = -np.inf
        self._pending = ""
        if self.path is not None:
            if not self.path.is_file():
                raise InvalidInput(f"inputs file {self.path}: no such file")
            if self.path.suffix == ".json":
                try:
                    data = json.loads(self.path.read_text())
                except RecursionError:
                    raise InvalidInput(f"inputs file {self.path}: nested too deeply") from None
                except json.JSONDecodeError as exc:
                    raise InvalidInput(f"inputs file {self.path}: not JSON ({exc})") from None
                samples = data.get("samples") if isinstance(data, dict) else data
                if not isinstance(samples, list):
                    raise InvalidInput(f"inputs file {self.path}: expected a list of samples "
                                       "or an object with 'samples'")
                for i, obj in enumerate(samples):
                    self._add(obj, f"samples[{i}]")
            else:
                self._check_lines(self.path)
                self._file = self.path.open()
        self._read(np.inf if self._file is None else 0.0)

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def _check_lines(self, path: Path) -> None:
        """Check every complete line the file holds now, before a run.

        Lines appended later are checked as they are read.
        """
        last_t = -np.inf
        for number, line in enumerate(path.read_text().splitlines(keepends=True), 1):
            if not line.endswith("\n") or not line.strip():
                continue
            where = f"line {number}"
            last_t = self._parse(self._json(line, number), where, last_t)[0]

    def _json(self, line: str, number: int) -> object:
        try:
            return json.loads(line)
        except RecursionError:
            raise InvalidInput(f"inputs file {self.path}:{number}: nested too deeply") \
                from None
        except json.JSONDecodeError as exc:
            raise InvalidInput(f"inputs file {self.path}:{number}: not JSON ({exc.msg})") \
                from None

    def _add(self, obj: object, where: str) -> None:
        t, values = self._parse(obj, where, self._last_t)
        self._last_t = t
        for key, arr in values.items():
            self._samples[key].append((t, arr))

    def _parse(self, obj: object, where: str, last_t: float
               ) -> tuple[float, dict[str, np.ndarray]]:
        """Return a sample's time and values, checked (see the class's errors)."""
        if not isinstance(obj, dict) or "t" not in obj:
            raise InvalidInput(f"inputs file {self.path}: {where}: expected an object with 't'")
        t = obj["t"]
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not np.isfinite(t):
            raise InvalidInput(f"inputs file {self.path}: {where}: 't' expected a finite "
                               f"time [s], got {t!r}")
        t = float(t)
        if t < last_t:
            raise InvalidInput(f"inputs file {self.path}: {where}: times must not decrease")
        values: dict[str, np.ndarray] = {}
        for key, value in obj.items():
            if key == "t":
                continue
            spec = self.specs.get(key)
            if spec is None:
                raise InvalidInput(f"inputs file {self.path}: {where}: unknown input {key!r}; "
                                   f"inputs: {', '.join(sorted(self.specs)) or 'none'}")
            try:
                arr = np.array(value, dtype=float)
            except (TypeError, ValueError):
                arr = np.full((0,), np.nan)  # not numbers: reported below
            if value is None or isinstance(value, (bool, str)) or arr.shape != spec.shape \
                    or not np.isfinite(arr).all():
                raise InvalidInput(f"inputs file {self.path}: {where}: {key} expected shape "
                                   f"{list(spec.shape)} of finite numbers, got {value!r}")
            values[key] = arr
        return t, values

    def _read(self, t: float) -> None:
        """Read lines until one lies beyond ``t`` (one sample ahead, for interpolation)."""
        while self._file is not None and self._last_t <= t:
            line = self._file.readline()
            if not line:
                return  # end for now: the file may grow
            if not line.endswith("\n"):
                self._pending += line
                return
            line, self._pending = self._pending + line, ""
            self._line += 1
            if not line.strip():
                continue
            self._add(self._json(line, self._line), f"line {self._line}")

    def value(self, name: str, t: float) -> np.ndarray:
        """Value of input ``name`` at simulated time ``t`` [s].

        Raises:
            InvalidInput: Unknown input, or no sample yet and no default.

        """
        if name not in self.specs:
            raise InvalidInput(f"unknown input {name!r}; inputs: {', '.join(sorted(self.specs))}")
        self._read(t)
        spec = self.specs[name]
        samples = self._samples[name]
        before = [s for s in samples if s[0] <= t]
        if not before:
            if spec.default is None:
                raise InvalidInput(f"input {name!r} has no default and no sample before t={t}")
            return spec.default.copy()
        t0, v0 = before[-1]
        if spec.interpolate and len(before) < len(samples):
            t1, v1 = samples[len(before)]
            if t1 > t0:
                s = (t - t0) / (t1 - t0)
                return (1 - s) * v0 + s * v1
        return v0.copy()

    def values(self, t: float) -> dict[str, np.ndarray]:
        """Every input's value at ``t``."""
        return {k: self.value(k, t) for k in self.specs}
