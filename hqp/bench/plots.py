"""Plots of the ``controller``, ``recorded`` and ``all`` suites (``hqp bench --plot DIR``).

Two figures per suite:

- ``bench_<suite>_time.png``: median time of a control step (controller suite) or of a solve
  (recorded suite) against the problem size (number of rows of all levels; the number of
  variables ``n`` is in the legend of each robot), one marker series per solver, log scale;
- ``bench_<suite>_accuracy.png``: per-level accuracy, the excess cost of each level over the
  tightest contract solution (``level_cost_excess``), largest over the sources, one line per
  solver, symmetric-log scale (0 where the solver is as tight as the best one).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any


def _suite_rows(result: dict[str, Any]) -> dict[str, list[dict[str, Any]]]:
    rows = result.get("rows", [])
    out: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        out.setdefault(str(r.get("suite", result.get("suite"))), []).append(r)
    return out


def write_suite_plots(result: dict[str, Any], directory: str | Path) -> list[Path]:
    """Write the time-versus-size and per-level accuracy plots of each suite in ``result``.

    Rows of the ``solver`` suite (inside ``all``) are left to :mod:`hqp.bench.report`.

    Returns:
        The paths written.

    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    for suite, rows in _suite_rows(result).items():
        if suite not in ("controller", "recorded"):
            continue
        timed = [r for r in rows if r.get("median_ms") and r.get("rows")]
        if timed:
            fig, ax = plt.subplots(figsize=(7, 4.5))
            for solver in sorted({r["solver"] for r in timed}):
                pts = sorted((r["rows"], r["median_ms"]) for r in timed if r["solver"] == solver)
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", linestyle="",
                        label=solver)
            sizes = sorted({(r.get("robot"), r.get("n")) for r in timed}, key=str)
            ax.set_xlabel("rows of all levels  (" + ", ".join(f"{rb}: n = {n}"
                                                           for rb, n in sizes) + ")")
            what = "control step" if suite == "controller" else "solve"
            ax.set_ylabel(f"median {what} time [ms]")
            ax.set_yscale("log")
            ax.set_title(f"hqp bench --suite {suite}: time against size")
            ax.legend(fontsize=6, ncol=2)
            fig.tight_layout()
            path = out / f"bench_{suite}_time.png"
            fig.savefig(path, dpi=120)
            plt.close(fig)
            paths.append(path)
        acc = [r for r in rows if r.get("level_cost_excess")]
        if acc:
            fig, ax = plt.subplots(figsize=(7, 4.5))
            for solver in sorted({r["solver"] for r in acc}):
                sub = [r["level_cost_excess"] for r in acc if r["solver"] == solver]
                L = max(len(e) for e in sub)
                worst = [max((e[k] for e in sub if k < len(e)), default=0.0) for k in range(L)]
                ax.plot(range(L), worst, marker="o", label=solver)
            ax.set_yscale("symlog", linthresh=1e-12)
            ax.set_xlabel("level (0 = highest priority)")
            ax.set_ylabel("absolute excess cost over the tightest solution")
            ax.set_title(f"hqp bench --suite {suite}: per-level accuracy (worst case)\n"
                         "absolute excess; the contract measure is the relative cost_excess",
                         fontsize=9)
            ax.legend(fontsize=6, ncol=2)
            fig.tight_layout()
            path = out / f"bench_{suite}_accuracy.png"
            fig.savefig(path, dpi=120)
            plt.close(fig)
            paths.append(path)
    return paths


def table_markdown(rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> str:
    """Rows as a Markdown table over ``columns`` (missing values as ``-``)."""
    def fmt(v: Any) -> str:
        if v is None:
            return "-"
        if isinstance(v, float):
            return f"{v:.3g}"
        if isinstance(v, list):
            return "[" + ", ".join(fmt(x) for x in v) + "]"
        return str(v)

    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(fmt(r.get(c)) for c in columns) + " |" for r in rows]
    return "\n".join(lines)
