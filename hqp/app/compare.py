"""``hqp compare``: run the papers' scenarios and print their table or the contract's JSON.

``hqp compare NAME [--json] [--plot DIR] [--controllers ...] [--robot ...]
[--duration S] [--contacts unilateral|welded]`` and ``hqp compare --all``.
``--contacts welded`` holds the soles to the floor with MuJoCo weld equalities (the seed
papers' rigid feet) instead of MuJoCo's unilateral contacts; every run carries
``"contacts"``. The table (or, with ``--json``, the JSON object of docs/reference/contracts.md
the JSON sections, alone) goes to stdout; progress goes to stderr. With
``--all --json`` stdout holds one object
``{"scenarios": [<one contract object per scenario>]}``.

PlaCo (``placo``) runs in an environment of its own (:mod:`hqp.bench.peer_env`): the first
``hqp compare`` that runs it makes that environment (one line on stderr says so, and how long
it took), unless ``HQP_NO_PEER_INSTALL=1``; when it cannot be made (offline), PlaCo's runs are
listed under ``"skipped"`` (JSON) or below the table, with the command that adds it.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from typing import Any, TextIO

from comparisons import CONTROLLERS, SCENARIOS, get_scenario
from comparisons.report import format_table, write_plots
from hqp import robots
from hqp.app.console import fallback_note, stdout_to_stderr
from hqp.bench import peer_env
from hqp.errors import InvalidInput
from hqp.sim.simulator import CONTACT_MODES
from hqp.solver.qp import last_resort_count
from hqp.threads import single_blas_thread


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``hqp compare``."""
    p = subparsers.add_parser("compare", help="run the papers' scenarios",
                              description=__doc__)
    add_arguments(p)
    p.set_defaults(func=command)
    return p


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``hqp compare`` to a (sub)parser."""
    parser.add_argument(
        "name", nargs="?", metavar="NAME",
        help=f"scenario to run: {', '.join(SCENARIOS)}",
    )
    parser.add_argument("--all", action="store_true", help="run every scenario")
    parser.add_argument("--json", action="store_true", help="print JSON alone on stdout")
    parser.add_argument("--wide", action="store_true",
                        help="print every column (default: the table fits 100 columns)")
    parser.add_argument("--plot", metavar="DIR", help="write one PNG figure per run into DIR")
    parser.add_argument(
        "--controllers", nargs="+", metavar="C",
        help=f"controllers to run (default: all the scenario supports; {', '.join(CONTROLLERS)})",
    )
    parser.add_argument("--robot", help="robot name or robot TOML file (default: the "
                        "scenario's; the paper scenarios run on paper-humanoid)")
    parser.add_argument(
        "--duration", type=float, metavar="S", help="simulated duration of each run [s]"
    )
    parser.add_argument(
        "--contacts", choices=CONTACT_MODES, default=CONTACT_MODES[0],
        help="how the feet touch the floor: unilateral (MuJoCo's contacts, the default) or "
             "welded (weld equalities hold the soles, the papers' rigid feet)",
    )


def command(args: argparse.Namespace, out: TextIO | None = None,
            err: TextIO | None = None) -> int:
    """Execute ``hqp compare`` with parsed arguments.

    With ``--json``, everything written to stdout during the runs (by Python
    or by C libraries) is sent to stderr, and stdout receives the JSON object
    alone (:func:`hqp.app.console.stdout_to_stderr`).

    Args:
        args: Parsed arguments (:func:`add_arguments`).
        out: Stream of the table or JSON (default: stdout).
        err: Stream of the progress messages (default: stderr).

    Returns:
        The exit status (0).

    Raises:
        UnknownName: Unknown scenario, controller or robot (lists the valid ones).
        InvalidInput: Neither a scenario name nor ``--all``, or both.

    """
    if args.all == (args.name is not None):
        raise InvalidInput(
            f"hqp compare: give one scenario name ({', '.join(SCENARIOS)}) or --all"
        )
    if args.json and out is None:
        with stdout_to_stderr() as original:
            return _run(args, original, err or sys.stderr)
    return _run(args, out or sys.stdout, err or sys.stderr)


def _run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Run the scenarios and print (see :func:`command`)."""
    single_blas_thread()
    names: Sequence[str] = SCENARIOS if args.all else [args.name]
    scenarios = [get_scenario(n) for n in names]  # unknown names fail before any run
    if args.robot is not None:
        robots.check(args.robot)  # a missing robot file too; a scenario names its robots

    def progress(message: str) -> None:
        print(message, file=err, flush=True)

    unavailable: dict[str, str] = {}
    for name in peer_env.PEERS:
        wanted = args.controllers is None or name in args.controllers
        if wanted and any(name in s.controllers for s in scenarios):
            reason = peer_env.ensure(name, notice=err)
            if reason is not None:
                unavailable[name] = reason
    results = []
    for scenario in scenarios:
        fallbacks = last_resort_count()
        result = scenario.run(
            robot=args.robot,
            controllers=args.controllers,
            duration=args.duration,
            progress=progress,
            contacts=getattr(args, "contacts", CONTACT_MODES[0]),
            unavailable=unavailable,
        )
        results.append(result)
        if args.plot:
            for path in write_plots(result, args.plot):
                progress(f"[{result.scenario}] wrote {path}")
        if not args.json:
            print(format_table(result, wide=args.wide), file=out, flush=True)
            if last_resort_count() > fallbacks:
                print(fallback_note(last_resort_count() - fallbacks), file=out)
            print(file=out)
    if args.json:
        if args.all:
            payload: object = {"scenarios": [r.to_json() for r in results]}
        else:
            payload = results[0].to_json()
        print(json.dumps(payload), file=out, flush=True)
    return 0
