"""The closed loop's speed-ups leave every logged bit unchanged (slow).

The digests in ``tests/data/loop_traces.json`` were recorded with the per-step loop before it
was made faster (``tests/_loop_traces.py``): a g1 walk driven as ``hqp run`` drives it, and a
pushed g1 standing run logged by :func:`hqp.sim.simulate`. The same runs now must hash the same.
"""

from __future__ import annotations

import json

import _loop_traces as traces
import numpy as np
import pytest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def recorded() -> dict[str, dict[str, str]]:
    return json.loads(traces.FIXTURE.read_text())


def test_walk_trace_is_bit_identical(recorded) -> None:
    trace = traces.behavior_trace()
    lifted = trace["fc"].min(axis=0)
    assert lifted.min() == 0.0  # a foot left the floor: the run covers steps, not only standing
    assert traces.digests(trace) == recorded["walk_g1"]


def test_pushed_standing_log_is_bit_identical(recorded) -> None:
    trace = traces.stand_trace()
    assert np.abs(np.diff(trace["com"][:, 0])).max() > 0.0
    assert traces.digests(trace) == recorded["stand_push_g1"]
