"""The benchmark method, the suite registry, the report and the daqp-hier peer."""

from __future__ import annotations

import time

import numpy as np
import pytest

import hqp
from hqp.bench import get_suite, measure, register_suite, run_suite, suite_names
from hqp.bench.daqp_hier import daqp_hierarchy_data, solve_daqp_hierarchy
from hqp.bench.problems import LevelSpec, random_hierarchy, reference_specs
from hqp.bench.report import format_table, write_plots
from hqp.solver import Level, solve


def test_measure_settles_on_a_steady_call():
    timing = measure(lambda: time.sleep(0.001), warmup=1, batch=5, min_reps=10, budget_s=2.0)
    assert timing.reps >= 10
    assert 0.9 <= timing.median_ms <= 20.0
    assert timing.p95_ms >= timing.median_ms


def test_measure_stops_at_the_budget():
    start = time.perf_counter()
    timing = measure(lambda: time.sleep(0.01), warmup=0, batch=3, min_reps=1000,
                     budget_s=0.05)
    assert time.perf_counter() - start < 1.0
    assert 3 <= timing.reps < 1000
    assert not timing.settled


def test_registry():
    assert {"solver", "controller", "recorded"} <= set(suite_names())

    @register_suite("unit-test-suite")
    def _suite(quick: bool = False, progress=None):
        return [{"robot": None, "solver": "x", "levels": 1, "n": 2, "median_ms": 1.0,
                 "p95_ms": 2.0}]

    result = run_suite("unit-test-suite", quick=True)
    assert result == {"suite": "unit-test-suite", "rows": _suite(), "skipped": []}
    skipped = {"robot": "g1", "solver": "tsid", "levels": 1, "n": 2, "median_ms": None,
               "p95_ms": None, "skipped": "no environment"}
    register_suite("unit-test-skip")(lambda quick=False, progress=None: _suite() + [skipped])
    assert run_suite("unit-test-skip") == {"suite": "unit-test-skip", "rows": _suite(),
                                           "skipped": [skipped]}
    with pytest.raises(hqp.UnknownName, match="unknown suite 'nope'.*solver"):
        get_suite("nope")


def test_report_table_and_plots(tmp_path):
    result = {"suite": "solver", "rows": [
        {"robot": None, "solver": "basis/proxsuite", "levels": 2, "n": 20, "median_ms": 0.5,
         "p95_ms": 0.7, "speedup_vs_cascade": 3.2},
        {"robot": None, "solver": "cascade/proxsuite", "levels": 2, "n": 20, "median_ms": 1.6,
         "p95_ms": 2.0},
    ]}
    table = format_table(result)
    assert "basis/proxsuite" in table and "median [ms]" in table and "3.2" in table
    paths = write_plots(result, tmp_path)
    assert [p.name for p in paths] == ["bench_solver_2levels.png"]
    assert paths[0].stat().st_size > 0


def test_daqp_hierarchy_peer_on_a_planted_problem():
    # level 0: x0 <= 1; level 1: x0 = 2, x1 = 3: DAQP's hierarchy finds (1, 3) too
    levels = [Level(C=[[1.0, 0.0]], upper=[1.0]), Level(A=np.eye(2), b=[2.0, 3.0])]
    x, flag = solve_daqp_hierarchy(daqp_hierarchy_data(levels))
    assert flag > 0
    np.testing.assert_allclose(x, [1.0, 3.0], atol=1e-6)


def test_daqp_hierarchy_normalises_rows():
    # one level, two conflicting rows of different norms: DAQP weighs them by 1/||a||^2,
    # the contract does not, so the two optima differ
    levels = [Level(A=[[1.0], [10.0]], b=[0.0, 10.0])]
    x, _ = solve_daqp_hierarchy(daqp_hierarchy_data(levels))
    contract = solve(levels).x
    np.testing.assert_allclose(contract, [100.0 / 101.0], atol=1e-9)
    np.testing.assert_allclose(x, [0.5], atol=1e-5)


def test_random_hierarchies_have_the_requested_shapes():
    rng = np.random.default_rng(0)
    levels = random_hierarchy(rng, 40, reference_specs(40))
    assert len(levels) == 4
    assert levels[0].A.shape == (5, 40) and levels[0].C is None
    assert levels[1].C.shape == (20, 40) and levels[1].lower is not None
    assert levels[3].lower is None and levels[3].upper is not None
    assert np.linalg.matrix_rank(levels[3].A) < levels[3].A.shape[0]
    sol = solve(random_hierarchy(rng, 12, [LevelSpec(m_eq=4), LevelSpec(m_eq=4,
                                                                          conflicting=True)]))
    assert sol.levels[0].satisfied and not sol.levels[1].satisfied


def test_solver_suite_quick_rows():
    rows = run_suite("solver", quick=True)["rows"]
    names = {r["solver"] for r in rows}
    assert {"basis/proxsuite", "cascade/proxsuite", "daqp-hier"} <= names
    for r in rows:
        assert r["robot"] is None
        assert r["n"] == 20 and r["levels"] in (2, 4)
        assert r["median_ms"] > 0 and r["p95_ms"] >= r["median_ms"]
        if r["solver"] != "daqp-hier":
            assert r["exact"], r
    basis = [r for r in rows if r["solver"].startswith("basis/")]
    assert all("speedup_vs_cascade" in r for r in basis)
