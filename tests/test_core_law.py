"""The null-space law in the native core against the Python law (the oracle).

``hqp._core._ext.NullSpaceLaw`` (the law on plain matrices) against
:func:`hqp.control.nullspace.law.prioritized_torques` on random systems, fixed and floating
base, singular levels included; the law's native step (``NativeLaw``, the default of
:class:`~hqp.control.nullspace.resolver.NullSpaceController` on a bundled robot) against the
Python law's step at random states of every bundled robot standing on both feet, with and
without the joint-limit activation zones (joints driven into their zones); its heap
allocations (the checked module), the GIL, and what falls back to the Python law.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from _threads import assert_runs_beside_python

from hqp import robots
from hqp.control.nullspace.law import EIG_TOL, prioritized_torques
from hqp.control.nullspace.native import NativeLawMirror
from hqp.control.presets import standing_nullspace_controller
from hqp.errors import HQPError
from hqp.model import RobotModel, RobotState
from hqp.robots.erd import erd_robots_dir
from hqp.tasks.base import Category, Rows, Task

_ext = pytest.importorskip("hqp._core._ext")

RTOL = 1e-8
"""Native against Python: relative to the largest entry of the Python value."""


def close(native, python, what, rtol=RTOL):
    native, python = np.asarray(native, dtype=float), np.asarray(python, dtype=float)
    assert native.shape == python.shape, what
    finite = np.isfinite(python)
    np.testing.assert_array_equal(native[~finite], python[~finite], err_msg=what)  # +-inf
    scale = max(1.0, float(np.abs(python[finite]).max(initial=0.0)))
    np.testing.assert_allclose(native[finite], python[finite], rtol=0, atol=rtol * scale,
                               err_msg=what)


def native_plain(M, h, levels, nv_base=0, support=None, internal_forces="none",
                 eig_tol=EIG_TOL):
    nv = M.shape[0]
    law = _ext.NullSpaceLaw(nv, nv_base)
    Js, bs = support if support is not None else (np.zeros((0, nv)), np.zeros(0))
    J = np.vstack([J for J, _ in levels])
    a = np.concatenate([a for _, a in levels])
    starts = [0, *np.cumsum([J.shape[0] for J, _ in levels]).tolist()]
    error = law.solve(M, h, Js, bs, J, a, starts, eig_tol, internal_forces == "min-norm")
    assert error == ""
    return law


def check_plain(law, ref, what):
    """Torques, accelerations, forces and the per-level report of eq. 22-23."""
    close(law.tau, ref.tau, f"{what}: tau")
    close(law.qdd, ref.qdd, f"{what}: qdd")
    close(law.f, ref.f, f"{what}: f")
    close(law.tau_internal, ref.tau_internal, f"{what}: tau_internal")
    close(law.phi_pinv, ref.phi_pinv, f"{what}: phi_pinv")
    levels = law.levels()
    assert len(levels) == len(ref.levels)
    for (start, rows, rank, _free, threshold, target), lv in zip(levels, ref.levels):
        s = slice(start, start + rows)
        assert rank == lv.rank, (what, lv.name)
        close(law.eigenvalues[s], lv.eigenvalues, f"{what}: {lv.name} eigenvalues")
        assert threshold == pytest.approx(lv.threshold, rel=1e-10), (what, lv.name)
        assert target == pytest.approx(lv.target_norm, rel=1e-12)
        close(law.forces[s], lv.force, f"{what}: {lv.name} F")
        close(law.residuals[s], lv.residual, f"{what}: {lv.name} residual")


def random_system(rng, nv, ns, sizes, singular=False):
    A = rng.normal(size=(nv, nv))
    M = A @ A.T + 0.5 * nv * np.eye(nv)
    h = rng.normal(scale=5.0, size=nv)
    levels = [(rng.normal(size=(m, nv)), rng.normal(size=m)) for m in sizes]
    if singular:  # a level repeating a row of the level above: eq. 22-23 on its range
        J, a = levels[1]
        levels[1] = (np.vstack([J, levels[0][0][:1]]), np.concatenate([a, [0.3]]))
    support = (rng.normal(size=(ns, nv)), rng.normal(size=ns)) if ns else None
    return M, h, levels, support


@pytest.mark.parametrize("internal_forces", ["none", "min-norm"])
@pytest.mark.parametrize("case", ["fixed", "floating", "floating-air", "singular", "conflict"])
def test_plain_law_equals_the_python_law(case, internal_forces):
    """Random systems (10 each): a fixed base (S = I, Phi = M^-1), a floating base on a
    support (S = [0 I], Phi of rank nv - ns), a floating base without support, a level
    singular within the hierarchy (a zero eigenvalue of Lambda^-1) and levels asking for more
    than is left (the last infeasible)."""
    rng = np.random.default_rng(["fixed", "floating", "floating-air", "singular",
                                 "conflict"].index(case))
    nv, nv_base, ns, sizes = {
        "fixed": (9, 0, 0, [2, 3, 3]),
        "floating": (16, 6, 8, [3, 2, 6]),
        "floating-air": (12, 6, 0, [3, 4, 2]),
        "singular": (16, 6, 6, [3, 2, 4]),
        "conflict": (14, 6, 6, [3, 3, 7]),
    }[case]
    for trial in range(10):
        M, h, levels, support = random_system(rng, nv, ns, sizes, singular=case == "singular")
        S = np.eye(nv)[nv_base:] if nv_base else None
        ref = prioritized_torques(M, h, levels, S=S, support=support,
                                  internal_forces=internal_forces)
        law = native_plain(M, h, levels, nv_base, support, internal_forces)
        check_plain(law, ref, f"{case} #{trial}")
        if case == "singular":
            assert ref.levels[1].singular
        if case == "conflict":
            assert not ref.levels[-1].satisfied


@functools.lru_cache(maxsize=None)
def _panda() -> RobotModel:
    urdf = erd_robots_dir() / "panda_description/urdf/panda.urdf"
    return RobotModel.from_urdf(urdf, floating_base=False)


def test_plain_law_on_a_fixed_base_arm():
    """A fixed-base robot (panda): frame-Jacobian levels at random states, M and h with
    Coriolis terms; a stretched arm makes a level nearly singular."""
    model = _panda()
    rng = np.random.default_rng(3)
    frames = [f.name for f in model.model.frames if f.parentJoint > 0]
    for trial in range(10):
        model.update(model.random_configuration(rng), rng.normal(size=model.nv))
        picked = rng.choice(frames, size=3, replace=False)
        levels = [(model.frame_jacobian(str(f))[:3], rng.normal(size=3)) for f in picked]
        ref = prioritized_torques(model.M, model.h, levels)
        law = native_plain(model.M, model.h, levels)
        check_plain(law, ref, f"panda #{trial}")


def test_plain_law_refuses_what_the_python_law_refuses():
    nv = 4
    M, h = np.eye(nv), np.zeros(nv)
    law = _ext.NullSpaceLaw(nv, 0)
    J, a = np.eye(2, nv), np.zeros(2)
    assert law.solve(-M, h, np.zeros((0, nv)), np.zeros(0), J, a, [0, 2], EIG_TOL, True) \
        == "M is not positive definite"
    with pytest.raises(HQPError, match="starts"):
        law.solve(M, h, np.zeros((0, nv)), np.zeros(0), J, a, [0, 3], EIG_TOL, True)
    with pytest.raises(HQPError, match="eig_tol"):
        law.solve(M, h, np.zeros((0, nv)), np.zeros(0), J, a, [0, 2], 0.0, True)
    with pytest.raises(HQPError, match="nv_base"):
        _ext.NullSpaceLaw(nv, nv)


# -- the law's native step on the bundled robots ---------------------------------------------


def _controllers(name, **options):
    robot = robots.load(name)
    native = standing_nullspace_controller(robot, **options)
    python = standing_nullspace_controller(robot, **options)
    python.native = None  # the Python law's step
    assert native.native is not None
    return robot, native, python


def _states(robot, model, seed, count=10):
    """Random states around standing; every other one drives joints into their zones."""
    rng = np.random.default_rng(seed)
    for i in range(count):
        q = robot.q_standing.copy()
        q[7:] += rng.normal(scale=0.02, size=model.na)
        v = rng.normal(scale=0.1, size=model.nv)
        if i % 2:
            joints = rng.choice(model.na, size=3, replace=False)
            upper = rng.random(3) < 0.5
            q[7 + joints] = np.where(upper, model.q_upper[joints] - 0.03,
                                     model.q_lower[joints] + 0.03)
            v[6 + joints] = np.where(upper, 0.3, -0.3)
        yield q, v, 1.0 + 0.001 * i


def check_commands(a, b, native, python):
    """The native step's command and report against the Python law's."""
    close(a.tau, b.tau, "tau")
    close(native.last_x, python.last_x, "x")
    for key in a.wrenches:
        close(a.wrenches[key], b.wrenches[key], f"wrench {key}")
    assert a.report.notes == b.report.notes
    assert [(s.name, s.level, s.status, s.yields_to) for s in a.report.tasks] == \
        [(s.name, s.level, s.status, s.yields_to) for s in b.report.tasks]
    for sa, sb in zip(a.report.tasks, b.report.tasks):
        # (rounding of the law: ~1e-9 on a satisfied task, 30x on a weight-1e-3 one)
        assert sa.residual == pytest.approx(sb.residual, rel=1e-6, abs=1e-7), sa.name
        if np.isnan(sb.sigma_min):
            assert np.isnan(sa.sigma_min), sa.name
        else:
            assert sa.sigma_min == pytest.approx(sb.sigma_min, rel=1e-6, abs=1e-12), sa.name
    close(a.report.level_costs, b.report.level_costs, "level costs", 1e-7)


@pytest.mark.parametrize("zones", [True, False], ids=["zones", "no-zones"])
@pytest.mark.parametrize("name", robots.NAMES)
def test_native_law_equals_the_python_law_at_random_states(name, zones):
    """10 random states per robot (half of them with joints inside their activation zones):
    torques and x to 1e-8 of the largest, the law's per-level eigenvalues, ranks, thresholds
    and satisfaction, the report (statuses, residuals, eigenvalues, notes, level costs)."""
    diagnostics = "full" if zones else "residuals"
    robot, native, python = _controllers(name, diagnostics=diagnostics,
                                         joint_limit_zones=zones)
    held = 0
    for q, v, t in _states(robot, native.model, seed=robots.NAMES.index(name)):
        a = native.step(RobotState(q, v), t)
        b = python.step(RobotState(q, v), t)
        check_commands(a, b, native, python)
        la, lb = native.last_law, python.last_law
        assert [lv.name for lv in la.levels] == [lv.name for lv in lb.levels]
        for x, y in zip(la.levels, lb.levels):
            assert (x.rank, x.satisfied, x.singular) == (y.rank, y.satisfied, y.singular), x.name
            close(x.eigenvalues, y.eigenvalues, f"{x.name} eigenvalues")
            assert x.threshold == pytest.approx(y.threshold, rel=1e-8)
        # the internal-force torque is the least-squares solution of an ill-conditioned
        # system (Lambda_s): the Python law itself moves it by up to 4e-9 of its largest
        # entry when M is perturbed by 1e-16 relative (measured at these states), the native
        # law differs from it by up to 1.1e-8
        close(la.tau_internal, lb.tau_internal, "tau_internal", 1e-7)
        close(la.f, lb.f, "f")
        pa, pb = native.last_problem, python.last_problem
        assert pa.names == pb.names and pa.built_levels == pb.built_levels
        assert pa.task_rows.keys() == pb.task_rows.keys() and pa.skipped == pb.skipped
        if zones:
            zone = native.task("joint_limit_zone")
            assert zone.active == python.task("joint_limit_zone").active
            held += len(zone.active) > 0
    assert native.native.steps == 10, native.native.unsupported
    if zones:
        assert held >= 5  # the zones' rows were at the top of the hierarchy
        assert "joint_limits" in [lv.name for lv in native.last_law.levels] or held < 10


def test_native_law_on_one_foot_equals_the_python_law():
    """A foot released (its slot held at zero by the physics rows, six support rows left):
    once the release is done the steps are native again and equal the Python law's."""
    robot, native, python = _controllers("g1", diagnostics="full")
    state = RobotState(robot.q_standing.copy(), np.zeros(native.model.nv))
    for ctrl in (native, python):
        ctrl.step(state, 1.0)
        ctrl.deactivate_contact("left_foot", t=1.0, unload_time=0.0)
    steps = native.native.steps
    for i, (q, v, _t) in enumerate(_states(robot, native.model, seed=9, count=80)):
        t = 1.001 + 0.001 * i
        v[:6] = 0.0
        a = native.step(RobotState(q, v), t)
        b = python.step(RobotState(q, v), t)
        if native.native.steps > steps:  # past the blend of the release: native
            check_commands(a, b, native, python)
    # the release's blend (blend_time 0.05 s) on the Python law, then 30 native steps
    assert native.active_contacts == ("right_foot",) and native.native.steps - steps >= 25
    assert native.last_problem.support[0].shape[0] == 6
    assert not native.last_x[native.layout.contact("left_foot").slice].any()


def test_a_task_at_the_physics_level_is_support_as_in_python():
    """A task's qdd rows at the physics level are support rows (law_problem's rule): the
    support forces then include its rows, and x maps J_s^T f onto the contact slots by least
    squares (the general path of decision_vector, not the contacts-only shortcut)."""
    from hqp.tasks.posture import PostureTask

    robot, native, python = _controllers("talos", diagnostics="residuals")
    for ctrl in (native, python):
        held = PostureTask(ctrl.model, list(ctrl.model.joint_names[-2:]), name="held",
                           kp=20.0, weight=4.0)
        held.set_goal(np.zeros(2))
        ctrl.add_task(held, Category.PHYSICS, t=1.0, ramp_time=0.0)
    for q, v, t in _states(robot, native.model, seed=11, count=6):
        a = native.step(RobotState(q, v), t)
        b = python.step(RobotState(q, v), t)
        check_commands(a, b, native, python)
        assert native.last_problem.support[0].shape[0] == 14
    assert native.native.steps == 6, native.native.unsupported


def test_native_law_levels_are_the_python_levels():
    """``last_built`` of a native step (the native rows, a zone's rows from its kernel) equals
    ``Stack.build`` at the same state, spans and unweighted rows included."""
    robot, native, python = _controllers("talos")  # two joints in their zones at standing
    q, v, t = next(_states(robot, native.model, seed=7))
    native.step(RobotState(q, v), t)
    python.step(RobotState(q, v), t)
    a, b = native.last_built, python.last_built
    assert a.level_index == b.level_index
    assert [(s.name, s.level, s.built_level, s.eq, s.ineq) for s in a.spans] == \
        [(s.name, s.level, s.built_level, s.eq, s.ineq) for s in b.spans]
    for la, lb in zip(a.levels, b.levels):
        for field in ("A", "b", "C", "lower", "upper"):
            x, y = getattr(la, field), getattr(lb, field)
            assert (x is None) == (y is None), (la.name, field)
            if x is not None:
                close(x, y, f"{la.name} {field}", 1e-10)
    zone = a.rows["joint_limit_zone"]
    np.testing.assert_allclose(zone.A @ native.last_x, zone.b, atol=1e-8)


# -- hot path: allocations and the GIL ---------------------------------------------------


def _checked_law(name, zones=True):
    from conftest import checked_core
    _ext_checked = checked_core()

    robot = robots.load(name)
    ctrl = standing_nullspace_controller(robot, joint_limit_zones=zones)
    ctrl.step(RobotState(robot.q_standing.copy(), np.zeros(ctrl.model.nv)), 1.0)
    return robot, ctrl, NativeLawMirror(robot, ctrl, core=_ext_checked)


@pytest.mark.parametrize("name", robots.NAMES)
def test_a_law_step_allocates_nothing_once_sized(name):
    """Eigen's run-time check over the whole law step (model pass, kernels, zones, the law,
    x, the report's numbers and the full diagnostics; the checked module): once a state's step
    has sized the workspace, steps at other states of the same shapes (the same joints in
    their zones, the same ranks) make no heap allocation, with the goals pushed down at every
    step."""
    robot, ctrl, mirror = _checked_law(name)
    model, law = ctrl.model, mirror.law
    rng = np.random.default_rng(21)
    q0 = robot.q_standing.copy()
    q0[7:] += rng.normal(scale=0.003, size=model.na)
    v0 = rng.normal(scale=0.01, size=model.nv)
    t = 1.0
    for _ in range(2):  # sizes everything (allowed to allocate)
        t += 0.001
        assert mirror.step(q0, v0, t) == ""
        law.diagnose(1e-6)
    shapes = [lv[:4] for lv in law.law.levels()]
    for i in range(12):
        t += 0.001
        q = q0 + np.r_[np.zeros(7), rng.normal(scale=1e-4, size=model.na)]
        v = v0 + rng.normal(scale=1e-3, size=model.nv)
        mirror.kernels.push_goals(t)
        assert law.step(q, v, ctrl.dt, forbid_malloc=True) == ""  # an allocation: an error
        law.diagnose(1e-6, forbid_malloc=True)  # raises on an allocation
        assert np.isfinite(law.tau).all()
        assert [lv[:4] for lv in law.law.levels()] == shapes  # the same shapes throughout


def test_the_allocation_check_sees_an_allocation():
    """The check of the test above can fail: a step whose shapes change (a joint entering
    its zone adds a row to the top level) resizes the workspace, and the checked module
    reports it."""
    robot, ctrl, mirror = _checked_law("g1")
    model = ctrl.model
    q = robot.q_standing.copy()
    v = np.zeros(model.nv)
    assert mirror.step(q, v, 1.0) == ""
    j = int(np.argmax(model.q_upper - q[7:] > 0.5))
    q[7 + j] = model.q_upper[j] - 0.01
    mirror.kernels.push_goals(1.001)
    error = mirror.law.step(q, v, ctrl.dt, forbid_malloc=True)
    assert error.startswith("eigen assertion")


def test_a_law_step_in_a_second_thread_leaves_the_first_to_python():
    """The law's step releases the GIL: Python code of another thread runs during a step
    (a stamp of the main thread inside a call of the worker)."""
    robot = robots.load("talos")
    ctrl = standing_nullspace_controller(robot)
    ctrl.step(RobotState(robot.q_standing.copy(), np.zeros(ctrl.model.nv)), 1.0)
    mirror = NativeLawMirror(robot, ctrl)
    q, v = robot.q_standing.copy(), np.zeros(ctrl.model.nv)
    mirror.kernels.push_goals(1.0)
    law = mirror.law
    assert law.step(q, v, ctrl.dt) == ""
    assert_runs_beside_python(lambda: law.step(q, v, ctrl.dt))


# -- what runs on the Python law -------------------------------------------------------------


class _OwnTask(Task):
    """A Python task (no kernel): joint damping at the posture level."""

    category = Category.POSTURE

    def __init__(self) -> None:
        super().__init__("own", weight=0.1)

    def rows(self, model, layout, dt, t):
        A = layout.zeros(model.na)
        A[:, model.actuated] = np.eye(model.na)
        return Rows(A=A, b=-2.0 * model.v[model.actuated])


@pytest.mark.parametrize("setting, why", [
    ({"method": "literal"}, "method='literal'"),
    ({"internal_forces": "balanced"}, "internal_forces='balanced'"),
    ({"support_zone": 0.8}, "support and torque activation zones"),
    ({"torque_zone": 0.95}, "support and torque activation zones"),
    ({"task": True}, "no native kernel"),
])
def test_what_the_native_law_does_not_run_is_the_python_laws(setting, why):
    """Settings and tasks without a native path: every step is the Python law's (the same
    command as a controller without the native step), and the engine says why."""
    robot, native, python = _controllers("g1", diagnostics="residuals")
    for ctrl in (native, python):
        if setting.get("task"):
            ctrl.add_task(_OwnTask(), t=1.0, ramp_time=0.0)
        else:
            for key, value in setting.items():
                setattr(ctrl, key, value)
    for q, v, t in _states(robot, native.model, seed=5, count=3):
        a = native.step(RobotState(q, v), t)
        b = python.step(RobotState(q, v), t)
        np.testing.assert_array_equal(a.tau, b.tau)
    assert native.native.steps == 0 and why in native.native.unsupported


def test_python_law_steps_between_native_ones():
    """A task ramping in, and the step after the safe command, are the Python law's; the steps
    after them are native again (and the ramp's last steps equal the Python law's), the
    decaying-offset blend out of the safe command included."""
    from hqp.tasks.posture import PostureTask

    robot, native, python = _controllers("g1", diagnostics="residuals")
    state = RobotState(robot.q_standing.copy(), np.zeros(native.model.nv))
    for ctrl in (native, python):
        ctrl.step(state, 1.0)
        arms = PostureTask(ctrl.model, list(ctrl.model.joint_names[-4:]), name="arms", kp=10.0)
        arms.set_goal(np.zeros(4))
        ctrl.add_task(arms, "operational", t=1.0, ramp_time=0.005)
    steps = native.native.steps
    for i in range(1, 12):
        a = native.step(state, 1.0 + 0.001 * i)
        b = python.step(state, 1.0 + 0.001 * i)
        close(a.tau, b.tau, f"step {i}")
    assert native.native.steps - steps == 11 - 4  # t = 1.001 .. 1.004 ramping: Python
    native._was_safe = True  # as after a safe command: the Python step blends out of it
    steps = native.native.steps
    t = 1.02
    native.step(state, t)
    assert native.native.steps == steps and native._blend_start is not None
    blend = 0
    while native._blend_start is not None:  # the blend's steps (a decaying offset): native
        t += 0.001
        command = native.step(state, t)
        blend += 1
        assert command.report.strictness_suspended or native._blend_start is None
    assert blend > 1 and native.native.steps == steps + blend
    native.step(state, t + 0.001)
    assert native.native.steps == steps + blend + 1


def test_the_controller_suite_runs_the_law_natively():
    """The contract's ``nullspace`` row of the controller suite is the law's native step."""
    from hqp.bench import suite_controller as sc

    robot = robots.load("g1")
    stepper = sc._Stepper("nullspace", robot, sc.states("g1", count=2))
    for _ in range(3):
        cmd = stepper()
    assert stepper.ctrl.native is not None and stepper.ctrl.native.steps >= 1
    assert np.isfinite(cmd.tau).all() and cmd.report.tasks
