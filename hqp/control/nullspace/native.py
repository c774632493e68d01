"""The null-space law's native step (``hqp._core._ext.NativeLaw``).

:class:`NativeLawMirror` holds a controller's stack in the C++ core the way the HQP
controller's native step does (:class:`~hqp.control.native.NativeStepMirror`: one kernel per
task, goals pushed down each step), plus the papers' joint-limit activation zones
(:class:`~hqp.tasks.joint_limit_zone.JointLimitZone`, a kernel of the law's own), and runs the
law's whole step in one call with the GIL released: the model pass and every kernel's rows
(``NativeStep.rows``, no QP), the law's matrices as
:func:`~hqp.control.nullspace.multicontact.law_problem` takes them from the built levels,
:func:`~hqp.control.nullspace.law.prioritized_torques` (``method="whitened"``), the decision
vector of :func:`~hqp.control.nullspace.multicontact.decision_vector` and the numbers of the
feasibility report (per-task residuals, level costs, eigenvalues of ``Lambda^-1``). The Python
law stays the readable reference and the test oracle (``tests/test_core_law.py`` holds the two
equal).

What runs on it (:class:`NativeLawEngine`, the engine of
:class:`~hqp.control.nullspace.resolver.NullSpaceController`): steady steps (as for the HQP
native step) of a stack whose tasks all have a kernel, with ``method="whitened"``,
``internal_forces`` ``"none"`` or ``"min-norm"`` and the contact and actuation zones off
(``support_zone`` and ``torque_zone`` ``None``). Everything else is the Python law's step
(``engine.unsupported`` says why): ``method="literal"``, ``internal_forces="balanced"``, the
support and torque zones, a task without a kernel, a joint-limit zone on a model whose joints
are not all one-dimensional, the step after the safe command (the Python step blends out of it),
a failed native step (the Python law then fails or succeeds the same way, with its notes).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np

from hqp._core import _ext as _core_ext
from hqp.control.command import Feasibility, TaskStatus
from hqp.control.diagnostics import Diagnostics
from hqp.control.native import NativeEngine, NativeStepMirror, NotSupported
from hqp.control.nullspace.law import LawLevel, LawSolution
from hqp.control.nullspace.multicontact import LawProblem
from hqp.robots.robot import Robot
from hqp.solver.level import Level
from hqp.stack import BuiltStack, Stack, TaskSpan
from hqp.tasks.base import Category, Rows
from hqp.tasks.contact import Contact
from hqp.tasks.joint_limit_zone import JointLimitZone

_PRESENT, _FORCE_ROWS, _SINGULAR = 1, 2, 4


class _WithoutZones:
    """The stack as the HQP mirror sees it: every task but the joint-limit zones."""

    def __init__(self, stack: Stack) -> None:
        self._stack = stack
        self.tasks = tuple(t for t in stack.tasks if not isinstance(t, JointLimitZone))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stack, name)


def physics_level(stack: Stack, index: int) -> bool:
    """Whether stack level ``index`` holds the physics (its qdd rows are the law's support)."""
    return (stack.level_categories[index] is Category.PHYSICS
            or stack.level_names[index] == "physics")


def zone_kernel(core: Any, task: JointLimitZone, model: Any) -> Any:
    """Return the native kernel of a joint-limit zone (its edges and safety positions).

    Raises:
        NotSupported: Joints that are not one-dimensional, or widths the Python task refuses
            (the Python step raises its error).

    """
    if model.nq - model.nq_base != model.na:
        raise NotSupported(f"{task.where()}: joints with more than one coordinate")
    if task.zone.size not in (1, model.na) or task.depth.size not in (1, model.na):
        raise NotSupported(f"{task.where()}: zone or depth of another robot")
    zone = np.broadcast_to(task.zone, (model.na,)).astype(float)
    low_safe, high_safe = task.safety_positions(model)
    return core.JointLimitZoneKernel(model.q_lower + zone, model.q_upper - zone,
                                     np.asarray(low_safe, dtype=float),
                                     np.asarray(high_safe, dtype=float),
                                     task.kp, task.kv, task.max_velocity)


class NativeLawMirror:
    """A null-space controller's stack in the native core, and the law's step on it.

    Args:
        robot: The bundled robot (its URDF builds the native model).
        controller: A :class:`~hqp.control.nullspace.resolver.NullSpaceController` (its
            ``stack``, ``model``, ``layout``, ``dt`` and resolver settings).
        core: The extension module (default ``hqp._core._ext``; the no-allocation test passes
            ``hqp._core._ext_checked``).

    Raises:
        NotSupported: A task without a kernel (see the module docstring).

    """

    def __init__(self, robot: Robot, controller: Any, core: Any = None) -> None:
        core = _core_ext if core is None else core
        stack, model, layout = controller.stack, controller.model, controller.layout
        self.model = model
        self.stack = stack
        self._layout = layout
        self.dt = float(controller.dt)
        view = SimpleNamespace(stack=_WithoutZones(stack), model=model, layout=layout,
                               dt=controller.dt, max_torque_rate=None)
        self.kernels = NativeStepMirror(robot, view, core=core)
        resolver = controller.resolver
        self._settings = (float(resolver.eig_tol), resolver.internal_forces == "min-norm")
        self.law = core.NativeLaw(self.kernels.step_core, *self._settings)
        for k in range(stack.n_levels):
            self.law.add_level(physics_level(stack, k))
        self.tasks: list[Any] = []  # by source index
        self.levels: list[int] = []  # stack level by source
        self._handles: list[int] = []  # NativeStep entry by source (-1: a zone)
        self._zones: list[tuple[int, JointLimitZone]] = []
        for task in stack.tasks:
            level = stack.level_of_task(task.name)
            if isinstance(task, JointLimitZone):
                source = self.law.add_zone(level, task.weight, zone_kernel(core, task, model))
                self._zones.append((source, task))
                self._handles.append(-1)
            else:
                handle = len(self._handles) - len(self._zones)
                slot = layout.contact(task.name).start if isinstance(task, Contact) else -1
                self.law.add_entry(level, handle, slot)
                self._handles.append(handle)
            self.tasks.append(task)
            self.levels.append(level)
        # spans in built order: by level, then in the stack's order (Stack.build)
        self._order = sorted(range(len(self.tasks)), key=lambda s: self.levels[s])
        self._physics = [physics_level(stack, k) for k in range(stack.n_levels)]
        self._inequalities: list[int] | None = None
        self.seconds = 0.0

    def settings(self, resolver: Any) -> None:
        """Push the resolver's ``eig_tol`` and internal forces when they changed."""
        settings = (float(resolver.eig_tol), resolver.internal_forces == "min-norm")
        if settings != self._settings:
            self.law.set_settings(*settings)
            self._settings = settings

    def sync_contacts(self) -> bool:
        """Push the contacts' activation (see :meth:`NativeStepMirror.sync_contacts`)."""
        return self.kernels.sync_contacts()

    def step(self, q: np.ndarray, v: np.ndarray, t: float) -> str:
        """One law step at ``(q, v)`` and time ``t``: ``""``, or why the law cannot run it."""
        self.kernels.push_goals(t)
        t0 = time.perf_counter()
        error = self.law.step(q, v, self.dt)
        self.seconds = time.perf_counter() - t0
        return error

    @property
    def x(self) -> np.ndarray:
        """``x = [qdd | wrenches]`` of the last step ``(n,)``."""
        return self.law.x

    @property
    def tau(self) -> np.ndarray:
        """Torques of the last step ``(na,)`` [N m]."""
        return self.law.tau

    def record_errors(self, controller: Any = None) -> None:
        """Give each task the error of the last step (kernels; zones: active joints, errors).

        A zone's ``active`` and :meth:`~hqp.tasks.joint_limit_zone.JointLimitZone.error` are
        what its ``rows`` leaves them at on the Python step. With the ``controller`` that ran
        the step, the kernels' tasks fetch theirs when first read
        (:meth:`~hqp.control.native.NativeStepMirror.record_errors`).
        """
        self.kernels.record_errors(controller)
        names = self.model.joint_names
        for source, task in self._zones:
            active, error, _ref = self.law.zone(source)
            task.record_error(tuple(names[i] for i in active), error)

    # -- the report -----------------------------------------------------------------------

    def _skipped(self, flags: np.ndarray) -> list[str]:
        """Return the notes of :func:`law_problem` on the rows the law does not use."""
        if self._inequalities is None:
            core = self.kernels.step_core
            self._inequalities = [0 if h < 0 else int(core.entry(h)[6]) for h in self._handles]
        out = []
        for s in self._order:
            f = int(flags[s])
            if not f & _PRESENT or self._physics[self.levels[s]]:
                continue
            name = self.tasks[s].name
            if self._inequalities[s]:
                out.append(f"{name}: {self._inequalities[s]} inequality rows not enforced")
            if f & _FORCE_ROWS:
                out.append(f"{name}: rows on contact forces not used")
        return out

    def report(self, diagnostics: Diagnostics, notes: list[str]) -> tuple[
            tuple[TaskStatus, ...] | Callable[[], tuple[TaskStatus, ...]], tuple[float, ...]]:
        """Statuses and level costs of the last step; the rows the law did not use in ``notes``.

        In ``"residuals"`` mode the statuses are a function of none, called when the report's
        tasks are first read (the step's data copied out now, as
        :meth:`~hqp.control.native.NativeStepMirror.report`).

        As :meth:`~hqp.control.nullspace.resolver.NullSpaceResolver.report`: residuals at
        ``x``, ``sigma_min`` the smallest eigenvalue of the task's ``Lambda^-1`` (its level's
        in ``"residuals"`` mode); a conflicting task under ``"full"`` diagnostics has its
        statuses from :meth:`~hqp.control.diagnostics.Diagnostics.law_statuses` on
        :meth:`built`, :meth:`law_problem` and :meth:`law_solution` (the level it yields to).
        """
        law = self.law
        full = diagnostics.full
        if full:
            law.diagnose(diagnostics.singular_tolerance)
        residual, eig, flags, level, _start, _count, cost, present = law.report()
        costs = tuple(float(c) for c, p in zip(cost, present) if p)
        notes.extend(self._skipped(flags))
        if not full:  # the statuses made when first read, from the step's data
            return (lambda: self._statuses(diagnostics, residual, eig, flags, level, False)[0],
                    costs)
        statuses, yields = self._statuses(diagnostics, residual, eig, flags, level, True)
        if yields:  # the level a conflicting task yields to: the Python diagnostics
            statuses = diagnostics.law_statuses(self.built()[0], self.law_problem(),
                                                self.law_solution(), self.x)
        return statuses, costs

    def _statuses(self, diagnostics: Diagnostics, residual: np.ndarray, eig: np.ndarray,
                  flags: np.ndarray, level: np.ndarray,
                  full: bool) -> tuple[tuple[TaskStatus, ...], bool]:
        """Each task's status from the step's data; whether a task in conflict yields (full)."""
        tolerance = diagnostics.tolerance
        out = []
        yields = False
        for s in self._order:
            f = int(flags[s])
            if not f & _PRESENT:
                continue
            r = float(residual[s])
            if r > tolerance:
                status = Feasibility.CONFLICT
                yields = yields or (full and level[s] >= 0)
            elif f & _SINGULAR:
                status = Feasibility.SINGULAR
            else:
                status = Feasibility.SATISFIED
            out.append(TaskStatus(self.tasks[s].name, self.levels[s], status, r, None,
                                  float(eig[s])))
        return tuple(out), yields

    # -- the last step as Python has it ---------------------------------------------------

    def law_solution(self) -> LawSolution:
        """Return the last step's law as ``prioritized_torques`` returns it (copied out)."""
        law = self.law.law
        eig, forces, residuals = law.eigenvalues, law.forces, law.residuals
        names = self.stack.level_names
        levels = []
        for (start, rows, rank, _free, threshold, target), index in zip(law.levels(),
                                                                         self.law.law_levels()):
            s = slice(start, start + rows)
            levels.append(LawLevel(names[index], eig[s].copy(), int(rank), float(threshold),
                                   residuals[s].copy(), forces[s].copy(), float(target)))
        bases = tuple(law.basis(k) for k in range(len(levels) + 1))
        return LawSolution(tau=np.array(self.law.tau), qdd=law.qdd, f=law.f,
                           levels=tuple(levels), tau_internal=law.tau_internal, phi=law.phi,
                           phi_pinv=law.phi_pinv, torque_to_qdd=law.torque_to_qdd,
                           qdd0=law.qdd0, whiten=law.whiten, bases=bases, method="whitened",
                           timings={"law": self.seconds})

    def law_problem(self) -> LawProblem:
        """Return the last step's law matrices as ``law_problem`` has them (copied out)."""
        law = self.law
        J, a = law.rows, law.targets
        Js = law.support
        _residual, _eig, flags, level, start, count, _cost, present = law.report()
        built_of = np.cumsum(present) - 1
        levels, names, built_levels = [], [], []
        names_of = self.stack.level_names
        for (s0, rows, *_rest), index in zip(law.law.levels(), law.law_levels()):
            levels.append((J[s0:s0 + rows], a[s0:s0 + rows]))
            names.append(names_of[index])
            built_levels.append(int(built_of[index]))
        task_rows = {}
        for s in self._order:
            if level[s] < 0:
                continue
            task = self.tasks[s]
            w = np.sqrt(task.weight)
            rows = slice(int(start[s]), int(start[s]) + int(count[s]))
            task_rows[task.name] = (int(level[s]), J[rows] / w, a[rows] / w)
        support = (Js, law.support_targets) if Js.shape[0] else None
        return LawProblem(support, levels, names, built_levels, task_rows,
                          tuple(self._skipped(flags)))

    def built(self) -> tuple[BuiltStack, None]:
        """Return the last step's levels and task rows as :meth:`Stack.build` has them.

        The native rows, divided by ``sqrt(weight)``; a zone's rows from its kernel.
        """
        core = self.kernels.step_core
        n = self._layout.n
        nv_base = self.model.nv_base
        raw = {int(k): (A, b, C, lo, up) for k, A, b, C, lo, up in core.levels()}
        per_level: dict[int, list[tuple[str, Rows, float]]] = {}
        for source, task in enumerate(self.tasks):
            k = self.levels[source]
            handle = self._handles[source]
            if handle < 0:
                active, _error, ref = self.law.zone(source)
                if active.size:
                    A = np.zeros((active.size, n))
                    A[np.arange(active.size), nv_base + active] = 1.0
                    per_level.setdefault(k, []).append((task.name, Rows(A=A, b=ref.copy()),
                                                        task.weight))
                continue
            _kind, _level, _built, eq0, neq, in0, nin, sqrt_w = core.entry(handle)
            if neq + nin == 0:
                continue
            A, b, C, lo, up = raw[k]
            rows = Rows(A=A[eq0:eq0 + neq] / sqrt_w if neq else None,
                        b=b[eq0:eq0 + neq] / sqrt_w if neq else None,
                        C=C[in0:in0 + nin] / sqrt_w if nin else None,
                        lower=lo[in0:in0 + nin] / sqrt_w if nin else None,
                        upper=up[in0:in0 + nin] / sqrt_w if nin else None)
            per_level.setdefault(k, []).append((task.name, rows, task.weight))
        levels, index, spans, all_rows = [], [], [], {}
        for k in sorted(per_level):
            items = per_level[k]
            eq0 = in0 = 0
            As, bs, Cs, los, ups = [], [], [], [], []
            for name, rows, weight in items:
                w = np.sqrt(weight)
                spans.append(TaskSpan(name, k, len(levels), slice(eq0, eq0 + rows.n_eq),
                                      slice(in0, in0 + rows.n_in), weight))
                eq0 += rows.n_eq
                in0 += rows.n_in
                all_rows[name] = rows
                if rows.n_eq:
                    As.append(w * rows.A)
                    bs.append(w * rows.b)
                if rows.n_in:
                    Cs.append(w * rows.C)
                    los.append(w * rows.lower)
                    ups.append(w * rows.upper)
            levels.append(Level(A=np.vstack(As) if As else None,
                                b=np.concatenate(bs) if bs else None,
                                C=np.vstack(Cs) if Cs else None,
                                lower=np.concatenate(los) if los else None,
                                upper=np.concatenate(ups) if ups else None,
                                name=self.stack.level_names[k],
                                weak_threshold=self.stack.weak_thresholds[k]))
            index.append(k)
        return BuiltStack(levels, tuple(index), tuple(spans), all_rows, n), None


class NativeLawEngine(NativeEngine):
    """The native law step of a null-space controller (see the module docstring).

    Args:
        robot: The bundled robot of the controller's model.

    """

    def signature(self, controller: Any) -> tuple[Any, ...]:
        """Return the HQP mirror's signature and the zones' parameters."""
        zones = tuple((t.name, t.zone.tobytes(), t.depth.tobytes(), t.kp, t.kv, t.max_velocity)
                      for t in controller.stack.tasks if isinstance(t, JointLimitZone))
        return super().signature(controller) + (("zones", zones),)

    def why_not(self, controller: Any) -> str | None:
        """Return why the controller's settings leave its steps to Python (``None``: none)."""
        r = controller.resolver
        if not 0.0 < r.eig_tol < 1.0:  # the Python law refuses it (and notes why)
            return f"eig_tol={r.eig_tol!r}"
        if r.method != "whitened":
            return f"method={r.method!r}"
        if r.internal_forces not in ("none", "min-norm"):
            return f"internal_forces={r.internal_forces!r}"
        if r.zones.support is not None or r.zones.torque is not None:
            return "the support and torque activation zones"
        return None

    def ready(self, controller: Any, t: float) -> NativeLawMirror | None:  # type: ignore[override]
        """Return the mirror to run this step, or ``None`` when the Python law must run it."""
        if not controller.stack.steady(t):
            return None
        why = self.why_not(controller)
        if why is not None:
            self.unsupported = why
            self._signature = None
            return None
        signature = self.signature(controller)
        if signature != self._signature:
            self._signature = signature
            self.mirror, self.unsupported = None, None
            try:
                self.mirror = NativeLawMirror(self.robot, controller)  # type: ignore[assignment]
            except NotSupported as exc:
                self.unsupported = str(exc)
        mirror: NativeLawMirror | None = self.mirror  # type: ignore[assignment]
        if mirror is None or mirror._layout is not controller.layout:
            return None
        mirror.settings(controller.resolver)
        return mirror if mirror.sync_contacts() else None
