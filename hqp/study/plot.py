"""Figures of a study's summary: the push map as a polar plot, a grid as heat maps.

The push map draws, per controller, the largest push survived in each direction as a
closed curve (radius: force [N]), with the bracket up to the smallest push that felled the
robot shaded; a direction where even the smallest push felled the robot sits at the centre.
A grid study draws one heat map per controller of a metric over the first two swept
parameters (averaged over any others; a single parameter is a strip).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from hqp.errors import InvalidInput


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(plt: Any, fig: Any, path: str | Path) -> Path:
    """Write a figure as a PNG (its folder created) and close it."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _survived(row: dict[str, Any]) -> float:
    """Radius of a direction: its largest push survived [N] (0: none; nan: unfinished)."""
    if row["largest_survived_n"] is not None:
        return float(row["largest_survived_n"])
    return 0.0 if row["status"] == "done" else float("nan")


def plot_push_map(summary: dict[str, Any], path: str | Path, title: str = "") -> Path:
    """Draw a push map summary (``hqp sweep push-map``) as a polar plot and save a PNG.

    Raises:
        InvalidInput: The summary holds no direction.

    """
    rows = summary.get("directions", [])
    if not rows:
        raise InvalidInput("plot_push_map: the summary holds no direction")
    plt = _pyplot()
    fig = plt.figure(figsize=(6.4, 6.4))
    ax = fig.add_subplot(projection="polar")
    controllers = list(dict.fromkeys(r["controller"] for r in rows))
    for controller in controllers:
        mine = sorted((r for r in rows if r["controller"] == controller),
                      key=lambda r: r["angle_deg"] % 360.0)
        theta = np.radians([r["angle_deg"] for r in mine])
        survived = np.array([_survived(r) for r in mine], dtype=float)
        fallen = np.array([np.nan if r["smallest_fallen_n"] is None else r["smallest_fallen_n"]
                           for r in mine], dtype=float)
        closed = np.append(theta, theta[:1] + 2 * math.pi)
        (line,) = ax.plot(closed, np.append(survived, survived[:1]), "o-", lw=1.8, ms=4,
                          label=f"{controller}: largest push survived")
        ax.fill_between(closed, np.append(survived, survived[:1]),
                        np.append(fallen, fallen[:1]), color=line.get_color(), alpha=0.15,
                        lw=0, label=f"{controller}: up to the smallest push that felled it")
        failed = [r for r in mine if r["status"] == "failed"]
        if failed:  # on the outer ring, where it shows
            edge = float(np.nanmax(np.concatenate([fallen, survived, [1.0]])))
            ax.plot(np.radians([r["angle_deg"] for r in failed]), [edge] * len(failed), "X",
                    color=line.get_color(), ms=10, ls="none",
                    label=f"{controller}: a simulation failed (no result)")
    ax.set_theta_zero_location("N")  # forward (+x) up, left (+y) to the left
    ax.set_theta_direction(1)
    ax.set_xticks(np.radians(np.arange(0, 360, 45)),
                  ["0° forward", "45°", "90° left", "135°", "180° back", "225°", "270° right",
                   "315°"])
    ax.set_rlabel_position(200)
    search = summary.get("definition", {}).get("push", {})
    detail = (f", bisection to {search['tolerance']:g} N" if "tolerance" in search else "")
    ax.set_title(title or "Largest push survived [N] by direction\n"
                 f"(push of {summary.get('push_duration_s', 0.1):g} s{detail})", pad=18)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=1, fontsize=8,
              frameon=False)
    fig.tight_layout()
    return _save(plt, fig, path)


def _number(value: Any) -> float:
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, (int, float)):
        return float(value)
    return float("nan")


def plot_grid(summary: dict[str, Any], path: str | Path, metric: str = "fell",
              title: str = "") -> Path:
    """Draw a grid summary (``hqp sweep grid``) as heat maps of ``metric`` and save a PNG.

    Raises:
        InvalidInput: No parameter or no row, or a metric no row holds.

    """
    names, rows = summary.get("parameters", []), summary.get("rows", [])
    if not names or not rows:
        raise InvalidInput("plot_grid: the summary holds no parameter or no row")
    if not any(metric in r for r in rows):
        known = sorted({k for r in rows for k in r} - {"controller", "id", "status", *names})
        raise InvalidInput(f"plot_grid: no row has the metric {metric!r} (rows have: {known})")
    x_name = names[0]
    y_name = names[1] if len(names) > 1 else None
    xs = list(dict.fromkeys(r[x_name] for r in rows))
    ys = list(dict.fromkeys(r[y_name] for r in rows)) if y_name else [None]
    controllers = list(dict.fromkeys(r["controller"] for r in rows))
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(controllers), squeeze=False, layout="constrained",
                             figsize=(1.5 + (1.2 + 0.8 * max(len(xs), 3)) * len(controllers),
                                      2.4 + 0.6 * max(len(ys), 2)))
    values = [_number(r.get(metric)) for r in rows]
    finite = [v for v in values if math.isfinite(v)]
    vmin, vmax = (min(finite), max(finite)) if finite else (0.0, 1.0)
    for ax, controller in zip(axes[0], controllers):
        grid = np.full((len(ys), len(xs)), np.nan)
        for i, y in enumerate(ys):
            for j, x in enumerate(xs):
                cell = [_number(r.get(metric)) for r in rows if r["controller"] == controller
                        and r[x_name] == x and (y_name is None or r[y_name] == y)]
                cell = [v for v in cell if math.isfinite(v)]
                if cell:
                    grid[i, j] = float(np.mean(cell))
        image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis", vmin=vmin,
                          vmax=vmax)
        for (i, j), v in np.ndenumerate(grid):
            ax.text(j, i, "-" if not math.isfinite(v) else f"{v:.3g}", ha="center",
                    va="center", color="w" if v < 0.5 * (vmin + vmax) else "k", fontsize=8)
        ax.set_xticks(range(len(xs)), [f"{x:g}" if isinstance(x, float) else str(x)
                                       for x in xs])
        ax.set_xlabel(x_name)
        if y_name:
            ax.set_yticks(range(len(ys)), [f"{y:g}" if isinstance(y, float) else str(y)
                                           for y in ys])
            ax.set_ylabel(y_name)
        else:
            ax.set_yticks([])
        ax.set_title(controller)
    fig.colorbar(image, ax=list(axes[0]), label=metric)
    fig.suptitle(title or f"{summary.get('name', 'grid')}: {metric}"
                 + (f" (mean over {', '.join(names[2:])})" if len(names) > 2 else ""))
    return _save(plt, fig, path)
