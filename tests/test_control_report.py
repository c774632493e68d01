"""The feasibility report computed by the core inside the step (``NativeStep.report``).

Oracle: :class:`hqp.control.diagnostics.Diagnostics` on the same built levels and solution,
an independent computation (singular value decompositions of the projected rows and of the
task's rows times each basis, in NumPy/SciPy) where the core uses pivoted QR factorisations
and row-support products. Held at every sampled step of a closed loop that goes through
conflicts (the posture always; a 150 N push for a tenth of a second), on every bundled robot.
"""

from __future__ import annotations

import numpy as np
import pytest

import hqp
from hqp.control.command import Feasibility

pytest.importorskip("hqp._core._ext")


def _closed_loop(name: str, push: float, steps: int = 500, every: int = 7):
    """Yield (step, controller, command) every ``every`` steps of a pushed standing loop."""
    robot = hqp.robots.load(name)
    controller = hqp.standing_controller(robot)
    sim = hqp.Simulator(robot)
    for k in range(steps):
        command = controller.step(sim.state(), k * sim.dt)
        force = np.array([push, 0.0, 0.0]) if 150 <= k < 250 else None
        sim.step(command.tau, force)
        if k % every == 0 and k > 0:
            yield k, controller, command


@pytest.mark.parametrize("name", ["paper-humanoid", "g1", "talos"])
def test_the_core_report_equals_the_diagnostics_on_the_same_levels(name):
    conflicts = yielded = 0
    for k, controller, command in _closed_loop(name, 150.0):
        mirror = controller._native_levels
        assert mirror is not None, f"step {k} left the native step"
        native = command.report.tasks
        built, solution = mirror.built()
        oracle = controller.feasibility.hqp_statuses(built, solution)
        assert [(s.name, s.level) for s in native] == [(s.name, s.level) for s in oracle]
        for a, b in zip(native, oracle):
            assert a.status == b.status, (k, a, b)
            assert a.yields_to == b.yields_to, (k, a, b)
            np.testing.assert_allclose(a.residual, b.residual, rtol=1e-9, atol=1e-12)
            if np.isfinite(b.sigma_min):
                np.testing.assert_allclose(a.sigma_min, b.sigma_min, rtol=1e-7, atol=1e-9,
                                           err_msg=f"step {k} {a.name}")
            else:
                assert np.isnan(a.sigma_min)
            conflicts += a.status is Feasibility.CONFLICT
            yielded += a.yields_to is not None
    # the loop went through conflicts that yield to a level above (else it proves little)
    assert conflicts > 20 and yielded > 20, (conflicts, yielded)


def test_the_quick_answers_agree_with_the_statuses():
    for _k, _controller, command in _closed_loop("g1", 150.0, steps=300, every=29):
        report = command.report
        quick = (report.any_conflict, report.names, [s.name for s in report.conflicts()])
        statuses = report.tasks
        assert quick[0] == any(s.status is Feasibility.CONFLICT for s in statuses)
        assert quick[1] == tuple(s.name for s in statuses)
        assert quick[2] == [s.name for s in statuses if s.status is Feasibility.CONFLICT]


def test_changing_the_tolerance_recomputes_the_report():
    robot = hqp.robots.load("g1")
    controller = hqp.standing_controller(robot)
    sim = hqp.Simulator(robot)
    for k in range(50):
        command = controller.step(sim.state(), k * sim.dt)
        sim.step(command.tau)
    controller.feasibility.tolerance = 1e9  # nothing can be in conflict
    command = controller.step(sim.state(), 50 * sim.dt)
    assert not command.report.any_conflict
    assert all(s.status is not Feasibility.CONFLICT for s in command.report.tasks)
