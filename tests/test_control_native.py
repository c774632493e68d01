"""The controller on the native step (``WholeBodyController(native=...)``) against the Python step.

The default controller of a bundled robot runs its steady steps natively: these tests hold its
command and feasibility report equal to the Python step's (the same solver, ``backend="native"``)
on calm sequences, at conflicts, through ramps, contact releases and tasks without a kernel.
"""

from __future__ import annotations

import numpy as np
import pytest

from hqp import robots
from hqp.control.presets import standing_controller
from hqp.errors import InvalidInput
from hqp.model import RobotState

pytest.importorskip("hqp._core._ext")


def _pair(name: str, diagnostics: str = "full", **options):
    """The default standing controller on the native step and on the Python step.

    ``max_torque_rate=None`` (the degenerate cases: levels in conflict) leaves the servo's
    torque-rate level out: its bounds follow each path's previous torques, so two QP points
    of equal costs at one step become two different problems at the next; its mirror is
    held to the Python level in tests/test_core_step.py.
    """
    robot = robots.load(name)
    native = standing_controller(robot, diagnostics=diagnostics, **options)
    python = standing_controller(robot, backend="native", native=False, diagnostics=diagnostics,
                                 **options)
    assert native.native is not None and python.native is None
    return robot, native, python


def _states(robot, model, count: int, seed: int, scale: float = 0.003):
    """A calm sequence: from standing to a perturbed state, then held."""
    rng = np.random.default_rng(seed)
    q1 = robot.q_standing.copy()
    q1[7:] += rng.normal(scale=scale, size=model.na)
    v1 = rng.normal(scale=0.01, size=model.nv)
    for i in range(count):
        s = min(1.0, i / 5.0)
        q = (1 - s) * robot.q_standing + s * q1
        q[3:7] /= np.linalg.norm(q[3:7])
        yield 0.001 * i, RobotState(q, s * v1)


def _same_command(a, b, what: str, tol: float = 1e-7, sigma_tol: float = 1e-8,
                  conflict_sigma: bool = True) -> None:
    """Same torques and residuals (to ``tol`` of the largest), statuses, levels yielded to,
    projected singular values (to ``sigma_tol``; for tasks in conflict only with
    ``conflict_sigma``, else a level yielded to must be at or above the task's)."""
    np.testing.assert_allclose(a.tau, b.tau, rtol=0, atol=tol * max(1.0, np.abs(b.tau).max()),
                               err_msg=f"{what}: tau")
    assert [(s.name, s.level) for s in a.report.tasks] == \
        [(s.name, s.level) for s in b.report.tasks], what
    for sa, sb in zip(a.report.tasks, b.report.tasks):
        assert sa.status == sb.status, (what, sa, sb)
        if conflict_sigma:
            assert sa.yields_to == sb.yields_to, (what, sa, sb)
        else:  # a level yielded to is at or above the task's
            for st in (sa, sb):
                assert st.yields_to is None or st.yields_to <= st.level, (what, sa, sb)
        assert abs(sa.residual - sb.residual) <= tol * max(1.0, sb.residual), (what, sa, sb)
        if sb.status.value == "conflict" and not conflict_sigma:
            continue
        if np.isfinite(sb.sigma_min):
            assert abs(sa.sigma_min - sb.sigma_min) <= sigma_tol * max(1.0, sb.sigma_min), (
                what, sa, sb)
        else:
            assert not np.isfinite(sa.sigma_min), (what, sa, sb)
    np.testing.assert_allclose(a.report.level_costs, b.report.level_costs, rtol=max(1e-6, tol),
                               atol=1e-12, err_msg=what)


def _same_optimum(nat, py, a, b, what: str, **tols) -> bool:
    """The command of a step that may be degenerate: where a level above the last has
    ``sigma_min`` below 1e-6 in the Python step's solution (its optimum not a continuous
    function of the data: levels 1e-10 apart, or two warm starts' histories, reach optima
    far apart), each level's cost at the two points within the solver contract's
    ``1e-6 * max(1, cost)`` (returns False); elsewhere :func:`_same_command` (returns True)."""
    from hqp.bench.accuracy import level_costs

    sol = py.last_solution
    degenerate = sol is not None and any(
        lv.sigma_min < 1e-6 for lv in sol.levels[:-1] if np.isfinite(lv.sigma_min))
    if not degenerate:
        _same_command(a, b, what, **tols)
        return True
    levels = py.last_built.levels
    ca, cb = level_costs(levels, nat.last_x), level_costs(levels, py.last_x)
    np.testing.assert_array_less(np.abs(ca - cb), 1e-6 * np.maximum(1.0, cb) + 1e-12,
                                 err_msg=f"{what}: level costs")
    return False


def _same_levels(nat, py, what: str, tol: float = 1e-10) -> None:
    """The levels of the last native step (copied out on demand) equal the Python step's rows
    (finite entries, to ``tol`` of each matrix's largest)."""
    built_n, built_p = nat.last_built, py.last_built
    assert built_n.level_index == built_p.level_index, what
    for la, lb in zip(built_n.levels, built_p.levels):
        for key in ("A", "b", "C", "lower", "upper"):
            va, vb = getattr(la, key), getattr(lb, key)
            assert (va is None) == (vb is None), (what, key)
            if vb is not None and np.size(vb):
                f = np.isfinite(vb)
                np.testing.assert_array_equal(np.isfinite(va), f, err_msg=f"{what}: {key}")
                np.testing.assert_allclose(np.asarray(va)[f], np.asarray(vb)[f], rtol=0,
                                           atol=tol * max(1.0, np.abs(vb[f]).max(initial=0)),
                                           err_msg=f"{what}: {key}")


def _same_errors(nat, py, what: str, tol: float = 1e-9) -> None:
    """Every task's ``error()`` after the step, as the Python step leaves it."""
    for task in py.stack.tasks:
        a, b = nat.task(task.name).error(), task.error()
        assert a.shape == b.shape, (what, task.name, a, b)
        np.testing.assert_allclose(a, b, rtol=0, atol=tol * max(1.0, np.abs(b).max(initial=0)),
                                   err_msg=f"{what}: {task.name}.error()")


def _add_hand(ctrl, state, frame, offset, ramp_time, t=None):
    """Add a position task holding ``frame`` at ``offset`` [m] from where it is at ``state``,
    ramped in over ``ramp_time`` [s] from ``t`` (``None``: the last step's time)."""
    from hqp.tasks.position import PositionTask

    task = PositionTask(ctrl.model, frame, name="hand")
    ctrl.model.update(state.q, state.v)
    task.set_goal(ctrl.model.frame_placement(frame).translation + np.asarray(offset))
    ctrl.add_task(task, "operational", t=t, ramp_time=ramp_time)


@pytest.mark.parametrize("name", robots.NAMES)
@pytest.mark.parametrize("diagnostics", ["full", "residuals"])
def test_native_controller_equals_the_python_step(name, diagnostics):
    robot, nat, py = _pair(name, diagnostics)
    for t, state in _states(robot, nat.model, 10, seed=7):
        a, b = nat.step(state, t), py.step(state, t)
        _same_command(a, b, f"{name} {diagnostics} t={t}")
        _same_errors(nat, py, f"{name} {diagnostics} t={t}")
        assert a.timings["rows"] == 0.0 or t == 0.0  # native steps build no Python rows
    assert nat.native.steps >= 9  # the first step captures the contacts' references
    # the levels of a native step, copied out on demand, are the Python step's
    built_n, built_p = nat.last_built, py.last_built
    assert built_n.level_index == built_p.level_index
    for la, lb in zip(built_n.levels, built_p.levels):
        for key in ("A", "b", "C", "lower", "upper"):
            va, vb = getattr(la, key), getattr(lb, key)
            assert (va is None) == (vb is None), key
            if vb is not None:
                f = np.isfinite(vb)
                np.testing.assert_allclose(np.asarray(va)[f], np.asarray(vb)[f], atol=1e-10)


@pytest.mark.parametrize("name", ["g1", "talos"])
def test_a_conflict_is_reported_as_the_python_step_reports_it(name):
    """A centre-of-mass goal far outside the support: the same statuses and levels yielded to.

    In conflict the levels hold QP points, found by the same solver along different
    warm-start paths: torques agree to 1e-5 of the largest (the solver contract's accuracy),
    not to the calm sequences' 1e-7. The projected singular values and the levels yielded
    to of the tasks in conflict are not compared: both depend on which inequality rows sit
    on their bounds at the point, which the 1e-6 differences of the point decide (g1's
    angular momentum: sigma 1.1e-4 and 9.4e-5 at the same state, and at t = 5 ms yielding
    to level 2 on one path and 1 on the other; CONFLICT on both, as the status says).
    """
    robot, nat, py = _pair(name, max_torque_rate=None)
    for ctrl in (nat, py):
        com = ctrl.task("com")
        goal = np.array(com.goal_at(0.0).position, dtype=float)
        goal[0] += 0.4
        com.set_goal(goal)
    conflicts = 0
    for t, state in _states(robot, nat.model, 6, seed=8):
        a, b = nat.step(state, t), py.step(state, t)
        _same_command(a, b, f"{name} t={t}", tol=1e-5, sigma_tol=1e-6, conflict_sigma=False)
        conflicts += sum(s.status.value == "conflict" for s in a.report.tasks)
    assert conflicts > 0


def test_ramps_and_unloading_run_natively_and_other_changes_on_the_python_step():
    """A task ramping in and a contact unloading run on the native step (the ramp offsets
    recorded from the kernel's rows, the contact's normal-force bound pushed down each step)
    with the Python step's commands, and so does the release's blend event (a decaying
    offset, started before the native solve); a task without a kernel runs on the Python
    step."""
    from _h5_standins import PostureStandIn

    robot, nat, py = _pair("g1", "residuals", max_torque_rate=None)  # degenerate steps
    states = list(_states(robot, nat.model, 400, seed=9))
    hand = robot.hands[1]
    strict = 0
    for k, (t, state) in enumerate(states):
        if k == 20:
            for ctrl in (nat, py):
                _add_hand(ctrl, state, hand, [0.02, 0.0, 0.0], ramp_time=0.05)
            before = nat.native.steps
        if k == 60:
            assert nat.native.steps - before == 40  # the ramp (and its goal ramp): native
            for ctrl in (nat, py):
                ctrl.deactivate_contact("left_foot", unload_time=0.05)
            before = nat.native.steps
        if k == 200:
            # the unloading natively, the release's blend event too
            assert nat.native.steps - before == 140
        # the hand's ramp and the contact's release move the robot: QP points, as in conflict
        before_step = nat.native.steps
        strict += _same_optimum(nat, py, nat.step(state, t), py.step(state, t), f"t={t}",
                                tol=1e-5, sigma_tol=1e-6, conflict_sigma=False)
        if 20 <= k < 60:  # the ramp natively: its rows (offsets at x_prev) the Python step's
            assert nat.native.steps == before_step + 1
            _same_levels(nat, py, f"t={t}", tol=1e-9)
        _same_errors(nat, py, f"t={t}", tol=1e-6)
    assert strict >= 0.8 * len(states)  # the command compared at most steps
    assert nat.native.unsupported is None
    for ctrl in (nat, py):  # a task written in Python (no kernel): the Python step
        ctrl.add_task(PostureStandIn("own_posture", robot.q_standing, weight=1e-2), "posture",
                      ramp_time=0.0)
    steps = nat.native.steps
    t, state = states[-1]
    _same_command(nat.step(state, t + 0.001), py.step(state, t + 0.001), "own task", tol=1e-5,
                  sigma_tol=1e-6, conflict_sigma=False)
    assert nat.native.steps == steps and "no native kernel" in nat.native.unsupported


@pytest.mark.parametrize("name", ["g1", "talos"])
def test_the_torque_blend_after_a_release_runs_natively(name):
    """A foot released at once: the decaying-offset torque blend after the release (the
    stack's blend_time, strictness suspended) runs on the native step from its first step on
    (the release's event), with the Python step's levels and blended command
    (:func:`_same_optimum` where a step is degenerate; without the torque-rate level, see
    :func:`_pair`).

    Released at once, not unloaded first: an unloading's last steps are ill-conditioned (the
    normal-force bound falls to zero), the two paths' solver warm starts, 1e-14 apart at its
    start, end it 1.4e-4 N m apart on g1 (1e-5 of the largest torque; the rows equal), and the
    blend would carry that offset. The unloading is compared in the test above."""
    robot, nat, py = _pair(name, "residuals", max_torque_rate=None)
    states = list(_states(robot, nat.model, 260, seed=16, scale=0.001))
    foot = robot.feet[0]
    contact = next(c.name for c in nat.layout.contacts if c.frame == foot)
    blend = strict = native = 0
    for k, (t, state) in enumerate(states):
        if k == 20:
            for ctrl in (nat, py):
                ctrl.deactivate_contact(contact, unload_time=0.0)
        before = nat.native.steps
        a, b = nat.step(state, t), py.step(state, t)
        ran_native = nat.native.steps == before + 1
        assert a.report.strictness_suspended == b.report.strictness_suspended, t
        native += ran_native
        if a.report.strictness_suspended:
            blend += 1
            _same_levels(nat, py, f"{name} t={t}")
        strict += _same_optimum(nat, py, a, b, f"{name} t={t}", tol=1e-6, sigma_tol=1e-6,
                                conflict_sigma=False)
    # every step natively, the release's event and the blend included
    assert native == len(states) and strict >= 0.8 * native
    assert blend >= round(nat.stack.blend_time / 0.001) - 1 > 0


def test_native_needs_a_bundled_robot_model():
    from hqp.control.servo import WholeBodyController
    from hqp.model import RobotModel

    robot = robots.load("g1")
    model = RobotModel(robot.pinocchio_model(), name="custom")
    assert WholeBodyController(model).native is None  # the Python step, silently
    with pytest.raises(InvalidInput, match="native=True"):
        WholeBodyController(model, native=True)


def test_a_task_written_in_python_runs_on_the_python_path():
    """The example of docs/design/control.md ("The native step"), run as written."""
    import re
    from pathlib import Path

    text = Path(__file__).resolve().parents[1].joinpath("docs", "design", "control.md").read_text()
    block = re.search(r"A task of your own.*?```python\n(.*?)```", text, re.S)
    assert block is not None
    scope: dict = {}
    exec(compile(block.group(1), "docs/design/control.md", "exec"), scope)  # noqa: S102
    controller = scope["controller"]
    assert "no native kernel" in controller.native.unsupported
    assert controller.native.steps == 0
    status = {s.name: s for s in controller.last_built.spans}
    assert "joint_damping" in status


def test_the_contact_force_regularisation_runs_natively():
    """ForceRegularization (constant rows of the layout, walk's lowest level) on the native
    step: the same command and report as the Python step."""
    from hqp.tasks.effort import ForceRegularization

    robot, nat, py = _pair("talos")
    for ctrl in (nat, py):
        ctrl.add_task(ForceRegularization(ctrl.model, weight=1e-3), "posture", ramp_time=0.0)
    for t, state in _states(robot, nat.model, 8, seed=12):
        _same_command(nat.step(state, t), py.step(state, t), f"t={t}")
        _same_errors(nat, py, f"t={t}")
    assert nat.native.unsupported is None and nat.native.steps >= 7


def test_a_native_step_runs_one_pinocchio_pass():
    """The Python model's pass waits for a reader after a native step (the core ran its own);
    read, it gives the Python step's quantities at the same state."""
    robot, nat, py = _pair("g1", "residuals")
    for t, state in _states(robot, nat.model, 4, seed=13):
        nat.step(state, t)
        py.step(state, t)
    assert nat.native.steps >= 3
    assert nat.model._pending and not py.model._pending  # no second pass unless read
    for name in ("M", "h", "com", "com_velocity", "com_jacobian", "centroidal_matrix",
                 "gravity"):
        np.testing.assert_array_equal(getattr(nat.model, name), getattr(py.model, name))
    assert not nat.model._pending
    frame = robot.hands[1]
    np.testing.assert_array_equal(nat.model.frame_jacobian(frame), py.model.frame_jacobian(frame))


def test_the_centre_of_mass_is_read_from_the_native_pass():
    """After a native step the Python model's centre of mass and its velocity (what behaviors
    read every step) come from the core's pass at the same state: no second pinocchio pass,
    the Python pass's values; the next update forgets them."""
    robot, nat, py = _pair("g1", "residuals")
    for t, state in _states(robot, nat.model, 4, seed=13):
        nat.step(state, t)
        py.step(state, t)
        if nat.native.steps:
            for name in ("com", "com_velocity"):
                np.testing.assert_allclose(getattr(nat.model, name), getattr(py.model, name),
                                           rtol=0, atol=1e-12)
            assert nat.model._pending  # read without the Python pass
            with pytest.raises(ValueError):  # the core's values, read only
                nat.model.com[0] = 0.0
    assert nat.native.steps >= 3
    q = robot.q_standing.copy()
    q[7] += 0.1
    nat.model.update(q, np.zeros(nat.model.nv), defer=True)
    py.model.update(q, np.zeros(py.model.nv))
    np.testing.assert_array_equal(nat.model.com, py.model.com)  # its own pass now
    assert not nat.model._pending


def _operational_tasks(robot, ctrl):
    """Gaze at a point ahead, a hand held in its pose, a foot's hybrid force/position rows,
    the feet's internal forces and a weighted effort term: (level, task) pairs."""
    from hqp.tasks.cop import CoPTask
    from hqp.tasks.effort import EffortTask
    from hqp.tasks.gaze import GazeTask
    from hqp.tasks.hybrid import HybridTask
    from hqp.tasks.internal_forces import InternalForcesTask
    from hqp.tasks.pose import PoseTask

    m = ctrl.model
    m.update(robot.q_standing, np.zeros(m.nv))
    head = robot.head_frame or robot.base_frame
    gaze = GazeTask(m, head, kp=25.0, max_velocity=1.0, max_acceleration=4.0)
    gaze.set_goal(m.frame_placement(head).act(np.array([1.5, 0.1, -0.4])))
    hand = robot.hands[0]
    pose = PoseTask(m, hand, kp=40.0, max_velocity=0.5)
    pose.set_goal(m.frame_placement(hand).homogeneous)
    feet = [c.name for c in ctrl.layout.contacts]
    foot = ctrl.layout.contact(feet[1])
    hybrid = HybridTask(m, foot.frame, foot.name, kp=20.0, weight=1e-2)
    hybrid.set_goal(m.frame_placement(foot.frame).homogeneous)
    hybrid.set_force([0.5 * m.mass * 9.81])
    cop = CoPTask(m, feet, name="cop", weight=1e-3)
    cop.set_goal(m.com[:2])
    return [("operational", gaze), ("operational", pose), ("operational", hybrid),
            ("operational", InternalForcesTask(m, feet)), ("posture", cop),
            ("posture", EffortTask(m, weight=1e-4))]


@pytest.mark.parametrize("name", robots.NAMES)
def test_operational_kernels_run_natively(name):
    """Gaze, pose, hybrid force/position, internal forces, CoP and effort on the native step: the
    same levels (1e-10) as the Python step, and the same command, report and task errors.
    The operational level's tasks conflict with one another (six tasks in conflict on g1):
    its points are QP points, found by the same solver along warm-start paths that rows
    equal to 1e-15 can still split (1.2e-7 of the largest torque at g1's t = 5 ms), so the
    command is held to the conflict tolerances (1e-5, as in the conflict test above)."""
    robot, nat, py = _pair(name, max_torque_rate=None)
    for ctrl in (nat, py):
        for level, task in _operational_tasks(robot, ctrl):
            ctrl.add_task(task, level, ramp_time=0.0)
    for t, state in _states(robot, nat.model, 10, seed=14):
        _same_command(nat.step(state, t), py.step(state, t), f"{name} t={t}", tol=1e-5,
                      sigma_tol=1e-6, conflict_sigma=False)
        _same_levels(nat, py, f"{name} t={t}")
        _same_errors(nat, py, f"{name} t={t}", tol=1e-6)
    assert nat.native.unsupported is None and nat.native.steps >= 9


@pytest.mark.parametrize("name", robots.NAMES)
def test_collision_kernels_run_natively(name):
    """Obstacle avoidance (a moving sphere near a hand) and self-collision pairs on the native
    step: the same levels (1e-10), command, report, margins and pair names as the Python step.
    Some of the pairs start inside their influence distance, so the constraint level is in
    conflict at a degenerate vertex (sigma_min 0): there optima far apart have the same costs
    (talos: 4.1e-3 N m apart from levels 1e-10 apart), and the command is held
    to the solver contract's costs (:func:`_same_optimum`)."""
    from hqp.model.world import Sphere, World
    from hqp.tasks.collision import ObstacleAvoidance, SelfCollision

    robot, nat, py = _pair(name, max_torque_rate=None)
    caps = list(robot.capsules)
    pairs = [(a, b) for i, a in enumerate(caps) for b in caps[i + 1:] if a.frame != b.frame]
    worlds = []
    for ctrl in (nat, py):
        ctrl.model.update(robot.q_standing, np.zeros(ctrl.model.nv))
        hand = ctrl.model.frame_placement(robot.hands[1]).translation
        world = World([Sphere("ball", hand + [0.25, -0.1, 0.0], 0.08,
                              velocity=[-0.3, 0.0, 0.0])])
        worlds.append(world)
        ctrl.add_task(ObstacleAvoidance("avoid", world, caps, d_safe=0.05, d_influence=0.3),
                      "joint_limits", ramp_time=0.0)
        ctrl.add_task(SelfCollision("self", pairs[:10], d_influence=0.15), "joint_limits",
                      ramp_time=0.0)
    finite = 0
    for t, state in _states(robot, nat.model, 10, seed=15):
        # the constraint level in conflict at a degenerate vertex: the contract's costs
        _same_optimum(nat, py, nat.step(state, t), py.step(state, t), f"{name} t={t}",
                      tol=1e-5, sigma_tol=1e-6, conflict_sigma=False)
        _same_levels(nat, py, f"{name} t={t}")
        _same_errors(nat, py, f"{name} t={t}", tol=1e-6)
        for task in ("avoid", "self"):
            assert nat.task(task).pair_names == py.task(task).pair_names
        finite += int(np.isfinite(py.last_built.rows["avoid"].lower).sum())
        for world in worlds:
            world.step(0.001)
    assert finite > 0  # the obstacle is within the rows' influence
    assert nat.native.unsupported is None and nat.native.steps >= 9


def test_a_failed_native_solve_is_solved_on_the_fallback_backend(monkeypatch):
    """A native step whose solve fails: the Python step of the same state solves it on the
    fallback backend (DAQP) first, not again on the same C++ solver, and says so."""
    robot, nat, _py = _pair("g1", "residuals")
    states = list(_states(robot, nat.model, 4, seed=3))
    for t, state in states[:3]:
        nat.step(state, t)
    mirror = nat.native.mirror
    assert mirror is not None and nat.native.steps >= 1

    def failing_step(q, v, t):
        raise RuntimeError("level 4: the native QP (DAQP) returned a non-finite solution")

    def primary_solve(*args, **kwargs):
        raise AssertionError("the failed native solve was solved again on the native solver")

    monkeypatch.setattr(mirror, "step", failing_step)
    monkeypatch.setattr(nat.resolver.solver, "solve", primary_solve)
    steps = nat.native.steps
    t, state = states[3]
    command = nat.step(state, t)
    assert nat.native.steps == steps and not command.safe_mode
    assert np.isfinite(command.tau).all()
    assert any("native step: level 4" in n and "'daqp'" in n for n in command.report.notes), \
        command.report.notes
    assert nat._native_failure is None  # consumed by this step
    monkeypatch.undo()
    t2, state2 = t + 0.001, states[3][1]
    assert not nat.step(state2, t2).report.notes  # the next step is native again, quiet
    assert nat.native.steps == steps + 1


def _change_posture_gain(c):
    c.task("posture").reference = type(c.task("posture").reference)(
        10.0, 2 * np.sqrt(10.0), np.inf, np.inf)


def _scale_torque_limits(c):
    task = c.task("torque_limits")
    task.tau_max = task.tau_max * 0.7  # (a new array: the task's own is read-only)


_CHANGES = {
    "weight": lambda c: setattr(c.task("trunk"), "weight", 7.0),
    "gains": _change_posture_gain,
    "friction": lambda c: setattr(c.task("left_foot"), "mu", 0.3),
    "torque_limits_scaled": _scale_torque_limits,
    "torque_scale": lambda c: setattr(c.task("torque_limits"), "scale", 0.8),
    "joint_limit_margin": lambda c: setattr(c.task("joint_limits"), "position_margin", 0.05),
}


@pytest.mark.parametrize("change", sorted(_CHANGES))
def test_a_parameter_changed_between_steps_rebuilds_the_native_step(change):
    """A task parameter set between two steps (by attribute) reaches the kernels: the next
    native step equals the Python step with the same change."""
    robot, nat, py = _pair("g1", "residuals")
    for c in (nat, py):  # an array of the task's own, changed below
        c.task("torque_limits").tau_max = c.model.tau_max
    states = list(_states(robot, nat.model, 8, seed=3))
    for t, state in states[:5]:
        nat.step(state, t), py.step(state, t)
    mirror = nat.native.mirror
    for c in (nat, py):
        _CHANGES[change](c)
    for t, state in states[5:]:
        a, b = nat.step(state, t), py.step(state, t)
        _same_command(a, b, f"{change} t={t}")
    assert nat.native.mirror is not mirror  # rebuilt
    assert a.timings["rows"] == 0.0  # and the steps after the change ran natively


@pytest.mark.parametrize("name", ["g1", "talos"])
def test_a_lazy_report_answers_conflicts_without_making_every_status(name):
    """``"residuals"`` diagnostics: the report's ``any_conflict``, ``names`` and ``conflicts()``
    (read first, from the step's residuals: only the conflicting statuses made) equal what its
    ``tasks``, made afterwards, give; on calm steps and with a centre-of-mass goal outside the
    support (tasks in conflict)."""
    from hqp.controller import Feasibility

    robot, nat, _py = _pair(name, "residuals", max_torque_rate=None)
    seen = 0
    for t, state in _states(robot, nat.model, 12, seed=17):
        if t == pytest.approx(0.006):
            com = nat.task("com")
            goal = np.array(com.goal_at(t).position, dtype=float)
            goal[0] += 0.4
            com.set_goal(goal)
        report = nat.step(state, t).report
        assert report._tasks is None  # nothing made yet
        any_conflict, names, conflicts = report.any_conflict, report.names, report.conflicts()
        assert report._tasks is None  # still nothing: the lazy answers
        tasks = report.tasks
        assert names == tuple(s.name for s in tasks)
        assert conflicts == [s for s in tasks if s.status is Feasibility.CONFLICT]
        assert any_conflict == bool(conflicts)
        seen += bool(conflicts)
    assert 0 < seen < 12


@pytest.mark.parametrize("name", ["g1", "talos"])
def test_error_norms_read_in_one_call_equal_each_tasks_error(name):
    """``hqp.control.native.error_norms`` (a behavior's per-step record): the norms of the
    errors waiting in a native step, read in one call, equal ``norm(task.error())`` of each
    task, on the native step and after a Python step (an operational task ramping in)."""
    from hqp.control.native import error_norms

    robot, nat, _py = _pair(name, "residuals")
    tasks = list(nat.stack.tasks)
    for k, (t, state) in enumerate(_states(robot, nat.model, 8, seed=18)):
        if k == 4:
            for level, task in _operational_tasks(robot, nat):
                nat.add_task(task, level, ramp_time=0.0)
            tasks = list(nat.stack.tasks)
        nat.step(state, t)
        got = error_norms(tasks)
        want = [np.linalg.norm(task.error()) if task.error().size else np.inf for task in tasks]
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15, err_msg=f"t={t}")
    assert nat.native.steps >= 6


def test_a_ramp_recorded_by_a_python_step_continues_natively():
    """A task added at the step a foot is made again: the contact's blend between two
    hierarchies runs on the Python step, which records the ramp's offsets from the Python
    rows; the native steps after the blend take them (``NativeStep.set_ramp_offsets``) and
    build the Python step's levels (to 1e-9)."""
    robot, nat, py = _pair("g1", "residuals", max_torque_rate=None)
    states = list(_states(robot, nat.model, 140, seed=19, scale=0.001))
    hand = robot.hands[0]
    contact = next(c.name for c in nat.layout.contacts if c.frame == robot.feet[0])
    blend_steps = round(nat.stack.blend_time / 0.001)
    ramped = python = 0
    for k, (t, state) in enumerate(states):
        if k == 10:
            for ctrl in (nat, py):
                ctrl.deactivate_contact(contact, unload_time=0.0)
        if k == 20:
            for ctrl in (nat, py):
                _add_hand(ctrl, state, hand, [0.0, 0.0, 0.02], ramp_time=0.1, t=t)
                ctrl.activate_contact(contact, t=t)  # a blend between two hierarchies
        before = nat.native.steps
        a, b = nat.step(state, t), py.step(state, t)
        if k == 20:
            offsets = nat.stack._tasks[-1].offsets
            assert offsets is not None  # recorded by the Python step
        python += nat.native.steps == before
        if 20 + blend_steps < k < 120 and nat.native.steps == before + 1:
            ramped += nat.stack.ramp_keep(nat.stack._tasks[-1], t) > 0.0
            _same_levels(nat, py, f"t={t}", tol=1e-9)
            assert nat.stack._tasks[-1].offsets is offsets  # the Python step's, pushed down
        _same_optimum(nat, py, a, b, f"t={t}", tol=1e-5, sigma_tol=1e-6, conflict_sigma=False)
    assert python >= blend_steps - 1  # the contact's blend
    assert ramped >= 20


def test_the_recovery_deceleration_is_mirrored_natively():
    """g1's right wrist roll thrown toward its limit at 20 rad/s (what a torque-rate level in
    conflict did, tests/test_sim_conflict.py): the native step's joint-limit rows are the
    Python step's, braking at the recovery deceleration rather than the reserve."""
    from hqp.tasks.joint_limits import JointLimits

    robot, nat, py = _pair("g1", max_torque_rate=None)
    jl = next(t for t in py.stack.tasks if isinstance(t, JointLimits))
    model = py.model
    wrist = model.joint_index("right_wrist_roll_joint")
    assert jl.recovery[wrist] > 1e4
    q = robot.q_standing.copy()
    v = np.zeros(model.nv)
    q[np.arange(model.nq)[model.actuated_q][wrist]] = model.q_upper[wrist] - 1.0
    v[np.arange(model.nv)[model.actuated][wrist]] = 20.0
    for t in (0.0, 0.001):
        nat.step(RobotState(q, v), t)
        py.step(RobotState(q, v), t)
    _same_levels(nat, py, "g1 wrist at 20 rad/s")
    lb, ub = jl.bounds(model, py.dt)
    assert lb[wrist] == ub[wrist] == pytest.approx(-20.0**2 / 2.0, rel=0.05)  # stops at the limit


def test_a_parameter_array_edited_in_place_is_an_error():
    """An array a task holds as a parameter is read-only: an edit in place, which the
    controller would not see, raises instead of being lost; the caller's array is copied,
    not frozen, and assigning a new array is an edit the next step applies."""
    robot, nat, _ = _pair("g1", "residuals")
    limits = nat.model.tau_max.copy()
    task = nat.task("torque_limits")
    task.tau_max = limits
    limits[0] = 1.0  # the caller's own array stays theirs
    assert task.tau_max[0] == nat.model.tau_max[0]
    with pytest.raises(ValueError, match="read-only"):
        task.tau_max[0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        task.tau_max *= 0.7


def test_a_task_set_seen_before_takes_its_engine_copy_again():
    """A hand task added, removed, added again (the same object): the third task set is the
    first one's, whose copy the engine kept (``NativeEngine.KEPT``); with it the commands,
    the report and every task's error equal the Python step's, goals changed meanwhile
    included."""
    robot, nat, py = _pair("g1", "residuals", max_torque_rate=None)
    rng = np.random.default_rng(23)
    drift = rng.normal(scale=0.02, size=nat.model.na)  # the joints move: errors change
    v = np.zeros(nat.model.nv)
    v[6:] = drift
    states = []
    for i in range(90):
        q = robot.q_standing.copy()
        q[7:] += 0.001 * i * drift
        states.append((0.001 * i, RobotState(q, v)))
    hand = robot.hands[1]
    tasks = {}
    for k, (t, state) in enumerate(states):
        if k == 10:
            for ctrl in (nat, py):
                _add_hand(ctrl, state, hand, [0.02, 0.0, 0.0], ramp_time=0.0, t=t)
                tasks[id(ctrl)] = ctrl.task("hand")
        if k == 40:
            for ctrl in (nat, py):
                ctrl.remove_task("hand", t=t)
                tasks[id(ctrl)].set_goal(tasks[id(ctrl)].goal_at(t).position + [0.0, 0.0, 0.02])
        if k == 60:
            for ctrl in (nat, py):
                ctrl.add_task(tasks[id(ctrl)], "operational", t=t, ramp_time=0.0)
        a, b = nat.step(state, t), py.step(state, t)
        if k == 20:
            with_hand = nat.native.mirror
        if k == 50:
            without = nat.native.mirror
            assert without is not with_hand
        if k == 70:
            assert nat.native.mirror is with_hand  # kept, not built again
        _same_optimum(nat, py, a, b, f"t={t}", tol=1e-6, sigma_tol=1e-6, conflict_sigma=False)
        _same_errors(nat, py, f"t={t}", tol=1e-6)
    assert nat.native.steps == len(states)
