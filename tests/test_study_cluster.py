"""``hqp sweep --address``: a cluster joined as a user would (slow).

A head started by the test on the loopback interface (no CPUs of its own) and a second node
joining it as the worker node (one CPU), both with ``ray start``; a small grid run through
``hqp sweep --address 127.0.0.1:PORT`` in a fresh process, so its simulations can only run
on the joined node. An address where no cluster answers is one line and exit status 2, before
any simulation.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

RAY = Path(sys.executable).with_name("ray")
ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def environment() -> dict[str, str]:
    # one authentication mode for the head, the worker node and the driver: a local Ray
    # instance (tests/test_study_ray.py) leaves a token in ~/.ray, which a head started
    # afterwards requires of nodes that do not know they should send it
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0", OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1", RAY_AUTH_MODE="disabled")
    env.pop("PYTHONPATH", None)  # the nodes do not see hqp: the driver hands it over
    return env


def stop(tag: str) -> None:
    """Stop the processes of the test's nodes (their command lines name its temp dir)."""
    listed = subprocess.run(["pgrep", "-f", tag], capture_output=True, text=True).stdout.split()
    for pid in map(int, listed):
        if pid != os.getpid():
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


@pytest.fixture(scope="module")
def cluster():
    if not RAY.exists():
        pytest.skip("the ray command is not installed")
    temp = tempfile.mkdtemp(prefix="hqpray", dir="/tmp")  # (Ray's socket paths must be short)
    port = free_port()
    env = environment()
    common = ["--temp-dir", temp, "--disable-usage-stats"]
    try:
        subprocess.run([str(RAY), "start", "--head", "--node-ip-address=127.0.0.1",
                        f"--port={port}", "--num-cpus=0", "--include-dashboard=false", *common],
                       env=env, check=True, capture_output=True, timeout=180)
        # the head may still be coming up: the worker node's join is tried a few times
        for attempt in range(4):
            joined = subprocess.run([str(RAY), "start", f"--address=127.0.0.1:{port}",
                                     "--node-ip-address=127.0.0.1", "--num-cpus=1", *common],
                                    env=env, capture_output=True, text=True, timeout=180)
            if joined.returncode == 0:
                break
            time.sleep(3.0)
        else:
            pytest.fail(f"the worker node could not join the head: {joined.stderr[-1500:]}")
        yield f"127.0.0.1:{port}"
    finally:
        stop(temp)
        time.sleep(1.0)
        shutil.rmtree(temp, ignore_errors=True)


def sweep(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = dict(environment(), PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "hqp.cli", "sweep", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def test_a_grid_runs_on_the_joined_node(cluster, tmp_path: Path) -> None:
    out = tmp_path / "grid.jsonl"
    done = sweep("grid", "--param", "duration=0.1,0.15", "--out", str(out),
                 "--address", cluster, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    summary = json.loads(done.stdout)
    assert summary["ran"] == 2 and summary["failed"] == 0
    assert summary["cpus"] == 1  # the worker node's CPU: the head has none
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert sorted(r["status"] for r in records) == ["ok", "ok"]
    assert all(r["metrics"]["duration_s"] > 0.09 for r in records)


def test_an_unreachable_cluster_is_one_line_before_any_simulation(tmp_path: Path) -> None:
    out = tmp_path / "none.jsonl"
    start = time.perf_counter()
    done = sweep("grid", "--param", "duration=0.1", "--out", str(out),
                 "--address", f"127.0.0.1:{free_port()}", cwd=tmp_path)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hqp: error: no Ray cluster at 127.0.0.1:")
    assert "Traceback" not in done.stderr
    assert not out.exists() or not out.read_text().strip()  # nothing ran
    assert time.perf_counter() - start < 60.0
    bad = sweep("grid", "--param", "duration=0.1", "--address", "cluster", cwd=tmp_path)
    assert bad.returncode == 2 and "expected HOST:PORT" in bad.stderr
