"""Readable tables and plots of benchmark rows."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hqp.bench.plots import write_suite_plots

COLUMNS = (
    ("suite", "suite"),
    ("source", "source"),
    ("robot", "robot"),
    ("solver", "solver"),
    ("n", "n"),
    ("levels", "levels"),
    ("rows", "rows"),
    ("median_ms", "median [ms]"),
    ("p95_ms", "p95 [ms]"),
    ("cpu_median_ms", "cpu [ms]"),
    ("speedup_vs_cascade", "cascade/basis"),
    ("ratio_to_basis_proxsuite", "x basis/proxsuite"),
    ("cost_excess", "cost excess"),
    ("over_nullspace", "x nullspace"),
    ("over_placo", "x placo"),
    ("over_placo_cpu", "x placo (cpu)"),
)


def _fmt(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if value == 0.0:
            return "0"
        if abs(value) < 1e-3 or abs(value) >= 1e5:
            return f"{value:.2e}"
        return f"{value:.4g}"
    return str(value)


def format_table(result: dict) -> str:
    """Format ``{"suite": ..., "rows": [...]}`` as a fixed-width text table."""
    rows: Sequence[dict] = result.get("rows", [])
    cols = [(k, h) for k, h in COLUMNS if any(k in r for r in rows)]
    if not cols:
        return f"suite {result.get('suite')}: no rows"
    cells = [[_fmt(r.get(k)) for k, _ in cols] for r in rows]
    widths = [max([len(h)] + [len(c[i]) for c in cells]) for i, (_, h) in enumerate(cols)]
    lines = [f"suite: {result.get('suite')}",
             "  ".join(h.ljust(w) for (_, h), w in zip(cols, widths)),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)) for row in cells]
    return "\n".join(lines)


def write_plots(result: dict, directory: str | Path) -> list[Path]:
    """Write one PNG per level count: median time against ``n`` for every solver.

    Returns:
        The paths written.

    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    rows = result.get("rows", [])
    paths = []
    if result.get("suite") in ("controller", "recorded", "all"):
        # time against size and per-level accuracy of whole steps (hqp.bench.plots)

        paths += write_suite_plots(result, out)
        rows = [r for r in rows if r.get("suite", result.get("suite")) == "solver"]
    for levels in sorted({r.get("levels") for r in rows if r.get("levels") is not None}):
        fig, ax = plt.subplots(figsize=(6, 4))
        sub = [r for r in rows if r.get("levels") == levels]
        for solver in sorted({r["solver"] for r in sub}):
            pts = sorted((r["n"], r["median_ms"]) for r in sub if r["solver"] == solver)
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=solver)
        ax.set_xlabel("n (variables)")
        ax.set_ylabel("median solve time [ms]")
        ax.set_yscale("log")
        ax.set_title(f"suite {result.get('suite')}: {levels} levels")
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = out / f"bench_{result.get('suite')}_{levels}levels.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        paths.append(path)
    return paths
