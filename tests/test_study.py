"""Studies without Ray or MuJoCo: definitions, bisection, grids, records, command line, plots."""

from __future__ import annotations

import json
import shlex
import subprocess
import sys

import pytest

from hqp.app.cli import main
from hqp.errors import InvalidInput, UnknownName
from hqp.study import RecordFile, load_study, make_plan, read_records, study_from_dict
from hqp.study.grid import GridPlan
from hqp.study.plot import plot_grid, plot_push_map
from hqp.study.pushmap import Bisection, PushMapPlan
from hqp.study.simulation import check_params, rerun_command, run_simulation
from hqp.study.spec import directions, simulation_id


def search(threshold: float, max_force: float = 800.0, tolerance: float = 10.0) -> Bisection:
    """A bisection against a robot that falls under any force >= threshold."""
    b = Bisection(max_force, tolerance)
    while (force := b.next_force()) is not None:
        b.feed(force, force >= threshold)
    return b


@pytest.mark.parametrize("threshold", [3.0, 97.0, 411.0, 799.0])
def test_bisection_brackets_the_threshold_with_runs(threshold: float) -> None:
    b = search(threshold)
    assert b.survived is not None and b.fell is not None
    assert b.survived < threshold <= b.fell
    assert b.fell - b.survived <= 10.0
    assert b.survived in b.probes and b.fell in b.probes  # both ends are runs, not guesses
    assert len(b.probes) <= b.expected_probes()


def test_bisection_ends_of_the_range() -> None:
    strong = search(1e9)
    assert strong.probes == [800.0] and strong.survived == 800.0 and strong.fell is None
    weak = search(0.0)
    assert weak.survived is None and weak.fell == 0.0 and weak.probes[-1] == 0.0
    failed = Bisection(800.0, 10.0)
    failed.feed(800.0, True)
    failed.feed(400.0, None)
    assert failed.failed and failed.done and failed.next_force() is None


def fake_record(params: dict, fell: bool | None, group: str, probe: int,
                repeat: int = 0) -> dict:
    status = "ok" if fell is not None else "crashed"
    return {"id": simulation_id(params), "params": params, "status": status,
            "metrics": {} if fell is None else {"fell": fell}, "error": None if fell is not None
            else "WorkerCrashedError: the worker died", "group": group, "probe": probe,
            "repeat": repeat}


def test_push_map_plan_runs_every_direction_in_parallel() -> None:
    study = study_from_dict({"study": "push-map", "controllers": ["hqp", "nullspace"],
                             "push": {"directions": 4, "max_force": 400, "tolerance": 100}})
    plan = PushMapPlan(study)
    first = plan.ready()
    assert len(first) == 8 and plan.ready() == []  # one pending probe per chain
    assert {p["push_angle_deg"] for p, _ in first} == {0.0, 90.0, 180.0, 270.0}
    thresholds = {0.0: 250.0, 90.0: 120.0, 180.0: 1e9, 270.0: 0.0}
    batch = first
    while batch:
        for params, notes in batch:
            fell = None if (params["controller"], params["push_angle_deg"], notes["probe"]) \
                == ("nullspace", 90.0, 1) else params["push_force"] >= thresholds[
                    params["push_angle_deg"]]
            plan.feed(fake_record(params, fell, **notes))
        batch = plan.ready()
    rows = {(r["controller"], r["angle_deg"]): r for r in plan.summary()["directions"]}
    assert rows["hqp", 0.0]["largest_survived_n"] == 200.0
    assert rows["hqp", 0.0]["smallest_fallen_n"] == 300.0
    assert rows["hqp", 180.0]["largest_survived_n"] == 400.0
    assert rows["hqp", 180.0]["smallest_fallen_n"] is None
    assert rows["hqp", 270.0]["largest_survived_n"] is None
    assert rows["nullspace", 90.0]["status"] == "failed"
    assert rows["nullspace", 90.0]["errors"] == ["crashed: WorkerCrashedError: the worker died"]
    assert all(r["status"] == "done" for k, r in rows.items() if k != ("nullspace", 90.0))


def test_push_map_repeats_count_a_force_survived_only_when_every_repeat_survived() -> None:
    # a robot whose survival is chaotic between 250 N and 350 N: seed 2 falls from 250 N,
    # the other seeds from 350 N; the bracket is that of the seed that falls first
    study = study_from_dict({"study": "push-map", "fixed": {"init_q_std": 1e-4},
                             "push": {"directions": [0.0, 90.0], "max_force": 800,
                                      "tolerance": 25, "repeats": 3}})
    plan = PushMapPlan(study)
    first = plan.ready()
    assert len(first) == 6 and plan.ready() == []  # the repeats of a probe run in parallel
    assert sorted(p["seed"] for p, _ in first) == [0, 0, 1, 1, 2, 2]
    assert len({simulation_id(p) for p, _ in first}) == 6
    assert plan.expected() == 3 * 2 * Bisection(800, 25).expected_probes()
    batch, ran = first, 0
    while batch:
        # fed in reverse order: a probe advances only once all its repeats are in
        for params, notes in reversed(batch):
            threshold = 250.0 if params["seed"] == 2 else 350.0
            plan.feed(fake_record(params, params["push_force"] >= threshold, **notes))
            ran += 1
        batch = plan.ready()
    rows = plan.summary()["directions"]
    for row in rows:
        assert row["largest_survived_n"] < 250.0 <= row["smallest_fallen_n"]
        assert row["smallest_fallen_n"] - row["largest_survived_n"] <= 25.0
        assert row["repeats"] == 3 and row["status"] == "done"
        fallen = next(r for r in plan.records[f"hqp/{row['angle_deg']:g}"]
                      if r["id"] == row["fallen_id"])
        assert fallen["metrics"]["fell"]  # the record named is one that fell
    assert ran == 3 * sum(r["probes"] for r in rows)


def test_push_map_repeats_need_a_perturbation_and_set_the_seed() -> None:
    with pytest.raises(InvalidInput, match="init_q_std"):
        study_from_dict({"study": "push-map", "push": {"repeats": 4}})
    with pytest.raises(InvalidInput, match="seed"):
        study_from_dict({"study": "push-map", "fixed": {"init_q_std": 1e-4, "seed": 3},
                         "push": {"repeats": 4}})
    for bad in (0, 2.5, True, "3"):
        with pytest.raises(InvalidInput, match="repeats"):
            study_from_dict({"study": "push-map", "fixed": {"noise_q_std": 1e-4},
                             "push": {"repeats": bad}})
    # one repeat: the params (and so the records' ids) of a study without repeats
    single = PushMapPlan(study_from_dict({"study": "push-map", "push": {"repeats": 1}}))
    assert all("seed" not in p for p, _ in single.ready())


def test_grid_plan_is_the_cartesian_product() -> None:
    study = study_from_dict({"study": "grid", "controllers": ["hqp", "nullspace"],
                             "fixed": {"duration": 0.5},
                             "grid": {"com_kp": [50, 100, 200], "seed": [0, 1]}})
    plan = GridPlan(study)
    sims = plan.ready()
    assert len(sims) == 12 and plan.ready() == []
    assert len({simulation_id(p) for p, _ in sims}) == 12
    assert all(p["duration"] == 0.5 and p["target"] == "standing" for p, _ in sims)
    plan.feed({**fake_record(sims[0][0], True, "hqp", 0)})
    rows = plan.summary()["rows"]
    assert rows[0]["status"] == "ok" and rows[0]["fell"] is True
    assert rows[1]["status"] == "missing"


@pytest.mark.parametrize("data, error", [
    ({"study": "spiral"}, UnknownName),
    ({"study": "push-map", "controllers": ["pid"]}, UnknownName),
    ({"study": "push-map", "colour": 1}, InvalidInput),
    ({"study": "push-map", "push": {"directions": 0}}, InvalidInput),
    ({"study": "push-map", "push": {"max_force": -1}}, InvalidInput),
    ({"study": "push-map", "push": {"min_force": 900}}, InvalidInput),
    ({"study": "push-map", "grid": {"com_kp": [1]}}, InvalidInput),
    ({"study": "grid"}, InvalidInput),
    ({"study": "grid", "grid": {"com_kp": []}}, InvalidInput),
    ({"study": "grid", "grid": {"controller": ["hqp"]}}, InvalidInput),
])
def test_bad_definitions_are_refused(data: dict, error: type) -> None:
    with pytest.raises(error):
        study_from_dict(data)


def test_directions() -> None:
    assert directions(4) == (0.0, 90.0, 180.0, 270.0)
    assert len(directions(16)) == 16 and directions(16)[1] == 22.5
    assert directions([10, 20]) == (10.0, 20.0)


def test_study_file(tmp_path) -> None:
    path = tmp_path / "gains.toml"
    path.write_text('study = "grid"\ncontrollers = ["nullspace"]\nduration = 0.4\n'
                    'timeout = 60\n[fixed]\nnoise_q_std = 0.001\n'
                    '[grid]\ncom_kp = [50, 100]\nposture_kp = [10.0]\n')
    study = load_study(path)
    assert study.name == "gains" and study.kind == "grid" and study.timeout == 60.0
    assert study.fixed == {"noise_q_std": 0.001, "duration": 0.4, "target": "standing"}
    assert study.grid == {"com_kp": (50, 100), "posture_kp": (10.0,)}
    make_plan(study)  # every simulation's params are valid
    (tmp_path / "bad.toml").write_text("study = [")
    with pytest.raises(InvalidInput, match="bad.toml"):
        load_study(tmp_path / "bad.toml")


def test_params_are_checked_per_target() -> None:
    check_params({"target": "standing", "controller": "nullspace", "zone": 0.2})
    check_params({"target": "behavior:squat-jump", "set.takeoff_height": 1.1})
    check_params({"target": "scenario:hand-reach", "controller": "placo",
                  "hierarchy": "cog-first"})
    with pytest.raises(InvalidInput, match="zone"):  # a parameter of the law only
        check_params({"target": "standing", "controller": "hqp", "zone": 0.2})
    with pytest.raises(InvalidInput, match="push_force"):
        check_params({"target": "standing", "push_force": -3.0})
    with pytest.raises(UnknownName):
        check_params({"target": "scenario:hand-reach", "hierarchy": "flat"})
    with pytest.raises(UnknownName):
        check_params({"target": "treadmill"})
    with pytest.raises(UnknownName):
        check_params({"robot": "asimo"})
    with pytest.raises(InvalidInput, match="metrics"):
        make_plan(study_from_dict({"study": "push-map", "metrics": ["fel"]}))


def test_rerun_command_holds_the_params() -> None:
    params = {"controller": "hqp", "push_force": 412.5, "push_angle_deg": 22.5,
              "target": "behavior:it's quoted"}
    argv = shlex.split(rerun_command(params))
    assert argv[:3] == ["hqp", "sweep", "--one"] and json.loads(argv[3]) == params


def test_records_file(tmp_path) -> None:
    path = tmp_path / "study.jsonl"
    rec = {"id": "a", "params": {}, "status": "crashed", "metrics": {}}
    records = RecordFile(path)
    records.write(rec)
    records.close()
    with pytest.raises(InvalidInput, match="--resume"):
        RecordFile(path)
    with path.open("a") as f:
        f.write('{"id": "b", "status": "o')  # a torn last line: the writer was killed
    resumed = RecordFile(path, resume=True)
    assert [r["id"] for r in resumed.previous] == ["a"] and resumed.finished() == {}
    resumed.write({**rec, "status": "ok"})
    resumed.close()
    assert [r["status"] for r in read_records(path)] == ["crashed", "ok"]
    assert RecordFile(path, resume=True).finished()["a"]["status"] == "ok"  # the latest wins
    assert RecordFile(path, overwrite=True).previous == []


def test_cli_refuses_before_any_simulation(tmp_path, capsys) -> None:
    assert main(["sweep"]) == 2
    assert main(["sweep", "push-map", "--set", "com_kpp=1"]) == 2
    assert "com_kpp" in capsys.readouterr().err
    assert main(["sweep", "grid", "--param", "com_kp"]) == 2
    capsys.readouterr()
    out = tmp_path / "exists.jsonl"
    out.write_text("")
    assert main(["sweep", "push-map", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--resume" in err and len(err.strip().splitlines()) == 1
    assert main(["sweep", "--one", "[1, 2]"]) == 2


def test_plots(tmp_path) -> None:
    rows = [{"controller": c, "angle_deg": a, "largest_survived_n": s, "smallest_fallen_n": f,
             "status": st} for c, k in (("hqp", 2.0), ("nullspace", 1.0))
            for a, s, f, st in ((0.0, 100 * k, 110 * k, "done"), (90.0, None, 0.0, "done"),
                                (180.0, 300.0, None, "done"), (270.0, None, None, "failed"))]
    png = plot_push_map({"directions": rows, "push_duration_s": 0.1}, tmp_path / "map.png")
    assert png.stat().st_size > 10_000
    grid = {"name": "g", "parameters": ["com_kp", "seed"],
            "rows": [{"controller": "hqp", "com_kp": kp, "seed": s, "fell": kp > 60,
                      "status": "ok"} for kp in (50, 100) for s in (0, 1)]}
    assert plot_grid(grid, tmp_path / "grid.png").stat().st_size > 5_000
    with pytest.raises(InvalidInput, match="fell"):
        plot_grid(grid, tmp_path / "x.png", metric="speed")


def test_errors_and_timeouts_are_records() -> None:
    bad = run_simulation({"target": "standing", "push_force": -1.0})
    assert bad["status"] == "error" and "push_force" in bad["error"] and bad["metrics"] == {}
    assert bad["command"] == rerun_command({"target": "standing", "push_force": -1.0})
    slow = run_simulation({"controller": "nullspace", "duration": 5.0}, timeout=1e-3)
    assert slow["status"] == "timeout" and "timeout of 0.001 s" in slow["error"]
    assert slow["timing"]["wall_s"] < 60.0  # stopped at its first check, not after 5 s of physics


def test_a_step_that_never_returns_ends_its_process() -> None:
    """The backstop of a simulation stuck where its timeout is never checked."""
    code = ("import time\nimport hqp.study.simulation as s\ns.HARD_TIMEOUT_GRACE = 0.5\n"
            "s.measure = lambda params, timeout: time.sleep(600)\n"
            "s.run_simulation({'controller': 'hqp'}, timeout=0.2)\n")
    # ends long before the sleep (or subprocess.run raises TimeoutExpired)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode != 0 and done.stderr.startswith("Timeout")
    assert "<lambda>" in done.stderr and "in run_simulation" in done.stderr  # where it hung
