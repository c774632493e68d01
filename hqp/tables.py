"""Plain-text tables of results: one number format per column, fitted to a width.

What ``hqp compare`` and ``hqp bench`` print. A column's numbers share one format
(:func:`column_format`): fixed decimals when its nonzero magnitudes span less than three
decades, else scientific notation for all of them; exact zeros print ``0``. The first columns
(the row's names) are always kept; the other columns follow in order while the table fits
``width`` characters, and the caller says how many were left out (``--wide`` or ``--json``
show them).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["column_format", "format_columns"]

SPAN_FIXED = 1e3
"""Largest ratio of a column's nonzero magnitudes printed in fixed decimals."""
DIGITS = 3
"""Significant digits of the smallest nonzero magnitude of a column."""


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def column_format(values: Sequence[Any]) -> Callable[[Any], str]:
    """Return the formatter of one column's cells (see the module docstring).

    Integers stay integers; ``None`` is ``-``; booleans ``yes``/``no``; text as it is.
    """
    floats = [abs(float(v)) for v in values
              if isinstance(v, float) and math.isfinite(v) and v != 0.0]
    if floats:
        lo, hi = min(floats), max(floats)
        if hi / lo < SPAN_FIXED and 1e-3 <= lo and hi < 1e6:
            decimals = max(0, min(6, DIGITS - 1 - math.floor(math.log10(lo))))
            number = f"{{:.{decimals}f}}"
        else:
            number = "{:.2e}"
    else:
        number = "{:g}"

    def fmt(value: Any) -> str:
        if value is None:
            return "-"
        if isinstance(value, bool):
            return "yes" if value else "no"
        if isinstance(value, int):
            return str(value)
        if isinstance(value, float):
            if value == 0.0:
                return "0"
            if not math.isfinite(value):
                return str(value)
            return number.format(value)
        return str(value)

    return fmt


def format_columns(headers: Sequence[str], rows: Sequence[Sequence[Any]], *,
                   width: int | None = None, keep: int = 1,
                   align_left: int | None = None) -> tuple[list[str], list[str]]:
    """Lay out a table: a header line, a rule, one line per row.

    Args:
        headers: Column headers.
        rows: Cell values, one sequence per row (numbers, text, ``None``, booleans).
        width: Widest line [characters] (``None``: every column).
        keep: Leading columns always shown (the names of the row).
        align_left: Leading columns aligned left (default: ``keep``); the others right.

    Returns:
        ``(lines, left_out)``: the table's lines and the headers of the columns that did not
        fit.

    """
    left = keep if align_left is None else align_left
    formats = [column_format([r[i] for r in rows]) for i in range(len(headers))]
    cells = [[formats[i](r[i]) for i in range(len(headers))] for r in rows]
    widths = [max([len(headers[i])] + [len(c[i]) for c in cells]) for i in range(len(headers))]
    shown, used, left_out = [], -2, []
    for i, w in enumerate(widths):
        if i < keep or width is None or (used + 2 + w <= width and not left_out):
            shown.append(i)
            used += 2 + w
        else:
            left_out.append(headers[i])

    def line(values: Sequence[str]) -> str:
        return "  ".join(values[i].ljust(widths[i]) if i < left else values[i].rjust(widths[i])
                         for i in shown).rstrip()

    lines = [line(list(headers)), "  ".join("-" * widths[i] for i in shown)]
    lines += [line(c) for c in cells]
    return lines, left_out
