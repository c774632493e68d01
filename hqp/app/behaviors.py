"""``hqp behaviors [--json]``: list the bundled behavior library."""

from __future__ import annotations

import argparse
import json
import textwrap
from typing import Any

from hqp.app.console import TABLE_WIDTH
from hqp.behaviors.loader import library_names, load_behavior


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``hqp behaviors [--json]``."""
    p = subparsers.add_parser("behaviors", help="list the behavior library",
                              description="List the bundled behaviors and their phases.")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=command)
    return p


def command(args: argparse.Namespace) -> int:
    """List the library (``hqp behaviors``)."""
    rows = []
    for name in library_names():
        spec = load_behavior(name)
        rows.append({"name": name, "description": spec.description, "phases": list(spec.phases),
                     "inputs": list(spec.inputs), "file": str(spec.path)})
    if args.json:
        print(json.dumps({"behaviors": rows}))
    else:
        width = max(len(r["name"]) for r in rows)
        indent = " " * (width + 2)
        for r in rows:
            phases = (f"phases: {', '.join(r['phases'])}"
                      + (f"; inputs: {', '.join(r['inputs'])}" if r["inputs"] else ""))
            print(textwrap.fill(r["description"], TABLE_WIDTH,
                                initial_indent=f"{r['name']:<{width}}  ", subsequent_indent=indent))
            print(textwrap.fill(phases, TABLE_WIDTH, initial_indent=indent,
                                subsequent_indent=indent))
    return 0
