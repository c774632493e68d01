"""Python function calls inside ``controller.step``: what is left of Python in a control step.

The step runs in the C++ core; Python around it only dispatches (issue: one engine). The
count is of Python frames entered (``sys.setprofile``'s ``"call"`` events, C functions not
counted) between the entry and the return of ``controller.step``, step by step, in MuJoCo.
"""

import collections
import gc
import sys

import numpy as np
import pytest

import hqp
from hqp.control.servo import WholeBodyController

LIMIT = 20
"""Python calls allowed in one control step."""


class _Counter:
    """Counts the Python calls of each ``WholeBodyController.step`` (and what they called)."""

    def __init__(self):
        self.counts = []
        self.names = []

    def step(self, controller, state, t):
        n = 0
        names = collections.Counter()

        def profile(frame, event, arg):
            nonlocal n
            if event == "call":
                n += 1
                names[frame.f_code.co_qualname] += 1

        # the cyclic collector off: a collection inside the step would run other objects'
        # finalizers, which are not the step's calls
        collecting = gc.isenabled()
        gc.disable()
        sys.setprofile(profile)
        try:
            return _ORIGINAL_STEP(controller, state, t)
        finally:
            sys.setprofile(None)
            if collecting:
                gc.enable()
            self.counts.append(n)
            self.names.append(names)

    def worst(self):
        k = int(np.argmax(self.counts[1:])) + 1
        return self.counts[k], dict(self.names[k].most_common(8))


_ORIGINAL_STEP = WholeBodyController.step


def _profiler_is_free():
    return sys.getprofile() is None  # coverage or a debugger would count itself


@pytest.mark.parametrize("robot_name", ["g1", "talos", "paper-humanoid"])
def test_the_standing_controller_steps_with_at_most_20_python_calls(robot_name):
    """The README's controller, every default, standing then pushed (150 N, 0.1 s).

    Every step after the first (which builds the engine) stays within the limit: the
    feasibility report's conflicts (the posture yields at every step), the push's torque
    limits and the clipping of the command included.
    """
    if not _profiler_is_free():
        pytest.skip("another profiler is installed")
    robot = hqp.robots.load(robot_name)
    controller = hqp.standing_controller(robot)
    sim = hqp.Simulator(robot)
    counter = _Counter()
    statuses = set()
    for k in range(800):
        command = counter.step(controller, sim.state(), k * sim.dt)
        statuses.update(s.status.value for s in command.report.tasks)
        force = np.array([150.0, 0.0, 0.0]) if 300 <= k < 400 else None
        sim.step(command.tau, force=force)
    assert not sim.fallen()
    assert "conflict" in statuses  # the report's conflict path ran
    assert controller.native.steps == 800  # every step was the core's
    worst, names = counter.worst()
    assert worst <= LIMIT, f"{worst} Python calls in a step: {names}"


LIBRARY = ["stand", "reach", "squat-jump", "walk", "mimic", "screwgun"]


@pytest.mark.slow
@pytest.mark.parametrize("behavior", LIBRARY)
def test_the_library_behaviors_step_with_few_python_calls(behavior, monkeypatch):
    """Every library behavior on its own robot: at most 20 calls in most steps.

    Every step within 20 is the issue's target and is not met yet: a step where a task
    ramps in or a contact unloads advances the stack in Python (about 40-70 calls), a step
    whose task set changed rebuilds the engine (hundreds to thousands), a step on a
    trajectory samples it in Python (21-26). Those steps are an expected failure with
    their measured count, until the ramps, blends and trajectories run in the core.
    """
    if not _profiler_is_free():
        pytest.skip("another profiler is installed")
    from hqp.app.run import run_behavior

    counter = _Counter()
    monkeypatch.setattr(WholeBodyController, "step",
                        lambda self, state, t: counter.step(self, state, t))
    run = run_behavior(behavior, duration=4.0)
    assert not run.fell, run.fall_reason
    counts = np.array(counter.counts[1:])
    assert len(counts) >= 3000
    assert np.median(counts) <= LIMIT
    assert np.mean(counts <= LIMIT) >= 0.5
    worst, names = counter.worst()
    if worst > LIMIT:
        pytest.xfail(f"{behavior}: {np.mean(counts > LIMIT):.0%} of the steps above {LIMIT} "
                     f"Python calls, the worst {worst}: {names}")
