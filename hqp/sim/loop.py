"""The closed loop: sense -> controller step -> torques -> MuJoCo step, with its fall check.

Every closed-loop run of hqp goes through :func:`closed_loop` (:func:`hqp.sim.simulate`, the
behavior runs of ``hqp run``, the recorder of :mod:`hqp.bench.record`). One control step per
simulation step:

1. apply the timed :class:`Event` s that are due;
2. read the state (pinocchio convention) and MuJoCo's floor contacts;
3. optional measurement noise and delay (:class:`Noise`), then ``controller.step(state, t)``;
4. ``before_step`` hook (logging, rendering, capture), then torques and the forces of the
   active :class:`Push` es go to MuJoCo, which steps;
5. ``after_step`` hook with the contacts at the new state, then the fall check of
   :meth:`~hqp.sim.simulator.Simulator.fall_reason`.
"""

from __future__ import annotations

import collections
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.model import RobotState
from hqp.sim.simulator import ContactReading, Simulator

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Push:
    """A horizontal (or any) force on the floating base during an interval.

    Attributes:
        t: Start [s].
        force: World force ``(3,)`` [N] applied at the base body's centre of mass.
        duration: Length of the push [s].

    """

    t: float
    force: tuple[float, float, float]
    duration: float = 0.1


@dataclass(frozen=True)
class Event:
    """A callable run once at a time: ``action(sim, controller, t)``.

    Use it to move goals, add or remove tasks, make or release contacts.

    Attributes:
        t: Time [s] at which it runs (at the first control step with ``time >= t``).
        action: The callable.
        name: A label for the log.

    """

    t: float
    action: Callable[[Simulator, Any, float], None]
    name: str = ""


@dataclass(frozen=True)
class Noise:
    """Gaussian measurement noise added to the state the controller sees.

    Attributes:
        q_std: Standard deviation on actuated joint positions [rad] and base position [m].
        v_std: Standard deviation on every velocity [rad/s or m/s].
        seed: Seed of the generator (runs are deterministic).

    """

    q_std: float = 0.0
    v_std: float = 0.0
    seed: int = 0


class Steppable(Protocol):
    """What the loop drives: a controller, or a behavior on its controller."""

    def step(self, state: RobotState, t: float) -> Any:
        """Return the command (with ``tau`` ``(na,)`` [N m]) for the state at time ``t``."""


@dataclass(frozen=True)
class Step:
    """One control step, as the hooks see it.

    Attributes:
        k: Step index (from 0).
        t: Control time [s].
        state: True state the step started from (before noise and delay).
        reading: MuJoCo's floor contacts at that state.
        command: The controller's command.
        wall_time: Wall-clock duration of ``step`` [s].

    """

    k: int
    t: float
    state: RobotState
    reading: ContactReading
    command: Any
    wall_time: float


@dataclass
class Outcome:
    """How a closed loop ended.

    Attributes:
        steps: Control steps run.
        t_end: Simulated time reached [s] (after the last step).
        fell_at: Control time of the step after which the robot had fallen (``None``: never).
        fall_reason: Why (:meth:`~hqp.sim.simulator.Simulator.fall_reason`).
        events: ``(t, name)`` of the events applied.
        wall_time: Wall-clock duration of the whole loop [s]: controller, MuJoCo, the hooks.

    """

    steps: int = 0
    t_end: float = 0.0
    fell_at: float | None = None
    fall_reason: str | None = None
    events: list[tuple[float, str]] = field(default_factory=list)
    wall_time: float = 0.0

    @property
    def fell(self) -> bool:
        """Whether the robot fell."""
        return self.fell_at is not None

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second of the loop (0 before any step)."""
        return self.t_end / self.wall_time if self.wall_time > 0.0 else 0.0


class _Sensor:
    """Measurement noise and delay of the state the controller sees."""

    def __init__(self, noise: Noise | None, delay_steps: int) -> None:
        self.noise = noise
        self.delay_steps = delay_steps
        self.rng = np.random.default_rng(noise.seed if noise is not None else 0)
        self.buffer: collections.deque[RobotState] = collections.deque(maxlen=delay_steps + 1)

    def __call__(self, state: RobotState, t: float) -> RobotState:
        if self.noise is None and self.delay_steps == 0:
            return state
        self.buffer.append(state if self.noise is None else self._noisy(state))
        return replace(self.buffer[0], t=t)

    def _noisy(self, state: RobotState, nq_base: int = 7) -> RobotState:
        noise = self.noise
        assert noise is not None
        q = state.q.copy()
        v = state.v.copy()
        if noise.q_std > 0.0:
            q[:3] += self.rng.normal(scale=noise.q_std, size=3)
            q[nq_base:] += self.rng.normal(scale=noise.q_std, size=q.size - nq_base)
        if noise.v_std > 0.0:
            v += self.rng.normal(scale=noise.v_std, size=v.size)
        return replace(state, q=q, v=v)


def push_force(pushes: Sequence[Push], t: float) -> np.ndarray | None:
    """Sum of the forces of the pushes active at time ``t`` ``(3,)`` [N] (``None``: none)."""
    if not pushes:
        return None
    force = np.zeros(3)
    for p in pushes:
        if p.t <= t < p.t + p.duration:
            force += np.asarray(p.force, dtype=float)
    return force if np.any(force) else None


def check_run(duration: float, delay_steps: int, where: str) -> None:
    """Check a run's duration [s] (> 0) and measurement delay [steps] (>= 0).

    Raises:
        InvalidInput: Either is out of range (the message starts with ``where``).

    """
    if not np.isfinite(duration) or duration <= 0.0:
        raise InvalidInput(f"{where}: duration must be positive, got {duration}")
    if delay_steps < 0:
        raise InvalidInput(f"{where}: delay_steps must be >= 0, got {delay_steps}")


def closed_loop(
    sim: Simulator,
    controller: Steppable,
    duration: float,
    events: Sequence[Event | Push] = (),
    *,
    noise: Noise | None = None,
    delay_steps: int = 0,
    before_step: Callable[[Step], None] | None = None,
    after_step: Callable[[Step, ContactReading], None] | None = None,
    clock: str = "simulator",
    stop_on_fall: bool = True,
    progress: Callable[[float], None] | None = None,
) -> Outcome:
    """Run ``controller`` on ``sim`` for ``duration`` [s] (see the module docstring).

    Args:
        sim: The simulator, in its initial state.
        controller: Anything with ``step(state, t) -> command``.
        duration: Simulated duration [s].
        events: Pushes and timed callables.
        noise: Measurement noise (default none).
        delay_steps: Measurement delay in steps (>= 0).
        before_step: Called after the controller's step, before MuJoCo's.
        after_step: Called after MuJoCo's step with the contacts at the new state.
        clock: Control time of step ``k``: ``"simulator"`` (MuJoCo's accumulated time) or
            ``"steps"`` (``k * dt`` exactly, the clock of the behavior runs).
        stop_on_fall: End at the first fall.
        progress: Called with the control time every 100 steps.

    Raises:
        InvalidInput: Non-positive duration, negative delay, a push force not ``(3,)``,
            unknown clock.

    """
    check_run(duration, delay_steps, "closed loop")
    if clock not in ("simulator", "steps"):
        raise InvalidInput(f"closed loop: clock must be 'simulator' or 'steps', got {clock!r}")
    timed = sorted([e for e in events if isinstance(e, Event)], key=lambda e: e.t)
    pushes = [e for e in events if isinstance(e, Push)]
    for p in pushes:
        check_array(p.force, (3,), "closed loop: push force")
    sense = _Sensor(noise, delay_steps)
    sensed = sense if noise is not None or delay_steps else None
    outcome = Outcome()
    next_event, n_timed = 0, len(timed)
    next_t = timed[0].t if timed else np.inf
    steps_clock = clock == "steps"
    hooked = before_step is not None or after_step is not None
    dt = sim.dt
    perf_counter = time.perf_counter
    controller_step = controller.step
    sim_step, sim_contacts, sim_state = sim.step, sim.contacts, sim.state
    fall_reason = sim.fall_reason
    reading = sim_contacts()
    k = -1
    step: Step | None = None
    loop_start = perf_counter()
    for k in range(int(round(duration / dt))):
        t = k * dt if steps_clock else sim.time
        if next_t <= t + 1e-12:
            while next_event < n_timed and timed[next_event].t <= t + 1e-12:
                ev = timed[next_event]
                ev.action(sim, controller, t)
                outcome.events.append((t, ev.name or f"event {next_event}"))
                next_event += 1
            next_t = timed[next_event].t if next_event < n_timed else np.inf
            reading = sim_contacts()
        state = sim_state(reading)
        if hooked:
            w0 = perf_counter()
            command = controller_step(state if sensed is None else sensed(state, t), t)
            step = Step(k, t, state, reading, command, perf_counter() - w0)
            if before_step is not None:
                before_step(step)
        else:
            command = controller_step(state if sensed is None else sensed(state, t), t)
        before = sim.time
        sim_step(command.tau, push_force(pushes, t) if pushes else None)
        reading = sim_contacts()
        if after_step is not None:
            after_step(step, reading)  # type: ignore[arg-type]
        # MuJoCo resets a diverging simulation (state and time back to the start): the run
        # has failed there, not started again
        reason = ("the simulation diverged (MuJoCo reset its state)" if sim.time < before
                  else fall_reason(reading))
        if reason is not None and outcome.fell_at is None:
            outcome.fell_at, outcome.fall_reason = t, reason
            logger.info("t=%.3f: fell (%s)", t, reason)
            if stop_on_fall:
                break
        if progress is not None and k % 100 == 0:
            progress(t)
    outcome.steps = k + 1
    outcome.t_end = (k + 1) * dt if steps_clock else sim.time
    outcome.wall_time = perf_counter() - loop_start
    return outcome
