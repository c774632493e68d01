"""``hqp sweep``: a study of many simulations on Ray (push maps, parameter grids).

``hqp sweep push-map [flags]``, ``hqp sweep grid --param NAME=V1,V2 [flags]`` or
``hqp sweep STUDY.toml [flags]`` (flags given override the file). Every simulation is a Ray
task: on a new local Ray instance by default (``--workers`` CPUs), on a running cluster with
``--address``. One JSON Lines record per simulation is appended to the results file
(``--out``, default ``NAME.jsonl``) as it finishes; ``--resume`` reuses the file's finished
simulations. The summary JSON goes to stdout, the progress bar and logs to stderr;
``--plot`` draws the push map (polar) or the grid (heat maps of ``--plot-metric``).
``hqp sweep --one PARAMS`` runs one simulation alone in this process (the ``command`` of
every record). Exit status: 0, 1 if a simulation failed, 2 for a bad study (before any
simulation runs).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from tqdm import tqdm

from hqp import robots
from hqp.app.console import output_path_problem, stdout_to_stderr
from hqp.errors import InvalidInput
from hqp.study import (
    KINDS,
    RecordFile,
    Study,
    connect,
    make_plan,
    run_simulation,
    run_study,
    study_from_dict,
)
from hqp.study.plot import plot_grid, plot_push_map
from hqp.study.spec import read_study_file
from hqp.threads import single_blas_thread


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``hqp sweep``."""
    p = subparsers.add_parser(
        "sweep", help="run a study (push map, parameter grid) on Ray",
        description="Run a study of many simulations on Ray, local by default, --address for "
                    "a cluster; one JSON Lines record per simulation, a summary JSON on stdout.")
    p.add_argument("study", nargs="?", metavar="STUDY",
                   help=f"a built-in study ({', '.join(KINDS)}) or a study file (.toml)")
    p.add_argument("--one", metavar="PARAMS",
                   help="run one simulation alone, here (no Ray): its params as JSON (the "
                        "`command` of a record); prints its record")
    what = p.add_argument_group("what is simulated")
    what.add_argument("--name", help="name of the study (default: its kind or file name)")
    what.add_argument("--target", help="standing (default), behavior:NAME or scenario:NAME")
    what.add_argument("--robot", help="robot name or robot TOML file (default: paper-humanoid)")
    what.add_argument("--controllers", nargs="+", metavar="C",
                      help="controllers compared (default: hqp)")
    what.add_argument("--duration", type=float, metavar="S", help="simulated time per run [s]")
    what.add_argument("--backend", help="QP backend of the HQP controller (default: its own)")
    what.add_argument("--set", action="append", default=[], metavar="NAME=JSON",
                      help="a parameter of every simulation (a gain such as com_kp, noise_q_std, "
                           "init_q_std, seed, set.INPUT of a behavior, hierarchy of a scenario)")
    what.add_argument("--param", action="append", default=[], metavar="NAME=V1,V2,...",
                      help="grid: a swept parameter and its values (comma-separated or a JSON "
                           "list)")
    what.add_argument("--metrics", nargs="+", metavar="M", help="metrics kept (default: all)")
    push = p.add_argument_group("push map")
    push.add_argument("--directions", type=int, metavar="N",
                      help="N directions evenly spaced from 0 (forward +x; 90: left +y)")
    push.add_argument("--angles", type=float, nargs="+", metavar="DEG",
                      help="the push directions [deg] (instead of --directions)")
    push.add_argument("--max-force", type=float, metavar="N", help="upper end [N] (800)")
    push.add_argument("--tolerance", type=float, metavar="N", help="bisection resolution [N] (10)")
    push.add_argument("--min-force", type=float, metavar="N", help="lower end [N] (0)")
    push.add_argument("--push-at", type=float, metavar="S", help="start of the push [s] (0.3)")
    push.add_argument("--push-duration", type=float, metavar="S",
                      help="length of the push [s] (0.1)")
    push.add_argument("--repeats", type=int, metavar="K",
                      help="simulations per probed force, seeds 0..K-1 of a perturbation set "
                           "with --set (e.g. init_q_std=1e-4); a force is survived when all "
                           "K survived (1)")
    run = p.add_argument_group("execution")
    run.add_argument("--address", help="a running Ray cluster (default: a new local instance)")
    run.add_argument("--workers", type=int, metavar="N",
                     help="CPUs of the local Ray instance (default: all cores)")
    run.add_argument("--timeout", type=float, metavar="S",
                     help="wall-clock limit of one simulation [s] (default: none)")
    run.add_argument("--out", metavar="FILE", help="results file (default: NAME.jsonl)")
    run.add_argument("--resume", action="store_true",
                     help="reuse the results file's finished simulations, re-run the others")
    run.add_argument("--overwrite", action="store_true", help="start the results file anew")
    run.add_argument("--plot", metavar="PNG", help="draw the push map or the grid's heat maps")
    run.add_argument("--plot-metric", default="fell", metavar="M",
                     help="grid: the metric of the heat maps (default: fell)")
    p.add_argument("--json", action="store_true",
                   help="accepted for symmetry: the summary is always JSON on stdout")
    p.set_defaults(func=command)
    return p


def _value(text: str) -> Any:
    """Return a parameter value: JSON if it parses (numbers, true, null, lists), else the text."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def _pairs(items: list[str], flag: str) -> dict[str, str]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise InvalidInput(f"hqp sweep: {flag} expects NAME=VALUE, got {item!r}")
        out[key] = value
    return out


def study_from_args(args: argparse.Namespace) -> Study:
    """Build the study of the command line: a file or a built-in kind, then the flags.

    Raises:
        InvalidInput: A bad flag or definition. UnknownName: unknown study kind or name.

    """
    if args.study is None:
        raise InvalidInput(f"hqp sweep: give a study ({', '.join(KINDS)} or a .toml file), "
                           "or --one PARAMS")
    if args.study in KINDS:
        data: dict[str, Any] = {"study": args.study, "name": args.study}
    elif args.study.endswith(".toml"):
        data = read_study_file(args.study)
    else:
        raise InvalidInput(f"hqp sweep: unknown study {args.study!r}: give one of "
                           f"{', '.join(KINDS)} or a .toml file")
    for key in ("name", "target", "robot", "duration", "backend", "controllers", "metrics",
                "timeout"):
        if getattr(args, key) is not None:
            data[key] = getattr(args, key)
    if args.robot is not None and robots.is_robot_file(args.robot):
        data["robot"] = str(Path(args.robot).resolve())  # the workers' working directory
    fixed = {k: _value(v) for k, v in _pairs(args.set, "--set").items()}
    if fixed:
        data["fixed"] = {**data.get("fixed", {}), **fixed}
    grid = {}
    for key, text in _pairs(args.param, "--param").items():
        value = _value(text)
        grid[key] = value if isinstance(value, list) else [_value(v) for v in text.split(",")]
    if grid:
        data["grid"] = {**data.get("grid", {}), **grid}
    push = {key: getattr(args, flag) for key, flag in (
        ("max_force", "max_force"), ("tolerance", "tolerance"), ("min_force", "min_force"),
        ("at", "push_at"), ("duration", "push_duration"), ("repeats", "repeats"))
        if getattr(args, flag) is not None}
    if args.directions is not None:
        push["directions"] = args.directions
    if args.angles is not None:
        push["directions"] = list(args.angles)
    if push:
        data["push"] = {**data.get("push", {}), **push}
    return study_from_dict(data)


def _one(args: argparse.Namespace, out: Any) -> int:
    """``hqp sweep --one PARAMS``: one simulation here; its record on stdout."""
    try:
        params = json.loads(args.one)
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"hqp sweep --one: PARAMS is not JSON ({exc})") from None
    if not isinstance(params, dict):
        raise InvalidInput("hqp sweep --one: PARAMS must be a JSON object")
    record = run_simulation(params, args.timeout or 0.0, tuple(args.metrics or ()))
    out.write(json.dumps(record, sort_keys=True) + "\n")
    return 0 if record["status"] == "ok" else 1


def command(args: argparse.Namespace) -> int:
    """Run ``hqp sweep``; print the summary JSON. Returns 0, or 1 if a simulation failed."""
    single_blas_thread()
    if args.one is not None:
        with stdout_to_stderr() as out:
            return _one(args, out)
    study = study_from_args(args)
    make_plan(study)  # every first simulation's params checked before Ray starts
    path = Path(args.out or f"{study.name}.jsonl")
    for target in (path, args.plot):
        problem = None if target is None else output_path_problem(target)
        if problem:
            raise InvalidInput(f"hqp sweep: cannot write {target}: {problem}")
    if args.workers is not None and args.workers < 1:
        raise InvalidInput(f"hqp sweep: --workers must be at least 1, got {args.workers}")
    records = RecordFile(path, resume=args.resume, overwrite=args.overwrite)
    with stdout_to_stderr() as out:
        ray = connect(args.address, args.workers)
        bar = tqdm(desc=study.name, unit="sim", file=sys.stderr, disable=None,
                   dynamic_ncols=True)

        def progress(done: int, expected: int) -> None:
            bar.total = expected
            bar.update(done - bar.n)

        try:
            summary = run_study(study, records, ray, progress=progress)
        finally:
            bar.close()
            if args.address is None:
                ray.shutdown()
        if args.plot:
            draw = plot_push_map if study.kind == "push-map" else (
                lambda s, p: plot_grid(s, p, args.plot_metric))
            summary["plot"] = str(draw(summary, args.plot))
        out.write(json.dumps(summary) + "\n")
    return 1 if summary["failed"] else 0
