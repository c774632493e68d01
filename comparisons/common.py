"""Pieces shared by the scenarios: controllers over a stack, standing setup, the recorder.

A scenario describes its hierarchy as a list of levels of named tasks (after
the constraint levels). :func:`make_controller` turns it into a controller:

- ``hqp``: :class:`hqp.control.WholeBodyController`; constraint sub-levels
  first (physics: floating-base dynamics and the feet; contact and actuation
  limits: friction, centre of pressure, torque limits; the servo's torque-rate
  level, :data:`MAX_TORQUE_RATE`; joint limits: the viable bounds of
  :class:`hqp.tasks.joint_limits.JointLimits`; collision), then the scenario's
  levels.
- ``nullspace``: :class:`hqp.control.NullSpaceController`; the law has no
  inequalities, so joint limits are the papers' activation zones
  (:class:`hqp.tasks.joint_limit_zone.JointLimitZone`) on the top task level,
  and torque and friction limits are not enforced.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from hqp.control import presets
from hqp.control.servo import MAX_TORQUE_RATE
from hqp.model import RobotModel, RobotState
from hqp.robots import Robot, load
from hqp.sim.run import Log, simulate
from hqp.sim.simulator import CONTACT_MODES, Simulator, inside_polygon
from hqp.stack import Stack
from hqp.tasks.base import Category, Task
from hqp.tasks.com import support_center
from hqp.tasks.joint_limits import JointLimits, max_acceleration_from_torques

DT = 1e-3
"""Control and simulation period [s]."""

JOINT_LIMIT_MARGIN = 0.25
"""Fraction of the single-joint deceleration estimate
(:func:`hqp.tasks.joint_limits.max_acceleration_from_torques`) used as the
constant braking acceleration ``A`` of the viable joint-limit bounds. With
0.5 (the standing controllers' value) the hand-reach squat needed more
torque than the limits allow to brake several joints at once under the
body's weight: the torque-limit level (above) won and the knees and hips
went past their limits in MuJoCo."""
JOINT_VELOCITY_SCALE = 0.5
"""Fraction of the model's joint velocity limits used by the viable bounds."""

BACKEND = "native"
"""QP backend of the HQP controller in the scenarios: the native step (the default
controller's). A level QP that fails sends the solve to a second pass absorbing the carried
rows active over the optimal sets above, so the scenarios run without safe-mode steps.

The servo's torque-rate level (:data:`MAX_TORQUE_RATE`, the presets' default) is on: it
keeps the scenarios' per-step torque changes at its band where the levels in conflict
switch their active bounds (figures with their command: docs/results/experiments.md)."""


@dataclass
class Hierarchy:
    """The scenario's own levels (below the constraint levels), highest first.

    Attributes:
        levels: ``(level name, tasks)`` pairs.
        collision: Tasks of the collision sub-level (obstacle avoidance).

    """

    levels: list[tuple[str, list[Task]]]
    collision: list[Task] = field(default_factory=list)


def standing_setup(name: str) -> tuple[Robot, RobotModel, np.ndarray]:
    """Load a robot, its controller model updated at the standing configuration, the feet centre.

    Returns:
        ``(robot, model, feet)`` with ``feet`` the centre of the soles ``(3,)`` [m] in the world.

    """
    robot = load(name)
    model = robot.model()
    model.update(robot.q_standing, np.zeros(model.nv))
    return robot, model, support_center(model, list(robot.feet))


def feet_contacts(robot: Robot, model: RobotModel) -> list[Task]:
    """Return the two sole contacts, as the standing controllers declare them.

    Friction ``0.8 x`` the sole's, centre of pressure within ``0.9 x`` the sole
    (:func:`hqp.control.presets.feet_contacts`).
    """
    return presets.feet_contacts(robot, model)


def braking_acceleration(robot: Robot, model: RobotModel) -> np.ndarray:
    """Constant braking acceleration of the joint-limit bounds, per actuated joint [rad/s^2].

    :data:`JOINT_LIMIT_MARGIN` of the support-aware single-joint estimate at the
    standing posture; the HQP stack and PlaCo's ``qdd_safe`` use the same values.
    """
    model.update(robot.q_standing, np.zeros(model.nv))
    return max_acceleration_from_torques(model, margin=JOINT_LIMIT_MARGIN,
                                         supports=list(robot.feet))


def build_stack(robot: Robot, model: RobotModel, hierarchy: Hierarchy) -> Stack:
    """Constraint sub-levels, then the scenario's levels (module docstring).

    The constraint levels are :func:`hqp.control.presets.constraint_stack`'s, with the
    scenarios' viable joint limits (:func:`braking_acceleration`, :data:`JOINT_VELOCITY_SCALE`)
    and the stack's default ramp time; the contacts are declared by :func:`make_controller`.
    """
    names = [name for name, _ in hierarchy.levels]
    limits = JointLimits(qdd_max=braking_acceleration(robot, model),
                         velocity_scale=JOINT_VELOCITY_SCALE)
    stack, _ = presets.constraint_stack(
        robot, model, levels=[Category.PHYSICS, Category.CONTACT_LIMITS, Category.JOINT_LIMITS,
                              Category.COLLISION, *names],
        ramp_time=Stack().ramp_time, joint_limits=limits)
    for task in hierarchy.collision:
        stack.add(task, Category.COLLISION)
    for name, tasks in hierarchy.levels:
        for task in tasks:
            stack.add(task, name)
    return stack


def make_controller(
    kind: str,
    robot: Robot,
    model: RobotModel,
    hierarchy: Hierarchy,
    *,
    zone: float = 0.1,
    zone_gains: tuple[float, float] = (400.0, 40.0),
) -> Any:
    """Build the controller ``kind`` over the scenario's hierarchy.

    Both controllers get the same stack (:func:`build_stack`); for the
    null-space law the viable joint limits are replaced by the papers'
    activation zones (:func:`hqp.control.presets.papers_joint_limits`), and its
    inequality rows (friction, torque limits, obstacle distances) are
    reported, not enforced.

    Args:
        kind: ``"hqp"`` or ``"nullspace"``.
        robot: The robot.
        model: The controller's model.
        hierarchy: The scenario's levels.
        zone: Width of the null-space law's joint-limit activation zones [rad].
        zone_gains: ``(kp, kv)`` of the activation-zone PD law.

    Raises:
        UnknownName: Another kind.

    """
    preset = presets.controller_kind(kind)
    stack = build_stack(robot, model, hierarchy)
    options: dict[str, Any] = {"backend": BACKEND}
    if preset.torque_rate:
        options["max_torque_rate"] = MAX_TORQUE_RATE
    if kind == "nullspace":
        presets.papers_joint_limits(stack, zone=zone, gains=zone_gains)
        options = {}
    return presets.make_controller(kind, model, feet_contacts(robot, model), stack, dt=DT,
                                   diagnostics="residuals", **options)


def kinematic_rollout(
    controller: Any,
    model: RobotModel,
    q0: np.ndarray,
    duration: float,
    on_step: Callable[[float, np.ndarray, np.ndarray, Any], None] | None = None,
) -> None:
    """Integrate the controller's accelerations without a simulator (for tuning and tests).

    Semi-implicit Euler on the manifold: ``v += dt qdd``, ``q = q (+) dt v``.
    """
    q = q0.copy()
    v = np.zeros(model.nv)
    n = int(round(duration / DT))
    for k in range(n):
        t = k * DT
        cmd = controller.step(RobotState(q, v, t), t)
        if on_step is not None:
            on_step(t, q, v, cmd)
        v = v + DT * cmd.qdd
        q = model.integrate(q, DT * v)


@dataclass
class Support:
    """The support wrenches of a run, read from MuJoCo at every logged step.

    Attributes:
        foot_wrench: Wrench of the world on each foot ``(N, nfeet, 6)`` (force, torque about
            the foot site, world-aligned) [N, N m]
            (:meth:`hqp.sim.simulator.Simulator.foot_wrenches`).
        sole_cop: Centre of pressure of each foot in its sole frame ``(N, nfeet, 2)`` [m]
            (``nan`` where the normal force is at most 1 % of the weight).
        sole_half: Half length and half width of each sole ``(nfeet, 2)`` [m].
        commanded_margin: Signed distance of the centre of pressure of the contact wrenches
            the controller commanded (:attr:`hqp.controller.Command.wrenches`) inside the
            convex hull of the soles ``(N,)`` [m] (negative: outside; ``nan`` where they pull
            or carry nothing), ``None`` for a controller that reports no wrenches (PlaCo).

    """

    foot_wrench: np.ndarray
    sole_cop: np.ndarray
    sole_half: np.ndarray
    commanded_margin: np.ndarray | None = None


def commanded_margin(robot: Robot, corners: np.ndarray, wrenches: Any,
                     weight: float) -> float | None:
    """Signed distance of the commanded support's centre of pressure inside the soles' hull [m].

    Args:
        robot: The robot (its feet name the contacts).
        corners: Sole corners of the feet in the world ``(nfeet, 4, 3)`` [m].
        wrenches: The command's wrenches by contact name (world-aligned ``[f; tau]`` at the
            sole centre).
        weight: The robot's weight [N].

    Returns:
        ``None`` when the command has no wrench for a foot; ``nan`` when the total normal
        force is at most 1 % of the weight (a pulling or vanishing support).

    """
    if not wrenches or any(np.size(wrenches.get(f, ())) != 6 for f in robot.feet):
        return None
    fz, moment = 0.0, np.zeros(2)
    for foot, c in zip(robot.feet, corners):
        w = np.asarray(wrenches[foot], dtype=float)
        p = c.mean(axis=0)
        fz += w[2]
        moment += w[2] * p[:2] + np.array([-w[4], w[3]])
    if fz <= 0.01 * weight:
        return float("nan")
    return inside_polygon(moment / fz, corners.reshape(-1, 3)[:, :2])


class ControllerRun(NamedTuple):
    """What :func:`run_controller` returns: log, note, support, the controller's own figures.

    ``metrics``: a peer's worker figures (its step and round-trip times), else empty.
    """

    log: Log
    note: str
    support: Support
    metrics: dict[str, Any]


def run_controller(
    spec_controller: str,
    robot: Robot,
    model: RobotModel,
    hierarchy: Hierarchy,
    duration: float,
    progress: Callable[[str], None],
    *,
    events: Sequence[Any] = (),
    wrap: Callable[[Any], Any] | None = None,
    zone: float = 0.1,
    contacts: str = CONTACT_MODES[0],
    torque_scale: float = 1.0,
) -> ControllerRun:
    """Simulate one controller over a hierarchy in MuJoCo.

    Args:
        spec_controller: ``"hqp"``, ``"nullspace"`` or ``"placo"``.
        robot: The robot.
        model: The controller's model.
        hierarchy: The scenario's levels.
        duration: Simulated time [s].
        progress: Receives progress messages.
        events: Timed events of :func:`hqp.sim.run.simulate`.
        wrap: Wraps the controller before the run (e.g. to move obstacles with time).
        zone: Activation-zone width of the null-space law [rad].
        contacts: ``"unilateral"`` (MuJoCo's floor contacts) or ``"welded"`` (the papers'
            rigid feet; :class:`hqp.sim.simulator.Simulator`).
        torque_scale: Factor on the torque limits of the controller's model and the
            simulator's motors (1: the robot's; the seed papers' simulations had none).

    Returns:
        The simulator's log, a note on what the controller cannot express ("" if nothing),
        the support wrenches, and the controller's own metrics (PlaCo: its worker's figures,
        :meth:`comparisons.placo_runner.PlacoController.metrics`; the log's step times are
        then the step's own, the pipe not counted).

    Raises:
        InvalidInput: Unknown contact mode.
        PeerUnavailable: ``placo`` without PlaCo's environment (the message says how to
            make it).

    """
    note = ""
    peer: Any = None
    if torque_scale != 1.0:
        model.tau_max = model.tau_max * float(torque_scale)
    if spec_controller == "placo":
        from comparisons.placo_runner import PlacoController, placo_note

        controller: Any = PlacoController(robot, hierarchy)
        peer = controller
        note = placo_note(controller, hierarchy)
    else:
        controller = make_controller(spec_controller, robot, model, hierarchy, zone=zone)
        if spec_controller == "nullspace":
            note = ("the null-space law has no inequalities: friction, centre of pressure and "
                    "torque limits are reported, not enforced; joint limits are the papers' "
                    "activation zones")
            if hierarchy.collision:
                note += "; obstacle-avoidance rows are not enforced"
    own: dict[str, Any] = {}
    try:
        log, wrenches, cops, margins = _closed_loop(robot, controller, duration, events,
                                                    progress, wrap, contacts, model.tau_max)
        if peer is not None:
            log.step_time = np.asarray(peer.step_time[: log.t.size])
            own = peer.metrics()
    finally:
        if peer is not None:
            peer.close()
    nfeet = len(robot.feet)
    half = np.array([[robot.contact(f).half_length, robot.contact(f).half_width]
                     for f in robot.feet])
    margin = (None if any(m is None for m in margins)
              else np.array(margins, dtype=float))
    support = Support(np.array(wrenches).reshape(-1, nfeet, 6),
                      np.array(cops).reshape(-1, nfeet, 2), half, margin)
    return ControllerRun(log, note, support, own)


def _closed_loop(robot: Robot, controller: Any, duration: float, events: Sequence[Any],
                 progress: Callable[[str], None], wrap: Callable[[Any], Any] | None,
                 contacts: str, tau_max: np.ndarray
                 ) -> tuple[Log, list[np.ndarray], list[np.ndarray], list[float | None]]:
    """Simulate a controller (wrapped first) in MuJoCo; the log and the support per step."""
    if wrap is not None:
        controller = wrap(controller)
    last = [-1.0]

    def tick(t: float) -> None:
        if t - last[0] >= 0.5 - 1e-9:
            last[0] = t
            progress(f"  t = {t:.1f} s")

    sim = Simulator(robot, dt=DT, contacts=contacts, torque_limits=tau_max)
    wrenches: list[np.ndarray] = []
    cops: list[np.ndarray] = []
    margins: list[float | None] = []

    def record(s: Simulator, command: Any) -> None:
        w = s.foot_wrenches()
        wrenches.append(w)
        cops.append(s.sole_cops(w))
        margins.append(commanded_margin(robot, s.sole_corners(),
                                        getattr(command, "wrenches", None), s.weight))

    log = simulate(robot, controller, duration, events, sim=sim, progress=tick, on_step=record)
    return log, wrenches, cops, margins
