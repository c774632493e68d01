"""The ``hqp`` command line: the contracts' JSON of compare, run and bench end to end, errors.

The keys checked are those of docs/reference/contracts.md, the JSON sections; each
command runs in its own process, as the checks outside the repository call it, with the
shortest durations and sizes it accepts.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

import hqp.app.cli
from hqp.cli import build_parser, main

ENV = {**os.environ, "OMP_NUM_THREADS": "1"}


def _hqp(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hqp.cli", *args], capture_output=True,
                          text=True, env=ENV, timeout=300)


def test_bench_solver_quick_json():
    proc = _hqp("bench", "--suite", "solver", "--quick", "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)  # stdout holds the JSON object alone
    assert result["suite"] == "solver"
    for row in result["rows"]:
        assert {"robot", "solver", "levels", "n", "median_ms", "p95_ms"} <= set(row)
        assert row["robot"] is None
    assert {"basis/proxsuite", "cascade/proxsuite", "daqp-hier"} <= {
        r["solver"] for r in result["rows"]}


def test_bench_table_and_plot(tmp_path, capsys):
    assert main(["bench", "--suite", "solver", "--quick", "--plot", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "suite: solver" in out and "basis/proxsuite" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "bench_solver_2levels.png", "bench_solver_4levels.png"]


def test_unknown_suite_is_an_error(capsys):
    assert main(["bench", "--suite", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown suite 'nope'" in err and "solver" in err


def test_subcommands_are_registered():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert {"bench", "compare", "run", "behaviors"} <= set(sub.choices)


def test_a_subcommand_that_fails_to_import_fails_loudly(monkeypatch):
    def broken(subparsers):
        raise ImportError("No module named 'missing_dependency'")

    monkeypatch.setattr(hqp.app.cli, "SUBCOMMANDS", (*hqp.app.cli.SUBCOMMANDS, broken))
    with pytest.raises(ImportError, match="missing_dependency"):
        build_parser()


COMPARE_RUN_KEYS = {"controller", "hierarchy", "cog_error_max_mm", "cog_error_final_mm",
                    "hand_final_distance_cm", "joint_limit_violation_max_rad",
                    "step_time_median_ms", "fell", "realtime_factor", "contacts"}
RUN_KEYS = {"behavior", "robot", "duration_s", "fell", "phases", "steps", "feasibility_events",
            "max_torque_jump_nm", "realtime_factor"}
BENCH_ROW_KEYS = {"robot", "solver", "levels", "n", "median_ms", "p95_ms"}


def test_compare_end_to_end():
    proc = _hqp("compare", "hand-reach", "--json", "--duration", "0.02")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)  # stdout holds the JSON object alone
    assert result["scenario"] == "hand-reach" and result["robot"] == "paper-humanoid"
    for run in result["runs"]:
        assert COMPARE_RUN_KEYS <= set(run), COMPARE_RUN_KEYS - set(run)
        assert run["fell"] is False
        assert run["contacts"] == "unilateral" and run["realtime_factor"] > 0.0, run
    pairs = {(r["controller"], r["hierarchy"]) for r in result["runs"]}
    assert {(c, h) for c in ("hqp", "nullspace") for h in ("shared", "cog-first")} <= pairs
    assert _hqp("compare", "no-such-scenario", "--json").returncode == 2


def test_run_end_to_end():
    proc = _hqp("run", "stand", "--duration", "0.02", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert RUN_KEYS <= set(data), RUN_KEYS - set(data)
    assert data["behavior"] == "stand" and data["robot"] == "paper-humanoid"
    assert data["fell"] is False and data["phases"] == ["stand"] and data["steps"] == 0
    assert data["duration_s"] == pytest.approx(0.02)
    assert isinstance(data["feasibility_events"], list)
    assert data["realtime_factor"] > 0.0
    assert _hqp("run", "no-such-behavior", "--json").returncode == 2


def test_bench_end_to_end():
    proc = _hqp("bench", "--suite", "controller", "--quick", "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["suite"] == "controller" and result["rows"]
    for row in result["rows"]:
        assert BENCH_ROW_KEYS <= set(row), BENCH_ROW_KEYS - set(row)
        assert isinstance(row["robot"], str) and row["median_ms"] > 0
    assert any(r["solver"].startswith("hqp/") for r in result["rows"])
    # a configuration this machine cannot run (a peer without its environment) is not a row
    for entry in result["skipped"]:
        assert entry["solver"] in ("placo", "tsid"), entry
        assert f"python -m hqp.bench.peer_env {entry['solver']}" in entry["skipped"]


def test_behaviors_lists_the_library(capsys):
    assert main(["behaviors", "--json"]) == 0
    names = {b["name"] for b in json.loads(capsys.readouterr().out)["behaviors"]}
    assert {"stand", "walk", "squat-jump"} <= names


def test_run_with_a_backend_reports_it_and_the_torque_jump(capfd):
    # (capfd: `hqp run` keeps file descriptor 1 for the JSON, C libraries print elsewhere)
    assert main(["run", "stand", "--backend", "quadprog", "--duration", "0.03", "--json"]) == 0
    data = json.loads(capfd.readouterr().out)
    assert data["backend"] == "quadprog" and data["fell"] is False
    assert 0.0 <= data["max_torque_jump_nm"] < 1.0  # standing still: measured 0.01 N m


def test_run_with_an_unknown_backend_lists_the_valid_ones(capsys):
    assert main(["run", "stand", "--backend", "nope", "--duration", "0.01"]) == 2
    err = capsys.readouterr().err
    assert "unknown backend 'nope'" in err and "daqp" in err
