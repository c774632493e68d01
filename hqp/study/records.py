"""A study's results file: JSON Lines, one record per simulation, written as each finishes.

Each line is the record of :func:`hqp.study.simulation.run_simulation` plus the study's
annotations (``study``, ``group``, ``probe`` of a push map, ``swept`` values of a grid,
``finished_at``). Lines are flushed one by one, so a study stopped at any point leaves a
file whose complete lines are results; a torn last line (a killed driver) is skipped on
reading. Resuming reads the file back (:meth:`RecordFile.finished`): the latest record of
each simulation id counts.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import IO, Any

from hqp.errors import InvalidInput

logger = logging.getLogger(__name__)


def read_records(path: str | Path) -> list[dict[str, Any]]:
    """Return the records of a results file, in file order (torn lines skipped).

    Raises:
        InvalidInput: The file cannot be read.

    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise InvalidInput(f"results file {path}: {exc.strerror}") from None
    records = []
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            logger.warning("%s:%d: not a complete JSON record, skipped", path, number)
            continue
        if isinstance(record, dict) and "id" in record and "status" in record:
            records.append(record)
    return records


class RecordFile:
    """The results file of a running study (append, flush per record).

    Args:
        path: The JSON Lines file.
        resume: Keep the records already there (else the file must not exist, unless
            ``overwrite``).
        overwrite: Start the file anew.

    Raises:
        InvalidInput: The file exists and neither ``resume`` nor ``overwrite`` is set.

    """

    def __init__(self, path: str | Path, *, resume: bool = False,
                 overwrite: bool = False) -> None:
        self.path = Path(path)
        self.previous: list[dict[str, Any]] = []
        if self.path.exists():
            if resume:
                self.previous = read_records(self.path)
            elif not overwrite:
                raise InvalidInput(f"results file {self.path} exists: pass --resume to reuse "
                                   f"its results or --overwrite to start again")
        elif resume:
            logger.info("%s does not exist: nothing to resume, starting the study", self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: IO[str] | None = None
        self._mode = "a" if resume else "w"

    def finished(self) -> dict[str, dict[str, Any]]:
        """Return the previous records that succeeded, by simulation id (the latest wins)."""
        latest: dict[str, dict[str, Any]] = {}
        for record in self.previous:
            latest[record["id"]] = record
        return {k: r for k, r in latest.items() if r["status"] == "ok"}

    def write(self, record: dict[str, Any]) -> None:
        """Append one record and flush it to disk."""
        if self._file is None:
            torn = self._mode == "a" and self._torn()
            self._file = self.path.open(self._mode, encoding="utf-8")
            if torn:  # a killed writer's last line: the next record starts a line of its own
                self._file.write("\n")
        self._file.write(json.dumps(record, sort_keys=True) + "\n")
        self._file.flush()

    def _torn(self) -> bool:
        """Whether the file exists and does not end with a newline."""
        if not self.path.exists() or self.path.stat().st_size == 0:
            return False
        with self.path.open("rb") as f:
            f.seek(-1, 2)
            return f.read(1) != b"\n"

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None
