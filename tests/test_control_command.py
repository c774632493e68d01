"""Command and the feasibility report's types (hqp.control.command)."""

import pytest

from hqp.controller import (
    Feasibility,
    FeasibilityReport,
    TaskStatus,
)
from hqp.errors import UnknownName


def test_report_lookup():
    s = TaskStatus("a", 3, Feasibility.CONFLICT, 0.5, 2, 0.1)
    r = FeasibilityReport(tasks=(s,))
    assert r["a"] is s and "a" in r and "b" not in r
    assert not r.feasible and r.conflicts() == [s] and r.singular() == []
    with pytest.raises(UnknownName, match="valid tasks: a"):
        r["b"]
