"""MkDocs hook: reference pages generated from the code, so they cannot drift from it.

A page holding the marker ``<!-- hqp-cli -->`` gets, in its place, one section per
subcommand with the help text argparse prints for it (``hqp.app.cli.build_parser()``); the
marker ``<!-- hqp-task-types -->`` becomes the table of the task types a behavior file
accepts (``hqp.behaviors.schema.SCHEMAS``).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

MARKER = "<!-- hqp-cli -->"
TASK_TYPES = "<!-- hqp-task-types -->"
ROOT = Path(__file__).resolve().parents[2]


def _importable() -> None:
    """Put the repository on ``sys.path`` (the docs build from a checkout)."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))


def cli_markdown() -> str:
    """Return the markdown of every ``hqp`` subcommand's help, in the parser's order."""
    _importable()
    os.environ["COLUMNS"] = "100"  # argparse wraps at the terminal's width: fix it
    from hqp.app.cli import build_parser

    parser = build_parser()
    parts = ["## `hqp`", "", "```text", parser.format_help().rstrip(), "```", ""]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                parts += [f"## `hqp {name}`", "", "```text", sub.format_help().rstrip(), "```", ""]
    return "\n".join(parts)


def _type_names(accepted: type | tuple[type, ...]) -> str:
    """``(int, float)`` -> ``number``; ``str`` -> ``string``; ``list`` -> ``list``."""
    names = {t.__name__ for t in (accepted if isinstance(accepted, tuple) else (accepted,))}
    return "number" if names <= {"int", "float"} else {"str": "string"}.get(
        "/".join(sorted(names)), "/".join(sorted(names)))


def task_types_markdown() -> str:
    """Return the table of the behavior file's task types and the keys each accepts."""
    _importable()
    from hqp.behaviors.schema import SCHEMAS

    rows = ["| `type` | default level | frames | goals (expressions) | parameters | what |",
            "| --- | --- | --- | --- | --- | --- |"]
    for schema in SCHEMAS.values():
        frames = ", ".join(f"`{k}`" + (" (required)" if k in schema.required else "")
                           for k in schema.frames) or "-"
        goals = ", ".join(f"`{k}`" for k in schema.goals) or "-"
        params = ", ".join(f"`{k}` ({_type_names(v)})" for k, v in schema.params.items()) or "-"
        rows.append(f"| `{schema.type}` | {schema.category.name.lower()} | {frames} | {goals} "
                    f"| {params} | {schema.description} |")
    return "\n".join(rows)


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: D103 (MkDocs API)
    if MARKER in markdown:
        markdown = markdown.replace(MARKER, cli_markdown())
    if TASK_TYPES in markdown:
        markdown = markdown.replace(TASK_TYPES, task_types_markdown())
    return markdown
