"""PNG figures of closed-loop runs, drawn like the hierarchy paper's Figures 4 and 5.

A figure is a grid of :class:`Panel` objects, each a few time series with a
title and axis labels. The scenario decides what goes in the panels (for
``hand-reach``: centre-of-gravity error x/y [mm], right-hand height against
its goal, right elbow and knee flexion against their limits); this module
only draws them, with matplotlib's non-interactive ``Agg`` backend.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hqp.errors import InvalidInput


@dataclass(frozen=True)
class Line:
    """One curve of a panel.

    Attributes:
        label: Legend entry.
        y: Values ``(N,)`` over the panel's time axis.
        style: ``"solid"``, ``"dashed"`` (goals, limits) or ``"dotted"``.

    """

    label: str
    y: np.ndarray
    style: str = "solid"


@dataclass(frozen=True)
class Panel:
    """One sub-plot: curves over time.

    Attributes:
        title: Panel title (the paper's "Balancing Error", "Right Elbow Angle", ...).
        ylabel: Vertical axis label with unit (``"error [cm]"``).
        t: Times ``(N,)`` [s].
        lines: Curves drawn in the panel.
        events: Times of events drawn as thin vertical lines [s].
        log: A logarithmic vertical axis (errors spanning decades; non-positive values are
            not drawn).

    """

    title: str
    ylabel: str
    t: np.ndarray
    lines: tuple[Line, ...]
    events: tuple[float, ...] = field(default_factory=tuple)
    log: bool = False


_STYLES = {"solid": "-", "dashed": "--", "dotted": ":"}


def plot_panels(panels: list[Panel], path: str | Path, title: str = "") -> Path:
    """Draw panels on a grid of two columns and save a PNG.

    The panels are lettered (a), (b), ... below their horizontal axis, as in
    the paper's figures. Vertical axes show their values without an offset (matplotlib's
    ``1e-6 + 9.2111e-1`` notation), or a logarithmic scale where the panel asks for one.

    Args:
        panels: Panels to draw, row by row.
        path: Output file (``.png``); its folder is created.
        title: Figure title.

    Returns:
        The path written.

    Raises:
        InvalidInput: No panel, or a curve whose length differs from its time axis.

    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not panels:
        raise InvalidInput("plot_panels: no panel to draw")
    for panel in panels:
        for line in panel.lines:
            if np.shape(line.y) != np.shape(panel.t):
                raise InvalidInput(
                    f"plot_panels: panel {panel.title!r}, curve {line.label!r} has shape "
                    f"{np.shape(line.y)}, time axis {np.shape(panel.t)}"
                )
    ncols = 2 if len(panels) > 1 else 1
    nrows = math.ceil(len(panels) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5.2 * ncols, 3.4 * nrows), squeeze=False)
    for k, ax in enumerate(axes.flat):
        if k >= len(panels):
            ax.set_visible(False)
            continue
        panel = panels[k]
        colors: dict[str, str] = {}
        for line in panel.lines:
            style = _STYLES.get(line.style, "-")
            if line.label in colors:  # a second curve of the same label: same colour, no entry
                ax.plot(panel.t, line.y, style, color=colors[line.label], lw=1.6)
                continue
            (curve,) = ax.plot(panel.t, line.y, style, label=line.label, lw=1.6)
            colors[line.label] = curve.get_color()
        for te in panel.events:
            ax.axvline(te, color="0.6", lw=0.8)
        if panel.log:
            ax.set_yscale("log")
        else:
            ax.ticklabel_format(axis="y", useOffset=False)  # values as they are, no "1e-6+0.92"
        ax.set_title(panel.title)
        ax.set_ylabel(panel.ylabel)
        ax.set_xlabel(f"time [s]\n({chr(ord('a') + k)})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
