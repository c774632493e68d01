"""The ``hqp`` command line: bench subcommand, JSON on stdout alone, errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys

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
    assert "bench" in sub.choices


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
