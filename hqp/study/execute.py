"""A study on Ray: every simulation one task, results streamed to the records file.

:func:`connect` starts a local Ray instance (``ray.init()`` on this machine, ``workers``
CPUs, its processes on the loopback interface, workers at nice 0 rather than Ray's 15, no
usage statistics sent) or joins an
existing cluster (``address``). :func:`run_study` submits the simulations a plan hands out
(:class:`~hqp.study.pushmap.PushMapPlan`, :class:`~hqp.study.grid.GridPlan`) as Ray tasks
of one CPU each, waits for them as they finish (:func:`ray.wait`), writes each record at
once and feeds it back to the plan (a push map's next probe of that direction). Failures are
records too: an exception or a timeout inside the simulation (``"error"``, ``"timeout"``),
and a worker that died under it (``"crashed"``, Ray's error). Ray never retries a task
(``max_retries=0``): a study is resumed, explicitly, from its records file, where every
simulation already finished with ``"ok"`` is reused and the others are run again.
"""

from __future__ import annotations

import datetime
import importlib
import logging
import os
import socket
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any, Protocol

from hqp.errors import HQPError, InvalidInput
from hqp.study.grid import GridPlan
from hqp.study.pushmap import PushMapPlan
from hqp.study.records import RecordFile
from hqp.study.simulation import STANDING_METRICS, check_params, rerun_command, run_simulation
from hqp.study.spec import Params, Study, simulation_id

logger = logging.getLogger(__name__)

RAY_MISSING = ("hqp sweep runs its simulations on Ray, which is not installed: "
               "pip install 'hqp[cluster]' (or pip install ray)")
"""The message when Ray cannot be imported."""


class RayUnavailable(HQPError):
    """Ray is not installed (:data:`RAY_MISSING`)."""


class ClusterUnreachable(HQPError):
    """``--address`` names no Ray cluster this machine can join (the message says why)."""


CONNECT_TIMEOUT_S = 5.0
"""How long :func:`connect` waits for a cluster's head to accept a connection [s]."""


def parse_address(address: str) -> tuple[str, int]:
    """Return ``(host, port)`` of a cluster address ``HOST:PORT`` (``ray start --head``'s).

    Raises:
        ClusterUnreachable: Not ``HOST:PORT`` with a port in 1..65535.

    """
    host, sep, port = address.strip().rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ClusterUnreachable(f"--address {address!r}: expected HOST:PORT, the address "
                                 "`ray start --head` prints (e.g. 10.0.0.5:6379)")
    return host, int(port)


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Check that a Ray head accepts connections at ``address`` (before Ray tries for minutes).

    Raises:
        ClusterUnreachable: Malformed address, unknown host, or nothing listening there.

    """
    host, port = parse_address(address)
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        if isinstance(exc, TimeoutError):
            why = f"no answer within {timeout:g} s"
        else:
            why = exc.strerror or type(exc).__name__
        raise ClusterUnreachable(
            f"no Ray cluster at {host}:{port} ({why}); start its head with "
            f"`ray start --head --port={port}` or give the address it printed") from None


def _worker_env() -> dict[str, Any]:
    """Return the runtime environment of a cluster's workers: hqp importable from here.

    Nodes that have hqp installed import theirs; a node sharing this machine's files (the
    same machine, or a shared file system) also finds a source checkout run without
    installing it (``PYTHONPATH``).
    """
    here = str(Path(__file__).resolve().parents[2])
    paths = [here] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
                      if p and p != here]
    return {"env_vars": {"PYTHONPATH": os.pathsep.join(paths)}}


class Plan(Protocol):
    """What :func:`run_study` drives: the simulations of a study, as they become ready."""

    def first_params(self) -> list[Params]:
        """Return the params to check before anything runs."""

    def ready(self) -> list[tuple[Params, dict[str, Any]]]:
        """Return the simulations that can start now, each with its record's annotations."""

    def feed(self, record: dict[str, Any]) -> None:
        """Take a finished simulation's record."""

    def expected(self) -> int:
        """Return the number (or an upper bound) of simulations."""

    def summary(self) -> dict[str, Any]:
        """Return the study's result."""


def make_plan(study: Study) -> PushMapPlan | GridPlan:
    """Return the plan of a study, its first simulations' params checked.

    Raises:
        HQPError: A simulation's params are invalid (nothing has run).

    """
    plan: PushMapPlan | GridPlan = (PushMapPlan(study) if study.kind == "push-map"
                                    else GridPlan(study))
    for params in plan.first_params():
        check_params(params)
    if study.metrics and study.fixed.get("target", "standing") == "standing":
        unknown = sorted(set(study.metrics) - set(STANDING_METRICS))
        if unknown:
            raise InvalidInput(f"study: unknown metrics {unknown} (a standing simulation "
                               f"measures {list(STANDING_METRICS)})")
    return plan


def connect(address: str | None = None, workers: int | None = None) -> ModuleType:
    """Start a local Ray instance or join a cluster, and return the ``ray`` module.

    Args:
        address: A running cluster's address (``ray start --head`` prints it; ``"auto"``
            for the cluster of this node). ``None``: a new local instance.
        workers: CPUs of the local instance (default: every core of the machine).

    Raises:
        RayUnavailable: Ray is not installed.
        ClusterUnreachable: ``address`` is malformed, nothing answers there, or Ray could not
            join it (a missing authentication token, say): one line, before any simulation.

    """
    if address is None:
        # a local instance on the loopback interface (read when Ray is imported), no
        # usage statistics, workers at the machine's usual priority (Ray's default, nice 15,
        # starves the simulations on a machine shared with other work)
        os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        os.environ.setdefault("RAY_worker_niceness", "0")
    try:
        ray = importlib.import_module("ray")
    except ImportError:
        raise RayUnavailable(RAY_MISSING) from None
    if ray.is_initialized():
        return ray
    if address is None:
        # address="local": a new instance on this machine, never a cluster Ray finds on its
        # own (RAY_ADDRESS, or the address file a `ray start` leaves in /tmp/ray)
        ray.init(address="local", num_cpus=workers or os.cpu_count() or 1,
                 include_dashboard=False, log_to_driver=False, configure_logging=False)
    else:
        check_reachable(address)
        try:
            ray.init(address=address, log_to_driver=False, configure_logging=False,
                     runtime_env=_worker_env())
        except (ConnectionError, RuntimeError, ValueError) as exc:
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            auth = "auth" in str(exc).lower() or "token" in str(exc).lower()
            hint = ("; the cluster requires its token: set RAY_AUTH_TOKEN (or copy "
                    "~/.ray/auth_token from the head, see `ray get-auth-token`)" if auth else "")
            raise ClusterUnreachable(f"could not join the Ray cluster at {address}: "
                                     f"{first}{hint}") from None
    return ray


def _crashed(params: Params, exc: BaseException) -> dict[str, Any]:
    """Return the record of a simulation whose worker died (or whose task Ray lost)."""
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return {"id": simulation_id(params), "params": dict(params), "status": "crashed",
            "metrics": {}, "timing": {}, "error": f"{type(exc).__name__}: {first}",
            "worker": None, "command": rerun_command(params)}


def run_study(
    study: Study,
    records: RecordFile,
    ray: ModuleType,
    *,
    simulate: Callable[..., dict[str, Any]] = run_simulation,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Run a study on Ray and return its summary (the JSON of ``hqp sweep``).

    Args:
        study: The study.
        records: Its results file (records already there with ``"ok"`` are reused).
        ray: The ``ray`` module, initialised (:func:`connect`).
        simulate: The task: ``simulate(params, timeout, metrics) -> record``
            (:func:`~hqp.study.simulation.run_simulation`).
        progress: Called as ``progress(done, expected)`` after each simulation.

    Returns:
        ``{"study", "name", "records", "simulations", "ran", "reused", "failed",
        "wall_s", "cpus", "definition", ...}`` plus the plan's summary (a push map's
        ``directions``, a grid's ``rows``).

    """
    start = time.perf_counter()
    plan = make_plan(study)
    task = ray.remote(num_cpus=1, max_retries=0)(simulate)
    cached = records.finished()
    pending: dict[Any, tuple[Params, dict[str, Any]]] = {}
    ran = reused = failed = 0

    def step() -> None:
        if progress is not None:
            progress(ran + reused, max(plan.expected(), ran + reused))

    while True:
        batch = plan.ready()
        while batch:  # reused records advance their chains at once
            for params, notes in batch:
                previous = cached.get(simulation_id(params))
                if previous is not None:
                    plan.feed({**previous, **notes})
                    reused += 1
                    step()
                else:
                    pending[task.remote(params, study.timeout, study.metrics)] = (params, notes)
            batch = plan.ready()
        if not pending:
            break
        done, _ = ray.wait(list(pending), num_returns=1)
        for ref in done:
            params, notes = pending.pop(ref)
            try:
                record = ray.get(ref)
            except ray.exceptions.RayError as exc:  # the worker died, or Ray lost the task
                record = _crashed(params, exc)
            record.update(notes, study=study.name, finished_at=datetime.datetime.now(
                datetime.timezone.utc).isoformat(timespec="seconds"))
            if record["status"] != "ok":
                failed += 1
                logger.warning("simulation %s %s: %s", record["id"], record["status"],
                               record["error"])
            records.write(record)
            plan.feed(record)
            ran += 1
            step()
    records.close()
    resources = ray.cluster_resources()
    return {
        "study": study.kind, "name": study.name, "records": str(records.path),
        "simulations": ran + reused, "ran": ran, "reused": reused, "failed": failed,
        "wall_s": round(time.perf_counter() - start, 3),
        "cpus": int(resources.get("CPU", 0)), "definition": study.as_dict(),
        **plan.summary(),
    }
