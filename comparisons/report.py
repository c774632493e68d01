"""Text tables and plot files of scenario results (what ``hqp compare`` prints and writes)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from comparisons.base import ScenarioResult
from hqp.plots import plot_panels

COLUMNS: tuple[tuple[str, str], ...] = (
    ("cog_error_max_mm", "cog max [mm]"),
    ("cog_error_final_mm", "cog final [mm]"),
    ("cog_error_x_max_mm", "x max [mm]"),
    ("cog_error_y_max_mm", "y max [mm]"),
    ("cog_error_x_final_mm", "x final [mm]"),
    ("cog_error_y_final_mm", "y final [mm]"),
    ("hand_final_distance_cm", "hand [cm]"),
    ("joint_limit_violation_max_rad", "limit viol. [rad]"),
    ("torque_clipping_count", "clipped"),
    ("safe_mode_steps", "safe steps"),
    ("step_time_median_ms", "step [ms]"),
    ("fell", "fell"),
)
"""Metrics shown in every table, with their headers (scenario-specific metrics follow)."""

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


def _fmt(value: Any) -> str:
    """Format one cell."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return str(value)
        if value != 0.0 and (abs(value) < 1e-2 or abs(value) >= 1e5):
            return f"{value:.2e}"
        return f"{value:.2f}"
    return str(value)


def format_table(result: ScenarioResult) -> str:
    """Return a plain-text table: one row per controller and hierarchy, one column per metric."""
    return format_rows(result.scenario, result.robot, [r.row() for r in result.runs])


def format_rows(scenario: str, robot: str, rows: list[dict[str, Any]]) -> str:
    """Format the contract's ``runs`` rows of one scenario as :func:`format_table` does."""
    keys = [k for k, _ in COLUMNS]
    headers = [h for _, h in COLUMNS]
    for row in rows:
        for k in row:
            if k not in _SKIP and k not in keys:
                keys.append(k)
                headers.append(header(k))
    table = [["controller", "hierarchy", *headers]]
    for row in rows:
        table.append([row["controller"], row["hierarchy"], *(_fmt(row.get(k)) for k in keys)])
    widths = [max(len(r[i]) for r in table) for i in range(len(table[0]))]
    lines = [f"{scenario} on {robot}"]
    for k, r in enumerate(table):
        lines.append("  ".join(c.rjust(w) if i > 1 else c.ljust(w) for i, (c, w) in
                               enumerate(zip(r, widths))))
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    notes = [
        f"note ({r['controller']}, {r['hierarchy']}): {r['note']}" for r in rows if "note" in r
    ]
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
