"""Text tables and plot files of scenario results (what ``hqp compare`` prints and writes)."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

from comparisons.base import ScenarioResult
from hqp.plots import plot_panels
from hqp.tables import format_columns

COLUMNS: tuple[tuple[str, str], ...] = (
    ("cog_error_max_mm", "CoG max [mm]"),
    ("cog_error_final_mm", "CoG end [mm]"),
    ("hand_final_distance_cm", "hand [cm]"),
    ("joint_limit_violation_max_rad", "past limit [rad]"),
    ("fell", "fell"),
    ("step_time_median_ms", "step [ms]"),
)
"""Key metrics, first in every table, with their headers (scenario-specific metrics follow,
then :data:`DETAILS`)."""

DETAILS: tuple[tuple[str, str], ...] = (
    ("cog_error_x_max_mm", "x max [mm]"),
    ("cog_error_y_max_mm", "y max [mm]"),
    ("cog_error_x_final_mm", "x final [mm]"),
    ("cog_error_y_final_mm", "y final [mm]"),
    ("torque_clipping_count", "clipped"),
    ("safe_mode_steps", "safe steps"),
)
"""Metrics shown last, where the width allows (``--wide``: always)."""

WIDTH = 100
"""Widest line of the default table [characters]."""

_SKIP = {"controller", "hierarchy", "note"}

_UNITS: tuple[tuple[str, str], ...] = (
    ("_flexion_gap_rad", " from limit [rad]"),
    ("_flexion_limit_s", " at limit [s]"),
    ("_mps", " [m/s]"),
    ("_rad", " [rad]"),
    ("_deg", " [deg]"),
    ("_cm", " [cm]"),
    ("_mm", " [mm]"),
    ("_ms", " [ms]"),
    ("_s", " [s]"),
)


def header(key: str) -> str:
    """Short column header of a scenario-specific metric key (the JSON keeps the key).

    ``right_elbow_flexion_gap_rad`` -> ``elbow from limit [rad]``,
    ``hand_speed_final_mps`` -> ``hand speed final [m/s]``.
    """
    name, unit = key, ""
    for suffix, label in _UNITS:
        if name.endswith(suffix):
            name, unit = name[: -len(suffix)], label
            break
    if name.startswith("right_"):
        name = name[len("right_"):]
    return name.replace("_", " ") + unit


def format_table(result: ScenarioResult, wide: bool = False) -> str:
    """Return a plain-text table: one row per controller and hierarchy, one column per metric.

    At most :data:`WIDTH` characters wide unless ``wide`` (the last line then names the
    columns left out); one number format per column (:func:`hqp.tables.column_format`).
    Controllers not run (a peer without its environment) follow, with why.
    """
    table = format_rows(result.scenario, result.robot, [r.row() for r in result.runs], wide)
    skipped = [f"skipped ({s['controller']}, {', '.join(s['hierarchies'])}): {s['skipped']}"
               for s in result.skipped]
    if not wide:
        skipped = [textwrap.fill(n, WIDTH, subsequent_indent="  ") for n in skipped]
    return "\n".join([table, *skipped])


def format_rows(scenario: str, robot: str, rows: list[dict[str, Any]],
                wide: bool = False) -> str:
    """Format the contract's ``runs`` rows of one scenario as :func:`format_table` does."""
    keys = [k for k, _ in COLUMNS]
    headers = [h for _, h in COLUMNS]
    detail = dict(DETAILS)
    for row in rows:
        for k in row:
            if k not in _SKIP and k not in keys and k not in detail:
                keys.append(k)
                headers.append(header(k))
    for k, h in DETAILS:
        if any(k in row for row in rows):
            keys.append(k)
            headers.append(h)
    table = [[row["controller"], row["hierarchy"], *(row.get(k) for k in keys)]
             for row in rows]
    lines, left_out = format_columns(["controller", "hierarchy", *headers], table,
                                     width=None if wide else WIDTH, keep=2)
    lines = [f"{scenario} on {robot}", *lines]
    if left_out:
        lines.append(f"({len(left_out)} more columns: --wide, or --json for every field)")
    notes = [
        f"note ({r['controller']}, {r['hierarchy']}): {r['note']}" for r in rows if "note" in r
    ]
    if not wide:
        notes = [textwrap.fill(n, WIDTH, subsequent_indent="  ") for n in notes]
    return "\n".join(lines + notes)


def write_plots(result: ScenarioResult, folder: str | Path) -> list[Path]:
    """One PNG per run, ``<folder>/<scenario>_<controller>_<hierarchy>.png``."""
    out = []
    for run in result.runs:
        name = f"{result.scenario}_{run.spec.controller}_{run.spec.hierarchy}.png"
        title = (
            f"{result.scenario}: {run.spec.controller}, hierarchy {run.spec.hierarchy} "
            f"({result.robot})"
        )
        out.append(plot_panels(run.panels, Path(folder) / name, title))
    return out
