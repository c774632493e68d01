"""Studies on a local Ray instance: a small push map with 2 and with 1 worker, a killed worker.

One module fixture runs everything (Ray starts twice, about 7 s each): the push map of the
null-space law on paper-humanoid, 4 directions, bisection from 400 N to a 200 N bracket,
1 s runs (the robot falls 0.4-0.9 s after a push it does not survive: 0.6 s runs miss the
fall backwards with MuJoCo 4.0.1), with 2 workers;
the same study resumed from its records without one direction, with a task that kills its
worker on that direction's first simulation, then resumed again; a tiny grid over the noise
seed; the push map again with 1 worker.
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from hqp.app.cli import main
from hqp.study import RecordFile, connect, read_records, run_simulation, run_study, study_from_dict

pytestmark = pytest.mark.slow

# -- a cluster on loopback: a head and a second node joining it (in this file, so that no
# other Ray test runs beside it on another pytest worker)

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


PUSH_MAP = {"study": "push-map", "name": "tiny", "controllers": ["nullspace"], "duration": 1.0,
            "push": {"directions": 4, "max_force": 400.0, "tolerance": 200.0, "at": 0.02}}
KILLED = 90.0
"""The direction whose first simulation kills its worker."""


def killing(angle: float):
    """A study task that kills its own worker (SIGKILL) on the first probe of ``angle``."""

    def simulate(params, timeout, metrics):
        if params["push_angle_deg"] == angle and params["push_force"] == 400.0:
            os.kill(os.getpid(), signal.SIGKILL)
        return run_simulation(params, timeout, metrics)

    return simulate


def deterministic(records: list[dict]) -> dict[str, tuple]:
    """What must not depend on the workers: params, status, metrics, by simulation id."""
    return {r["id"]: (r["params"], r["status"], r["metrics"], r["group"], r["probe"])
            for r in records}


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict:
    tmp = tmp_path_factory.mktemp("study")
    study = study_from_dict(PUSH_MAP)
    out: dict = {"tmp": tmp}
    for workers in (2, 1):
        ray = connect(workers=workers)
        try:
            path = tmp / f"workers{workers}.jsonl"
            start = time.perf_counter()
            out[workers] = run_study(study, RecordFile(path), ray)
            out[f"wall{workers}"] = time.perf_counter() - start
            out[f"records{workers}"] = read_records(path)
            if workers == 2:
                # resume without the killed direction's records, its worker killed
                resumed = tmp / "killed.jsonl"
                kept = [r for r in out["records2"] if r["params"]["push_angle_deg"] != KILLED]
                resumed.write_text("".join(json.dumps(r) + "\n" for r in kept))
                out["killed"] = run_study(study, RecordFile(resumed, resume=True), ray,
                                          simulate=killing(KILLED))
                out["killed_records"] = read_records(resumed)
                out["healed"] = run_study(study, RecordFile(resumed, resume=True), ray)
                out["healed_records"] = read_records(resumed)
                grid = study_from_dict({
                    "study": "grid", "name": "seeds", "controllers": ["nullspace"],
                    "duration": 0.05, "fixed": {"noise_q_std": 2e-3, "noise_v_std": 2e-2},
                    "grid": {"seed": [0, 1]}})
                out["grid"] = run_study(grid, RecordFile(tmp / "grid.jsonl"), ray)
                out["grid_records"] = read_records(tmp / "grid.jsonl")
        finally:
            ray.shutdown()
    return out


def test_push_map_records(runs) -> None:
    summary, records = runs[2], runs["records2"]
    assert summary["cpus"] == 2 and summary["failed"] == 0
    assert len(records) == summary["simulations"] == summary["ran"]  # one per simulation
    assert len({r["id"] for r in records}) == len(records)
    assert {r["params"]["push_angle_deg"] for r in records} == {0.0, 90.0, 180.0, 270.0}
    assert all(r["status"] == "ok" and r["study"] == "tiny" for r in records)
    assert len({r["worker"] for r in records}) >= 2  # both workers ran simulations
    by_id = {r["id"]: r for r in records}
    rows = summary["directions"]
    assert [r["angle_deg"] for r in rows] == [0.0, 90.0, 180.0, 270.0]
    for row in rows:
        assert row["status"] == "done" and row["probes"] <= 3
        mine = [r for r in records if r["group"] == f"nullspace/{row['angle_deg']:g}"]
        assert [r["probe"] for r in mine] == list(range(row["probes"]))
        assert mine[0]["params"]["push_force"] == 400.0  # the search starts at the top
        # the largest survived force is bracketed by a survived and a fallen run
        survived, fallen = by_id[row["survived_id"]], by_id[row["fallen_id"]]
        assert survived["metrics"]["fell"] is False and fallen["metrics"]["fell"] is True
        assert survived["params"]["push_force"] == row["largest_survived_n"]
        assert fallen["params"]["push_force"] == row["smallest_fallen_n"]
        assert 0.0 < row["smallest_fallen_n"] - row["largest_survived_n"] <= 200.0
        assert all(r["metrics"]["fell"] is (r["params"]["push_force"] >= row["smallest_fallen_n"])
                   for r in mine)


def test_a_killed_worker_is_reported_then_resumed(runs) -> None:
    killed, records = runs["killed"], runs["killed_records"]
    assert killed["ran"] == 1 and killed["failed"] == 1
    assert killed["reused"] == len(runs["records2"]) - sum(
        r["params"]["push_angle_deg"] == KILLED for r in runs["records2"])
    crashed = [r for r in records if r["status"] != "ok"]
    assert len(crashed) == 1 and crashed[0]["status"] == "crashed"
    assert crashed[0]["params"]["push_angle_deg"] == KILLED
    assert crashed[0]["params"]["push_force"] == 400.0
    assert "died" in crashed[0]["error"] and crashed[0]["command"].startswith("hqp sweep --one")
    row = next(r for r in killed["directions"] if r["angle_deg"] == KILLED)
    assert row["status"] == "failed" and row["errors"][0].startswith("crashed:")
    # resumed: the crashed simulation and the rest of its direction run, nothing else
    healed = runs["healed"]
    assert healed["failed"] == 0 and healed["ran"] == next(
        r["probes"] for r in runs[2]["directions"] if r["angle_deg"] == KILLED)
    assert healed["directions"] == runs[2]["directions"]
    latest = {r["id"]: r for r in runs["healed_records"]}
    assert deterministic(latest.values()) == deterministic(runs["records2"])


def test_one_and_two_workers_give_identical_results(runs) -> None:
    assert runs[1]["cpus"] == 1
    assert runs[1]["directions"] == runs[2]["directions"]
    assert deterministic(runs["records1"]) == deterministic(runs["records2"])
    ratio = runs["wall1"] / runs["wall2"]
    print(f"\npush map of {runs[2]['simulations']} simulations: 1 worker {runs['wall1']:.1f} s, "
          f"2 workers {runs['wall2']:.1f} s, ratio {ratio:.2f}")


def test_a_record_reruns_alone_with_its_command(runs, capfd) -> None:
    records = runs["grid_records"]
    assert len(records) == 2 and all(r["status"] == "ok" for r in records)
    assert records[0]["metrics"] != records[1]["metrics"]  # the seed reaches the noise
    record = next(r for r in records if r["params"]["seed"] == 1)
    argv = shlex.split(record["command"])
    assert argv[:2] == ["hqp", "sweep"]
    capfd.readouterr()
    assert main(argv[1:]) == 0
    again = json.loads(capfd.readouterr().out)
    assert again["id"] == record["id"] and again["metrics"] == record["metrics"]
