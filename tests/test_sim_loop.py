"""The one closed loop (hqp.sim.loop): clock, events, pushes, noise and delay, hooks, falls.

A recording controller (no QP) stands in for the servo: these tests check the loop itself.
"""

from __future__ import annotations

import numpy as np
import pytest

import hqp.robots as robots
from hqp.controller import Command, FeasibilityReport
from hqp.errors import InvalidInput
from hqp.sim import Event, Noise, Push, Simulator, closed_loop
from hqp.sim.loop import push_force


class Recorder:
    """Zero torques; remembers what it saw."""

    def __init__(self, na: int) -> None:
        self.na = na
        self.seen: list[tuple[float, np.ndarray, float]] = []

    def step(self, state, t):
        self.seen.append((t, state.q.copy(), state.t))
        return Command(np.zeros(self.na), np.zeros(self.na + 6), {}, FeasibilityReport())


@pytest.fixture(scope="module")
def robot():
    return robots.load("paper-humanoid")


def test_clocks_and_hooks(robot):
    for clock in ("simulator", "steps"):
        sim = Simulator(robot)
        ctrl = Recorder(sim.na)
        before, after = [], []
        out = closed_loop(sim, ctrl, 0.01, clock=clock,
                          before_step=lambda step: before.append(step.k),
                          after_step=lambda step, reading: after.append(reading))
        assert out.steps == 10 and not out.fell and before == list(range(10)) and len(after) == 10
        ts = [t for t, _, _ in ctrl.seen]
        if clock == "steps":
            assert ts == [k * sim.dt for k in range(10)]  # exactly k dt
        else:
            np.testing.assert_allclose(ts, np.arange(10) * sim.dt, atol=1e-12)
        assert out.t_end == pytest.approx(0.01)


def test_realtime_factor_is_simulated_over_wall_time(robot):
    """The loop's wall clock covers the controller, MuJoCo and the hooks."""
    import time

    sim = Simulator(robot)
    nap = 2e-3  # a hook that sleeps 2 ms per 1 ms step: the run is at most half real time

    out = closed_loop(sim, Recorder(sim.na), 0.02, before_step=lambda step: time.sleep(nap))
    assert out.wall_time >= 20 * nap
    assert 0.0 < out.realtime_factor <= 0.5
    assert out.realtime_factor == pytest.approx(out.t_end / out.wall_time)


def test_a_simulation_mujoco_resets_ends_as_a_failure(robot):
    """MuJoCo resets a diverging simulation (time back to 0): the loop reports it, stops."""
    sim = Simulator(robot)
    real_step = sim.step
    count = [0]

    def diverging(tau, force=None):
        real_step(tau, force)
        count[0] += 1
        if count[0] == 5:
            sim.mj_data.time = 0.0  # what mj_step does after a bad acceleration

    sim.step = diverging
    out = closed_loop(sim, Recorder(sim.na), 0.02)
    assert out.fell and "diverged" in out.fall_reason and out.steps == 5


def test_events_run_once_at_their_time_and_pushes_add_up(robot):
    sim = Simulator(robot)
    fired = []
    events = [Event(0.0035, lambda s, c, t: fired.append(t), "late"),
              Event(0.001, lambda s, c, t: fired.append(t))]
    out = closed_loop(sim, Recorder(sim.na), 0.006, events)
    np.testing.assert_allclose(fired, [0.001, 0.004], atol=1e-12)
    assert [name for _, name in out.events] == ["event 0", "late"]
    pushes = [Push(0.1, (10.0, 0.0, 0.0), 0.1), Push(0.15, (0.0, 5.0, 0.0), 0.1)]
    assert push_force(pushes, 0.05) is None
    np.testing.assert_allclose(push_force(pushes, 0.16), [10.0, 5.0, 0.0])
    with pytest.raises(InvalidInput):
        closed_loop(sim, Recorder(sim.na), 0.01, [Push(0.0, (1.0, 2.0), 0.1)])  # type: ignore[arg-type]


def test_delay_and_noise(robot):
    sim = Simulator(robot)
    truth = []
    ctrl = Recorder(sim.na)
    closed_loop(sim, ctrl, 0.005, delay_steps=2,
                before_step=lambda step: truth.append(step.state.q.copy()))
    for k, (t, q, t_state) in enumerate(ctrl.seen):
        np.testing.assert_array_equal(q, truth[max(k - 2, 0)])  # measured two steps earlier
        assert t_state == t  # stamped with the control time
    sim = Simulator(robot)
    ctrl = Recorder(sim.na)
    closed_loop(sim, ctrl, 0.002, noise=Noise(q_std=1e-3, seed=3),
                before_step=lambda step: truth.append(step.state.q.copy()))
    assert not np.array_equal(ctrl.seen[0][1], truth[-2])
    with pytest.raises(InvalidInput):
        closed_loop(sim, ctrl, 0.01, delay_steps=-1)
    with pytest.raises(InvalidInput):
        closed_loop(sim, ctrl, 0.0)
    with pytest.raises(InvalidInput):
        closed_loop(sim, ctrl, 0.01, clock="wall")


def test_a_fall_ends_the_loop_with_its_reason(robot):
    sim = Simulator(robot)
    q = robot.q_standing.copy()
    q[2] = 0.3  # pelvis far below 0.6 x standing height: fallen from the first step
    sim.reset(q)
    out = closed_loop(sim, Recorder(sim.na), 0.05)
    assert out.fell and out.steps == 1 and out.fell_at == 0.0
    assert out.fall_reason is not None and out.fall_reason == sim.fall_reason()
    sim.reset(q)
    out = closed_loop(sim, Recorder(sim.na), 0.005, stop_on_fall=False)
    assert out.fell and out.steps == 5
