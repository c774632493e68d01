"""Presets: the one standing constraint set and the one registry of controllers by name.

:func:`constraint_stack` builds the constraint levels every standing controller shares
(physics with both soles as contacts; contact and actuation limits; joint limits: the viable
bounds for HQP, the papers' activation zones for the null-space law); :func:`standing_stack`
adds the standing tasks. :data:`CONTROLLERS` maps a name (``hqp``, ``nullspace``) to how that
controller is assembled over a stack; the command line, the behaviors, the comparisons and the
benchmarks all build their controllers through it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from hqp.control.nullspace.law import EIG_TOL
from hqp.control.nullspace.resolver import NullSpaceController
from hqp.control.servo import MAX_TORQUE_RATE, WORK_BUDGET, Controller, WholeBodyController
from hqp.errors import InvalidGain, InvalidInput, UnknownName
from hqp.model.layout import ContactType
from hqp.stack import Stack
from hqp.tasks.base import Category, Task
from hqp.tasks.centroidal import CentroidalMomentumTask
from hqp.tasks.com import CoMTask, support_center
from hqp.tasks.contact import Contact
from hqp.tasks.dynamics import FloatingBaseDynamics
from hqp.tasks.joint_limit_zone import JointLimitZone
from hqp.tasks.joint_limits import JointLimits, SupportBraking, max_acceleration_from_torques
from hqp.tasks.orientation import OrientationTask
from hqp.tasks.posture import PostureTask
from hqp.tasks.torque_limits import TorqueLimits

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.robots import Robot

JOINT_LIMITS = ("viable", "zones", "none")
"""Joint-limit handling of :func:`constraint_stack`: viable acceleration bounds (inequalities,
HQP), the papers' activation zones (equalities, the null-space law), or none."""

STANDING_TASKS = (CoMTask, OrientationTask, PostureTask, CentroidalMomentumTask)
"""Task types :func:`standing_stack` adds above the constraint levels."""


def feet_contacts(robot: Robot, model: RobotModel, *, friction: float | None = None,
                  sole_margin: float = 0.9, kd: float = 0.0) -> list[Task]:
    """Return the two sole contacts as every standing controller declares them.

    Args:
        robot: The bundled robot.
        model: Its controller model.
        friction: Friction coefficient of the contact model (default: 0.8 x the sole's).
        sole_margin: Fraction of the sole's half-length and half-width given to the centre
            of pressure.
        kd: Damping of the contacts' drift stabilisation [1/s].

    """
    contacts: list[Task] = []
    for foot in robot.feet:
        surface = robot.contact(foot)
        mu = 0.8 * surface.friction if friction is None else friction
        contacts.append(Contact(
            foot, surface.frame, ContactType.SURFACE, mu=mu,
            half_length=sole_margin * surface.half_length,
            half_width=sole_margin * surface.half_width, kd=kd, model=model,
        ))
    return contacts


def viable_joint_limits(robot: Robot, model: RobotModel,
                        max_joint_acceleration: float = 50.0,
                        approach_time: float = 0.0) -> JointLimits:
    """Return the viable joint limits of the standing controllers (model at the standing pose).

    The bound on ``|qdd|`` is the fixed-base torque estimate clipped to
    ``[5, max_joint_acceleration]`` rad/s^2; the braking assumption is the smaller of half of
    it and what the supports allow (:class:`~hqp.tasks.joint_limits.SupportBraking`,
    all-or-none); a joint that moves its side of the robot alone gets a recovery deceleration
    (what its torque limit gives that side beyond its weight's largest torque, at most the
    fixed-base estimate) for states thrown past its braking curve; velocity bounds are
    approached over 20 ms, the braking curve over ``approach_time`` (opt-in; 0.02 s is the
    measured choice). Why these choices (and what was
    measured against the alternatives): docs/design/control.md, "The standing joint limits".
    """
    fixed_base = max_acceleration_from_torques(model, margin=0.5)
    qdd_max = np.clip(fixed_base, 5.0, max_joint_acceleration)
    feet = [robot.contact(foot).frame for foot in robot.feet]
    braking = SupportBraking(model, feet, 0.5 * qdd_max, margin=0.5, per_contact=False)
    # Recovery: a joint that moves its side alone (an arm, a wrist, the trunk) may brake an
    # overspeed at what its torque limit gives that side beyond its weight's largest torque,
    # and the other joints' torque limits the reaction (the fixed-base estimate, unclipped);
    # joints braked through the soles keep the reserve.
    alone = np.minimum(fixed_base, max_acceleration_from_torques(
        model, margin=0.5, supports=feet, worst_weight=True))
    recovery = np.where(alone > qdd_max, alone, 0.0)
    # Velocity bounds approached over 20 ms rather than in one step (no torque step when a
    # joint reaches its velocity limit); the braking curve over approach_time.
    return JointLimits(qdd_max=qdd_max, braking=braking, reserve=2.0, recovery=recovery,
                       velocity_time=0.02, approach_time=approach_time)


def papers_joint_limits(
    stack: Stack, *, zone: float = 0.1, gains: tuple[float, float] = (400.0, 40.0)
) -> None:
    """Replace the stack's viable joint limits by the papers' activation zones (in place).

    Every :class:`~hqp.tasks.joint_limits.JointLimits` task is removed and one
    :class:`~hqp.tasks.joint_limit_zone.JointLimitZone` is placed on the JOINT_LIMITS level
    (the first level with equality rows below the physics, i.e. the top of the task
    hierarchy, seed 003 eq. 12 and 25). The change is made before the first step (no blend).

    Args:
        stack: The stack to change.
        zone: Width of the activation zones [rad].
        gains: ``(kp, kv)`` of the zones' PD law (eq. 27).

    """
    for task in list(stack.tasks):
        if isinstance(task, JointLimits):
            stack.remove(task.name)
    stack.pop_events()
    stack.add(JointLimitZone(zone=zone, kp=gains[0], kv=gains[1]), _joint_limit_level(stack))


def _joint_limit_level(stack: Stack) -> Category | int:
    return Category.JOINT_LIMITS if Category.JOINT_LIMITS in stack.level_categories else 1


def constraint_stack(
    robot: Robot,
    model: RobotModel,
    *,
    levels: Sequence[str | Category] | None = None,
    ramp_time: float = 0.6,
    friction: float | None = None,
    sole_margin: float = 0.9,
    torque_scale: float = 1.0,
    contact_kd: float = 0.0,
    joint_limits: str | Task = "viable",
    max_joint_acceleration: float = 50.0,
    braking_approach_time: float = 0.0,
    zone: float = 0.1,
    zone_gains: tuple[float, float] = (400.0, 40.0),
) -> tuple[Stack, list[Task]]:
    """Build the constraint levels of a humanoid on both feet, and its sole contacts.

    Physics (floating-base dynamics; the contacts, declared by the controller); contact and
    actuation limits (torque limits here, friction and centre of pressure with the contacts);
    joint limits (``joint_limits``: one of :data:`JOINT_LIMITS` or a task of the caller's).
    The model is updated at the standing configuration.

    Args:
        robot: The bundled robot (feet, contact surfaces, ``q_standing``).
        model: Its controller model.
        levels: Levels of the stack (default: one per category).
        ramp_time: Default ramp of tasks added at runtime [s].
        friction: Friction coefficient of the contact model (default: 0.8 x the sole's).
        sole_margin: Fraction of the sole's half sizes given to the centre of pressure.
        torque_scale: Fraction of the torque limits the controller may use.
        contact_kd: Damping of the contacts' drift stabilisation [1/s].
        joint_limits: ``"viable"`` (:func:`viable_joint_limits`), ``"zones"`` (a
            :class:`~hqp.tasks.joint_limit_zone.JointLimitZone` of ``zone``, ``zone_gains``),
            ``"none"``, or a task to put on the JOINT_LIMITS level.
        max_joint_acceleration: Upper clip of the viable joint-acceleration bound [rad/s^2]
            (>= 5).
        braking_approach_time: Time over which a viable bound approaches the braking curve
            [s] (``JointLimits(approach_time=...)``; 0: none).
        zone: Width of the activation zones [rad].
        zone_gains: ``(kp, kv)`` of the zones' PD law (eq. 27).

    Returns:
        ``(stack, contacts)``; pass both to a controller of :data:`CONTROLLERS`.

    Raises:
        InvalidGain: ``max_joint_acceleration`` below 5 or not finite.
        InvalidInput: Unknown ``joint_limits``.

    """
    if not (np.isfinite(max_joint_acceleration) and max_joint_acceleration >= 5.0):
        raise InvalidGain(f"standing_stack: max_joint_acceleration must be finite and >= 5 "
                          f"rad/s^2, got {max_joint_acceleration}")
    if not isinstance(joint_limits, Task) and joint_limits not in JOINT_LIMITS:
        raise InvalidInput(f"constraint_stack: joint_limits must be a task or one of "
                           f"{JOINT_LIMITS}, got {joint_limits!r}")
    model.update(robot.q_standing, np.zeros(model.nv))
    stack = Stack(levels, ramp_time=ramp_time)
    stack.add(FloatingBaseDynamics(), Category.PHYSICS)
    contacts = feet_contacts(robot, model, friction=friction, sole_margin=sole_margin,
                             kd=contact_kd)
    stack.add(TorqueLimits(scale=torque_scale), Category.CONTACT_LIMITS)
    if isinstance(joint_limits, Task):
        stack.add(joint_limits, _joint_limit_level(stack))
    elif joint_limits == "viable":
        stack.add(viable_joint_limits(robot, model, max_joint_acceleration,
                                      braking_approach_time),
                  _joint_limit_level(stack))
    elif joint_limits == "zones":
        stack.add(JointLimitZone(zone=zone, kp=zone_gains[0], kv=zone_gains[1]),
                  _joint_limit_level(stack))
    return stack, contacts


def add_standing_tasks(
    stack: Stack,
    robot: Robot,
    model: RobotModel,
    *,
    com_kp: float = 100.0,
    orientation_kp: float = 100.0,
    posture_kp: float = 50.0,
    angular_momentum_weight: float = 1e-3,
    angular_momentum_gain: float = 10.0,
    redundancy_damping: float = 0.0,
    redundancy_damping_gain: float = 10.0,
) -> None:
    """Add the standing tasks: centre of mass over the feet, angular momentum, trunk, posture.

    The model must be updated at the standing configuration (:func:`constraint_stack` does).
    See :func:`standing_stack` for the arguments.
    """
    com = CoMTask(model, kp=com_kp)
    centre = support_center(model, list(robot.feet))
    com.set_goal(np.array([centre[0], centre[1], model.com[2]]))
    stack.add(com)
    if angular_momentum_weight > 0.0:
        stack.add(CentroidalMomentumTask(model, "angular", name="angular_momentum",
                                         weight=angular_momentum_weight,
                                         gain=angular_momentum_gain))
    trunk = OrientationTask(model, "trunk", kp=orientation_kp)
    trunk.set_goal(model.frame_placement("trunk").rotation.copy())
    stack.add(trunk)
    if redundancy_damping > 0.0:
        damping = PostureTask(model, name="damping", weight=redundancy_damping, kp=0.0,
                              kv=redundancy_damping_gain)
        damping.set_configuration(robot.q_standing, model)
        stack.add(damping, Category.OPERATIONAL)
    posture = PostureTask(model, kp=posture_kp)
    posture.set_configuration(robot.q_standing, model)
    stack.add(posture)


def standing_stack(
    robot: Robot,
    model: RobotModel,
    *,
    com_kp: float = 100.0,
    orientation_kp: float = 100.0,
    posture_kp: float = 50.0,
    friction: float | None = None,
    sole_margin: float = 0.9,
    torque_scale: float = 1.0,
    contact_kd: float = 0.0,
    angular_momentum_weight: float = 1e-3,
    angular_momentum_gain: float = 10.0,
    ramp_time: float = 0.6,
    max_joint_acceleration: float = 50.0,
    braking_approach_time: float = 0.0,
    redundancy_damping: float = 0.0,
    redundancy_damping_gain: float = 10.0,
) -> tuple[Stack, list[Task]]:
    """Build the stack of a humanoid standing on both feet, and its contacts.

    Levels (default categories): physics (floating-base dynamics, both soles as rigid surface
    contacts); contact and actuation limits (friction pyramids, unilateral forces, centre of
    pressure in the soles, yaw torques, torque limits); viable joint limits (acceleration bound:
    the fixed-base torque estimate clipped to [5, 50] rad/s^2 by default; braking: what the
    supports allow, see the comments below); balance (centre of mass over the centre of the
    feet at its standing height, and, weighted in the same level, damping of the centroidal
    angular momentum); operational (trunk orientation upright as in the standing
    configuration); posture (the standing configuration).

    The angular-momentum damping matters when the centre-of-mass task asks for more than the
    support gives (a goal moved faster than the centre of pressure can follow): the centre of
    mass can then still be accelerated by turning the body (arms, trunk), which a level holding
    the centre of mass alone does without bound, flailing the arms at their velocity limits and
    switching their acceleration bounds from step to step. With a small weight the trade only
    happens in that case: when both are feasible both are met exactly.

    Args:
        robot: The bundled robot (feet, contact surfaces, ``q_standing``, ``trunk`` frame).
        model: Its controller model.
        com_kp: Stiffness of the centre-of-mass task [1/s^2] (critical damping).
        orientation_kp: Stiffness of the trunk orientation task [1/s^2].
        posture_kp: Stiffness of the posture task [1/s^2].
        friction: Friction coefficient of the contact model (default: 0.8 x the sole's).
        sole_margin: Fraction of the sole's half-length and half-width given to the centre
            of pressure (a margin against tipping on the edge).
        torque_scale: Fraction of the torque limits the controller may use.
        contact_kd: Damping of the contacts' drift stabilisation [1/s].
        angular_momentum_weight: Weight of the angular-momentum damping in the balance level
            (the centre-of-mass task has weight 1; rows in [N m] against [m/s^2]); 0 leaves
            it out.
        angular_momentum_gain: Its damping [1/s].
        ramp_time: Default ramp of tasks added at runtime [s] (goal ramps from zero error; a
            min-jerk goal move of ``d`` over ``T`` asks for a peak feed-forward acceleration
            of ``5.8 d / T^2``).
        max_joint_acceleration: Upper clip of the joint-acceleration bound [rad/s^2] (>= 5;
            the bound is the fixed-base torque estimate clipped to ``[5, this]``; the
            braking assumption is half of it, or what the active supports allow).
        braking_approach_time: Time over which the joint-limit bounds approach the braking
            curve [s] (0: the discrete bound alone; 0.02 is the measured choice,
            docs/design/control.md).
        redundancy_damping: Weight of a joint damping ``qdd = -d v`` (a posture task named
            ``damping`` with ``kp = 0``) inside the operational level (0: none). A task of
            that level whose goal is out of reach leaves a residual that its least squares
            spends along the directions it barely controls (``1 / sigma`` per unit of
            residual); the damping regularises that level (damped least squares) without
            moving its equilibria (it asks nothing at rest). Opt-in: docs/design/control.md, "An
            unreachable goal".
        redundancy_damping_gain: Its damping ``d`` [1/s].

    Returns:
        ``(stack, contacts)``; pass both to :class:`~hqp.control.servo.WholeBodyController`.

    """
    stack, contacts = constraint_stack(
        robot, model, ramp_time=ramp_time, friction=friction, sole_margin=sole_margin,
        torque_scale=torque_scale, contact_kd=contact_kd,
        max_joint_acceleration=max_joint_acceleration,
        braking_approach_time=braking_approach_time)
    add_standing_tasks(stack, robot, model, com_kp=com_kp, orientation_kp=orientation_kp,
                       posture_kp=posture_kp, angular_momentum_weight=angular_momentum_weight,
                       angular_momentum_gain=angular_momentum_gain,
                       redundancy_damping=redundancy_damping,
                       redundancy_damping_gain=redundancy_damping_gain)
    return stack, contacts


# ------------------------------------------------------------------------------------------------
# Controllers by name
# ------------------------------------------------------------------------------------------------


def _hqp(model: RobotModel, contacts: Sequence[Task], stack: Stack,
         **options: Any) -> WholeBodyController:
    return WholeBodyController(model, contacts, stack, **options)


def _nullspace(model: RobotModel, contacts: Sequence[Task], stack: Stack,
               **options: Any) -> NullSpaceController:
    options.pop("backend", None)  # the law has no QP backend
    options.pop("algorithm", None)
    return NullSpaceController(model, contacts, stack, **options)


@dataclass(frozen=True)
class ControllerKind:
    """How a controller of the registry is assembled.

    Attributes:
        joint_limits: The joint-limit handling of its constraint levels (:data:`JOINT_LIMITS`).
        build: ``(model, contacts, stack, **options) -> Controller`` (options: the
            controller's keyword arguments).
        torque_rate: Whether it takes the servo's torque-rate level (``max_torque_rate``;
            the HQP resolver only: the null-space law has no inequality levels).

    """

    joint_limits: str
    build: Callable[..., Controller]
    torque_rate: bool = False


CONTROLLERS: dict[str, ControllerKind] = {
    "hqp": ControllerKind("viable", _hqp, torque_rate=True),
    "nullspace": ControllerKind("zones", _nullspace),
}
"""The controllers by name: the strict hierarchy of QPs, the papers' null-space law."""

CONTROLLER_NAMES: tuple[str, ...] = tuple(CONTROLLERS)
"""Names accepted by :func:`make_controller` and :func:`make_standing_controller`."""


def controller_kind(name: str) -> ControllerKind:
    """Return a controller of the registry by name.

    Raises:
        UnknownName: Another name (lists the valid ones).

    """
    try:
        return CONTROLLERS[name]
    except KeyError:
        raise UnknownName("controller", name, CONTROLLER_NAMES) from None


def make_controller(kind: str, model: RobotModel, contacts: Sequence[Task], stack: Stack,
                    **options: Any) -> Controller:
    """Assemble the controller ``kind`` over a stack and its contacts.

    Args:
        kind: One of :data:`CONTROLLER_NAMES`.
        model: The controller's robot model.
        contacts: Contacts to declare.
        stack: The levels of tasks.
        **options: Keyword arguments of the controller (``backend`` and ``algorithm`` are
            ignored by the null-space law).

    Raises:
        UnknownName: Another kind.

    """
    return controller_kind(kind).build(model, contacts, stack, **options)


def standing_controller(
    robot: Robot,
    *,
    dt: float = 0.001,
    backend: str | None = None,
    algorithm: str = "basis",
    diagnostics: str = "full",
    native: bool | None = None,
    max_torque_rate: float | None = MAX_TORQUE_RATE,
    work_budget: int | None = WORK_BUDGET,
    **gains: float,
) -> WholeBodyController:
    """Build a :class:`~hqp.control.servo.WholeBodyController` standing on both feet.

    See :func:`standing_stack` for the levels and ``gains``.

    Args:
        robot: The bundled robot (``hqp.robots.load(name)``).
        dt: Control period [s].
        backend: QP backend (``None``: the native step, see ``WholeBodyController``).
        algorithm: ``"basis"`` or ``"cascade"``.
        diagnostics: ``"full"`` or ``"residuals"`` (see ``WholeBodyController``).
        native: Steady steps on the native step (see ``WholeBodyController``; ``None``: where
            it applies).
        max_torque_rate: The servo's torque-rate level [N m/s] (see ``WholeBodyController``;
            default :data:`~hqp.control.servo.MAX_TORQUE_RATE`, 4 N m per 1 ms step;
            ``None``: none).
        work_budget: Work budget of the native step's solve (see ``WholeBodyController``;
            default :data:`~hqp.control.servo.WORK_BUDGET`; ``None``: unbounded).
        **gains: Keyword arguments of :func:`standing_stack`.

    """
    model = robot.model()
    stack, contacts = standing_stack(robot, model, **gains)
    return WholeBodyController(model, contacts, stack, dt=dt, backend=backend,
                               algorithm=algorithm, diagnostics=diagnostics, native=native,
                               max_torque_rate=max_torque_rate, work_budget=work_budget)


def standing_nullspace_controller(
    robot: Robot,
    *,
    dt: float = 0.001,
    backend: str | None = None,
    algorithm: str = "basis",
    diagnostics: str = "full",
    joint_limit_zones: bool = True,
    zone: float = 0.1,
    zone_gains: tuple[float, float] = (400.0, 40.0),
    eig_tol: float = EIG_TOL,
    internal_forces: str = "min-norm",
    support_zone: float | None = None,
    torque_zone: float | None = None,
    ramp_time: float = 0.6,
    friction: float | None = None,
    sole_margin: float = 0.9,
    torque_scale: float = 1.0,
    contact_kd: float = 0.0,
    max_joint_acceleration: float = 50.0,
    **gains: float,
) -> NullSpaceController:
    """Build a :class:`~hqp.control.nullspace.NullSpaceController` standing on both feet.

    Same arguments as :func:`standing_controller` (``backend`` and ``algorithm`` are accepted
    and unused) and the same stack (:func:`standing_stack`), except that the viable joint
    limits, which are inequalities, are the papers' activation zones. Friction,
    centre-of-pressure and torque limits stay in the stack: reported, not enforced.

    Args:
        robot: The bundled robot (``hqp.robots.load(name)``).
        dt: Control period [s].
        backend: Unused (call compatibility).
        algorithm: Unused (call compatibility).
        diagnostics: ``"full"`` or ``"residuals"``.
        joint_limit_zones: Use activation zones (``False``: no joint-limit handling at all,
            the case the HQP design is about).
        zone: Width of the activation zones [rad].
        zone_gains: ``(kp, kv)`` of the zones' PD law.
        eig_tol: Relative eigenvalue threshold of eq. 22.
        internal_forces: ``"min-norm"``, ``"balanced"`` or ``"none"``.
        support_zone: Support activation zone (``NullSpaceController``; ``None``: off).
        torque_zone: Torque activation zone (``NullSpaceController``; ``None``: off).
        ramp_time: See :func:`standing_stack`.
        friction: See :func:`standing_stack`.
        sole_margin: See :func:`standing_stack`.
        torque_scale: See :func:`standing_stack`.
        contact_kd: See :func:`standing_stack`.
        max_joint_acceleration: See :func:`standing_stack` (checked, unused by the zones).
        **gains: The standing tasks' keyword arguments of :func:`standing_stack`.

    """
    model = robot.model()
    stack, contacts = constraint_stack(
        robot, model, ramp_time=ramp_time, friction=friction, sole_margin=sole_margin,
        torque_scale=torque_scale, contact_kd=contact_kd,
        joint_limits="zones" if joint_limit_zones else "none",
        max_joint_acceleration=max_joint_acceleration, zone=zone, zone_gains=zone_gains)
    add_standing_tasks(stack, robot, model, **gains)
    return NullSpaceController(model, contacts, stack, dt=dt, diagnostics=diagnostics,
                               eig_tol=eig_tol, internal_forces=internal_forces,
                               support_zone=support_zone, torque_zone=torque_zone)


def make_standing_controller(kind: str, robot: Robot, **kwargs: Any) -> Controller:
    """Build the standing controller ``kind`` (``"hqp"`` or ``"nullspace"``) by name.

    Args:
        kind: One of :data:`CONTROLLER_NAMES`.
        robot: The bundled robot.
        **kwargs: Arguments of :func:`standing_controller` (both) and of
            :func:`standing_nullspace_controller` (``"nullspace"`` only).

    Raises:
        UnknownName: Another name (lists the valid ones).

    """
    controller_kind(kind)
    if kind == "nullspace":
        return standing_nullspace_controller(robot, **kwargs)
    return standing_controller(robot, **kwargs)


def constraint_controller(
    kind: str,
    robot: Robot,
    *,
    dt: float = 0.001,
    diagnostics: str = "residuals",
    backend: str | None = None,
    max_joint_acceleration: float | None = None,
    max_torque_rate: float | None = MAX_TORQUE_RATE,
) -> Controller:
    """Build a controller holding only the constraint levels of a humanoid on both feet.

    What a behavior starts from: the stack of :func:`standing_stack` (its ``ramp_time``
    included) without the standing tasks; the behavior writes its own task sets. Joint limits
    are the kind's (:attr:`ControllerKind.joint_limits`).

    Args:
        kind: One of :data:`CONTROLLER_NAMES`.
        robot: The bundled robot.
        dt: Control period [s].
        diagnostics: ``"residuals"`` (per-task residuals, cheap) or ``"full"``.
        backend: QP backend of the HQP controller (``None``: its default).
        max_joint_acceleration: Clip of the viable joint-acceleration bounds [rad/s^2]
            (``None``: the default; the null-space law has activation zones instead).
        max_torque_rate: The HQP servo's torque-rate level [N m/s] (default
            :data:`~hqp.control.servo.MAX_TORQUE_RATE`; ``None``: none; ignored by a kind
            without one, :attr:`ControllerKind.torque_rate`).

    Raises:
        UnknownName: Unknown controller.

    """
    preset = controller_kind(kind)
    model = robot.model()
    limits: dict[str, Any] = {}
    if max_joint_acceleration is not None and preset.joint_limits == "viable":
        limits["max_joint_acceleration"] = max_joint_acceleration
    stack, contacts = constraint_stack(robot, model, joint_limits=preset.joint_limits,
                                       **limits)
    options: dict[str, Any] = {} if backend is None else {"backend": backend}
    if preset.torque_rate:
        options["max_torque_rate"] = max_torque_rate
    return preset.build(model, contacts, stack, dt=dt, diagnostics=diagnostics, **options)
