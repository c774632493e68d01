"""The pipe client of the peers' worker processes (PlaCo, TSID).

A peer that cannot share hqp's environment (:mod:`hqp.bench.peer_env`) runs a worker script
(:mod:`hqp.bench.placo_worker`, :mod:`hqp.bench.tsid_worker`) with its own environment's
interpreter. The script imports nothing of hqp; it reads one JSON object per line on stdin
and writes one JSON reply per line on stdout (``{"ok": true, ...}`` or ``{"ok": false,
"error": "<type>: <message>"}``). Every worker answers ``{"op": "hello"}`` (before anything
else: a worker that dies before answering it has an environment that cannot run it) and
``{"op": "quit"}``.

The worker runs isolated (``python -I``: no ``PYTHONPATH``, no user site, not the script's
folder on ``sys.path``) with one BLAS/OpenMP thread, as every configuration of the
benchmarks; its stderr goes to a temporary file (a pipe left unread could fill up and block
it), whose last line names the cause when it dies.
"""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from hqp.bench.peer_env import PeerUnavailable, env_python, peer
from hqp.errors import HQPError

__all__ = ["PeerUnavailable", "Worker", "WorkerError", "start"]

THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""Set to 1 in the worker's environment: one thread, as every configuration of the suites."""


class WorkerError(HQPError):
    """The worker answered a request with an error, or died."""


class Worker:
    """A worker process speaking the JSON-lines protocol (module docstring).

    Args:
        command: The worker's command line (interpreter and script).
        cwd: Its working directory (not the project's: a peer's interpreter must not see hqp).

    """

    def __init__(self, command: list[str], cwd: str | None = None) -> None:
        env = dict(os.environ)
        env.update({k: "1" for k in THREAD_VARIABLES})
        self.errors = tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self.errors, text=True, bufsize=1, cwd=cwd,
                                     env=env)
        self.round_trip: list[float] = []
        """Wall-clock time of each request, from sending it to reading its reply [s]."""

    def request(self, payload: dict[str, Any]) -> dict[str, Any]:
        """Send one request, return its reply.

        Raises:
            WorkerError: An error reply, or the worker closed its output.

        """
        if self.proc.stdin is None or self.proc.stdout is None:
            raise WorkerError("worker has no pipes")
        start = time.perf_counter()
        try:
            self.proc.stdin.write(json.dumps(payload) + "\n")
            self.proc.stdin.flush()
        except (BrokenPipeError, ValueError):  # ValueError: the pipe was closed
            raise WorkerError(f"worker died: {self.stderr_tail()}") from None
        line = self.proc.stdout.readline()
        self.round_trip.append(time.perf_counter() - start)
        if not line:
            raise WorkerError(f"worker died: {self.stderr_tail()}")
        try:
            reply = json.loads(line)
        except json.JSONDecodeError:
            raise WorkerError(f"worker wrote something else than a reply: {line[:200]!r}"
                              ) from None
        if not reply.get("ok"):
            raise WorkerError(f"worker: {reply.get('error')}")
        return reply

    def stderr_tail(self) -> str:
        """Last line the worker wrote on stderr (its exit status if none), once it has ended."""
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            return "no reply (the worker is still running)"
        self.errors.seek(0)
        lines = self.errors.read().strip().splitlines()
        return lines[-1] if lines else f"exit {self.proc.returncode}"

    def close(self) -> None:
        """Ask the worker to quit and wait for it (killed after 10 s)."""
        if self.proc.poll() is None:
            try:
                self.request({"op": "quit"})
            except (WorkerError, OSError):
                pass
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for stream in (self.proc.stdin, self.proc.stdout):
            if stream is not None:
                try:
                    stream.close()
                except OSError:  # a request the dead worker never read was still buffered
                    pass
        self.errors.close()


def start(name: str, script: Path, python: Path | None = None) -> Worker:
    """Start a peer's worker script with its environment's interpreter and greet it.

    Args:
        name: The peer (``placo``, ``tsid``; :data:`hqp.bench.peer_env.PEERS`).
        script: The worker script.
        python: The interpreter (default: the peer's environment's,
            :func:`hqp.bench.peer_env.env_python`).

    Raises:
        PeerUnavailable: No interpreter there, or the worker died before answering ``hello``
            (its environment cannot import the peer); the message says how to make it.

    """
    p = peer(name)
    python = python or env_python(name)
    if not python.is_file():
        raise PeerUnavailable(f"no {p.title} environment at {python.parent.parent} "
                              f"(create it with: {p.command})")
    worker = Worker([str(python), "-I", str(script)], cwd=str(python.parent))
    try:
        worker.request({"op": "hello"})
    except WorkerError as exc:
        worker.close()
        raise PeerUnavailable(f"{p.title} environment at {python.parent.parent} cannot run "
                              f"its worker ({exc}; re-create it with: {p.command})") from None
    return worker


def start_setup(name: str, script: Path, setup: dict[str, Any],
                python: Path | None = None) -> tuple[Worker, dict[str, Any]]:
    """Start a peer's worker (:func:`start`) and send it its ``setup`` request.

    Returns:
        The worker and the setup's reply; the worker is closed if the setup fails.

    Raises:
        PeerUnavailable: As :func:`start`.
        WorkerError: The setup request failed (the worker's message).

    """
    worker = start(name, script, python)
    try:
        return worker, worker.request(setup)
    except Exception:
        worker.close()
        raise
