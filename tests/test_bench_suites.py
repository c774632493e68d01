"""Benchmark suites on real control problems: recorded files, peers, accuracy, quick runs.

Quick modes only; no assertion on a measured time.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hqp.bench.accuracy import excess, level_costs, relative_excess, tightest
from hqp.bench.interleave import interleaved
from hqp.bench.peers import DaqpHierarchy, law_to_x, nullspace_law_x
from hqp.bench.recorded import DATA_DIR, RecordingError, available, capture, load, save
from hqp.solver import Level, solve


@pytest.fixture(scope="module")
def stepped_controller():
    """A standing HQP controller on paper-humanoid after a few steps."""
    from hqp.controller import standing_controller
    from hqp.model import RobotState
    from hqp.robots import load as load_robot

    robot = load_robot("paper-humanoid")
    ctrl = standing_controller(robot, backend="daqp", diagnostics="residuals")
    rng = np.random.default_rng(3)
    v = np.zeros(ctrl.model.nv)
    v[6:] = rng.normal(0.0, 0.05, ctrl.model.nv - 6)
    for k in range(3):
        t = 1.0 + 1e-3 * k
        ctrl.step(RobotState(robot.q_standing.copy(), v, t), t)
    return ctrl


def test_capture_save_load_round_trip(stepped_controller, tmp_path):
    ctrl = stepped_controller
    step = capture(ctrl, "stand", "paper-humanoid", 1.002)
    path = save(tmp_path / "stand_test.npz", [step, step], duration=1.0)
    back = load(path)
    assert len(back) == 2
    b = back[0]
    assert (b.source, b.robot, b.n, b.nv) == ("stand", "paper-humanoid", ctrl.layout.n,
                                               ctrl.model.nv)
    assert len(b.levels) == len(ctrl.last_built.levels)
    for lv, orig in zip(b.levels, ctrl.last_built.levels):
        assert lv.name == orig.name
        for f in ("A", "b", "C", "lower", "upper"):
            o = getattr(orig, f)
            if o is None:
                assert getattr(lv, f) is None
            else:
                np.testing.assert_array_equal(getattr(lv, f), np.asarray(o, dtype=float))
    np.testing.assert_array_equal(b.M, ctrl.model.M)
    # the replayed levels give the controller's solution (same solver, same numbers)
    x = solve(list(b.levels), backend="daqp").x
    np.testing.assert_allclose(x, solve(list(ctrl.last_built.levels), backend="daqp").x,
                               rtol=0, atol=1e-9)


def test_load_rejects_missing_and_foreign_files(tmp_path):
    with pytest.raises(RecordingError, match="not found"):
        load(tmp_path / "nope.npz")
    np.savez(tmp_path / "foreign.npz", a=np.zeros(3))
    with pytest.raises(RecordingError, match="meta"):
        load(tmp_path / "foreign.npz")


def test_shipped_recordings_are_compact_and_consistent():
    files = available()
    assert files, f"no recorded problem files in {DATA_DIR}"
    total = sum(p.stat().st_size for p in files)
    assert total < 5e6, f"recorded files take {total / 1e6:.1f} MB"
    sources = set()
    for p in files:
        steps = load(p)
        assert steps
        for s in steps:
            sources.add(s.source)
            assert s.M.shape == (s.nv, s.nv)
            assert s.S.shape == (s.nv - 6, s.nv)
            for lv in s.levels:
                for m in (lv.A, lv.C):
                    if m is not None:
                        assert m.shape[1] == s.n
    assert {"hand-reach", "stand"} <= sources


def test_level_costs_match_a_direct_computation():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(3, 4))
    b = rng.normal(size=3)
    C = rng.normal(size=(2, 4))
    lo = np.array([-np.inf, 0.5])
    up = np.array([0.1, np.inf])
    x = rng.normal(size=4)
    cx = C @ x
    viol = np.array([max(cx[0] - 0.1, 0.0), min(cx[1] - 0.5, 0.0)])
    expected = [float(np.sum((A @ x - b) ** 2)), float(np.sum(viol**2))]
    got = level_costs([Level(A=A, b=b), Level(C=C, lower=lo, upper=up)], x)
    np.testing.assert_allclose(got, expected, rtol=1e-14)


def test_tightest_is_the_lexicographic_minimum_and_excess_is_measured_against_it():
    costs = {"a": np.array([0.0, 2.0, 5.0]), "b": np.array([0.0, 1.0, 9.0]),
             "c": np.array([1.0, 0.0, 0.0])}
    np.testing.assert_array_equal(tightest(costs), [0.0, 1.0, 9.0])
    ex = excess(costs, {k: v for k, v in costs.items() if k != "c"})
    np.testing.assert_array_equal(ex["a"], [0.0, 1.0, -4.0])
    np.testing.assert_array_equal(ex["c"], [1.0, -1.0, -9.0])
    assert relative_excess(ex["a"], tightest(costs)) == pytest.approx(1.0)


def test_ties_are_decided_on_residual_norms_not_on_costs():
    # Measured on the recorded stand step of paper-humanoid at t = 0.45 s (levels: dynamics,
    # contact limits, joint limits, CoM, trunk, posture): the cascade on ProxQP leaves the
    # dynamics rows with a residual of 3.8e-7 (cost 1.45e-13, within a 1e-9 tie on costs) and
    # a posture cost 1.26e-5 (relative) below the exact solutions'. On costs it was the
    # reference and every exact solution showed a spurious posture excess of 1.3e-5.
    exact = np.array([2.0e-26, 0.0, 2.7e-16, 2.4e-30, 1.7e-28, 28.44502038389])
    loose = np.array([1.45e-13, 0.0, 6.8e-17, 4.0e-20, 9.7e-24, 28.44466283615])
    costs = {"exact": exact, "loose": loose}
    np.testing.assert_array_equal(tightest(costs), exact)
    assert relative_excess(excess(costs)["exact"], exact) == 0.0
    # residuals equal to 1e-9 * max(1, residual) still tie (rounding), larger ones do not
    a, b = np.array([1.0, 5.0]), np.array([(1.0 + 0.5e-9) ** 2, 4.0])
    np.testing.assert_array_equal(tightest({"a": a, "b": b}), b)
    b[0] = (1.0 + 2e-9) ** 2
    np.testing.assert_array_equal(tightest({"a": a, "b": b}), a)


def test_contract_excess_stops_where_the_solver_gets_ahead_of_the_reference():
    # Measured on the recorded reach step of talos at t = 0.575 s (residual norms): OSQP is
    # 2.7e-8 tighter on the contact limits (level 1) than the exact solutions, so it is the
    # reference, but it violates the joint limits (level 2) by 1.1e-4 where they are at 6.6e-7,
    # and its posture cost (level 5) is 4.9e-6 (relative) lower. That posture excess is not a
    # contract miss of the exact solutions: they are ahead on level 2.
    res_exact = np.array([4.1e-13, 2.712095e-08, 6.615644e-07, 4.2e-16, 11.56287, 678.8023])
    res_osqp = np.array([3.2e-13, 0.0, 1.078082e-04, 8.9e-16, 11.56287, 678.8006])
    costs = {"exact": res_exact**2, "osqp": res_osqp**2}
    ref = tightest(costs)
    np.testing.assert_array_equal(ref, costs["osqp"])
    ex = excess(costs)["exact"]
    assert ex[5] / ref[5] > 4e-6  # the level excess is still reported as measured
    assert relative_excess(ex, ref) < 1e-12  # the contract excess counts levels 0-2 only
    # a solver behind the reference everywhere is measured on every level
    assert relative_excess(np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, 1.0])) == 2.0


def test_exact_solutions_meet_the_contract_on_recorded_ill_conditioned_steps():
    # The recorded stand steps of paper-humanoid replayed in order (warm starts as in the
    # benchmark): whatever the cascade on ProxQP returns, the basis algorithm's contract excess
    # over the tightest solution stays within the contract's 1e-6. Measured with the old rule
    # (ties on costs, every level counted): 1.26e-5 at t = 0.45 s, 1.4e-6 at 0.35 and 1.15 s.
    from hqp.solver import HierarchicalSolver

    solvers = {"basis/daqp": HierarchicalSolver("daqp", "basis"),
               "cascade/proxsuite": HierarchicalSolver("proxsuite", "cascade")}
    worst = 0.0
    for step in load(DATA_DIR / "stand_paper-humanoid.npz"):
        costs = {name: level_costs(step.levels, solver.solve(step.levels).x)
                 for name, solver in solvers.items()}
        worst = max(worst, relative_excess(excess(costs)["basis/daqp"], tightest(costs)))
    assert worst <= 1e-6


def test_daqp_hierarchy_peer_on_a_planted_problem():
    # level 0: x0 = 1; level 1: x0 + x1 = 3; level 2: x1 = 0 (unreachable)
    levels = [Level(A=[[1.0, 0.0]], b=[1.0]), Level(A=[[1.0, 1.0]], b=[3.0]),
              Level(A=[[0.0, 1.0]], b=[0.0])]
    x, flag = DaqpHierarchy().solve(levels)
    assert flag > 0
    np.testing.assert_allclose(x, [1.0, 2.0], atol=1e-5)  # DAQP regularises (H = I)


def test_law_decision_vector_meets_the_physics_level(stepped_controller):
    """The law's accelerations with the least-norm wrenches satisfy the top (physics) level."""
    step = capture(stepped_controller, "stand", "paper-humanoid", 1.002)
    x = nullspace_law_x(step)
    assert x.shape == (step.n,)
    c0 = level_costs(step.levels[:1], x)[0]
    scale = float(np.abs(step.h).max())
    assert c0 <= 1e-16 * scale**2, c0
    # a qdd far from the law's is not consistent with the same wrenches' level
    assert level_costs(step.levels[:1], law_to_x(step, x[: step.nv] + 1.0))[0] > 1e-6


def test_interleaved_runs_every_configuration_in_rotated_rounds():
    calls: list[str] = []
    fns = {name: (lambda n=name: calls.append(n)) for name in ("a", "b", "c")}
    out = interleaved(fns, warmup=1, batch=2, min_samples=6, max_seconds=5.0)
    assert set(out) == {"a", "b", "c"}
    assert all(t.samples.size >= 6 and t.cpu.size == t.samples.size for t in out.values())
    timed = calls[3:]  # after the warm-up
    firsts = [timed[i] for i in range(0, len(timed), 6)]
    assert firsts[:3] == ["a", "b", "c"]  # the order rotates between rounds


def _check_row_contract(row):
    for key in ("robot", "solver", "levels", "n", "median_ms", "p95_ms"):
        assert key in row, key
    assert row["median_ms"] is None or row["median_ms"] > 0


def test_recorded_suite_quick():
    from hqp.bench import run_suite

    result = run_suite("recorded", quick=True)
    json.dumps(result)
    rows = result["rows"]
    assert result["suite"] == "recorded" and rows
    by = {r["solver"]: r for r in rows}
    assert {"basis/proxsuite", "cascade/proxsuite", "daqp-hier", "nullspace"} <= set(by)
    for r in rows:
        _check_row_contract(r)
    basis = by["basis/proxsuite"]
    assert basis["algorithm"] == "basis" and basis["backend"] == "proxsuite"
    assert "speedup_vs_cascade" in basis and "over_nullspace" in basis
    assert len(basis["level_cost_excess"]) == basis["levels"]
    # the contract's algorithms meet the contract's tolerance against the tightest solution
    assert basis["cost_excess"] <= 1e-6
    assert by["cascade/proxsuite"]["cost_excess"] <= 1e-6


def test_controller_suite_quick_with_placo():
    from hqp.bench.suite_controller import run

    rows = run(quick=True, robots=["paper-humanoid"])
    by = {r["solver"]: r for r in rows}
    assert set(by) == {"hqp/basis/proxsuite", "nullspace", "placo", "tsid"}
    for r in rows:
        _check_row_contract(r)
        assert r["threads"] == 1 and "failed" not in r, r.get("failed")
    for peer in ("placo", "tsid"):  # measured in its own environment, or skipped saying how
        row = by[peer]
        if "skipped" in row:
            assert row["median_ms"] is None
            assert f"python -m hqp.bench.peer_env {peer}" in row["skipped"]
        else:
            assert row[f"{peer}_version"] and row["pinocchio_version"], row
            assert row["median_ms"] > 0 and row["solve_failures"] == 0, row
            # the worker's own step, the pipe's round trip apart
            assert row["round_trip_median_ms"] > row["median_ms"], row
    hqp = by["hqp/basis/proxsuite"]
    assert set(hqp["phases_ms"]) >= {"update", "rows", "solve", "report"}
    assert len(hqp["levels_ms"]) == hqp["levels"]
    if "skipped" not in by["placo"]:
        assert hqp["over_placo"] == pytest.approx(hqp["median_ms"] / by["placo"]["median_ms"],
                                                  rel=1e-2)
    assert hqp["cost_excess"] == 0.0  # the only contract configuration is the tightest


def test_plots_are_written(tmp_path):
    from hqp.bench.plots import write_suite_plots

    rows = [{"suite": "recorded", "robot": "g1", "solver": s, "n": 47, "rows": 145,
             "levels": 3, "median_ms": m, "p95_ms": 2 * m, "level_cost_excess": [0.0, e, 1e-3]}
            for s, m, e in (("basis/daqp", 0.5, 0.0), ("daqp-hier", 0.2, 1e-2))]
    paths = write_suite_plots({"suite": "recorded", "rows": rows}, tmp_path)
    assert sorted(p.name for p in paths) == ["bench_recorded_accuracy.png",
                                              "bench_recorded_time.png"]
    assert all(p.stat().st_size > 1000 for p in paths)


def test_profile_breakdown_names_the_phases_of_a_step():
    from hqp.bench.profile import BREAKDOWN, profile

    text, calls, ms, parts = profile("paper-humanoid", steps=3, backend="daqp", top=5)
    assert set(parts) == {label for label, _, _ in BREAKDOWN}
    assert calls > 100 and ms > 0.0 and "function calls" in text
    # the parts are inside the step (cumulative CPU time of nested calls)
    assert parts["solve"] <= parts["step"] + 1e-9
    assert parts["  QP backend calls"] <= parts["solve"] + 1e-9
    assert parts["model update"] + parts["rows (stack.build)"] + parts["solve"] <= (
        parts["step"] + 1e-9)


def test_peers_outside_the_contract_are_measured_on_every_level():
    from hqp.bench.accuracy import ExcessTracker

    # the peer is ahead on level 1 (it solves another problem) and far above on level 2
    costs = {"basis/x": np.array([0.0, 1.0, 1.0]), "peer": np.array([0.0, 0.5, 3.0])}
    tracker = ExcessTracker()
    tracker.add(costs, {"basis/x": costs["basis/x"]})
    assert tracker.contract["basis/x"] == 0.0
    assert tracker.contract["peer"] == pytest.approx(2.0)
    np.testing.assert_allclose(tracker.level["peer"], [0.0, -0.5, 2.0])
