"""PlaCo's ``DynamicsSolver`` served over a pipe: the controller suite's and the scenarios' PlaCo.

This file runs in PlaCo's own environment (``python -m hqp.bench.peer_env placo`` makes it:
``placo==0.10.2`` pins another pinocchio than hqp's), started by :func:`hqp.bench.worker.start`
as ``<placo python> -I placo_worker.py``. It imports nothing of hqp: numpy, pinocchio and
placo only. What PlaCo prints on stdout (its C++ code does) goes to stderr: stdout carries the
replies alone.

Protocol: one JSON object per line on stdin, one JSON reply per line on stdout.

- ``{"op": "hello"}`` -> ``{"ok": true}``;
- ``{"op": "setup", ...}`` (below) -> ``{"ok": true, "placo_version": ..., "pinocchio_version":
  ..., "nq": ..., "nv": ..., "com": [x, y, z]}`` (PlaCo's centre of mass at ``q``);
- ``{"op": "step", "q": [...], "v": [...], "refs": {task: reference}}`` -> ``{"ok": true,
  "tau": [...], "qdd": [...], "success": ..., "wall_s": ..., "cpu_s": ...}``: the actuated
  torques (zero when the solve fails), the accelerations, and the step's own wall-clock and
  CPU time (state, kinematics, references, solve, torques), measured here so that the pipe is
  not counted;
- ``{"op": "placements", "frames": [...]}`` -> ``{"ok": true, "T": {frame: 4 x 4}, "com":
  [x, y, z]}``: PlaCo's frame placements and centre of mass at the last state it was given;
- ``{"op": "quit"}`` -> ``{"ok": true}``, then the worker exits.

A request that fails gets ``{"ok": false, "error": "<type>: <message>"}``.

``setup`` fields (lists of floats unless said; ``null`` leaves PlaCo's own value):

- ``urdf``, ``ignore_collisions`` (bool: ``placo.Flags.ignore_collisions``), ``dt`` [s],
  ``q`` ``(nq,)`` (the state the targets are read at; ``v`` is zero), ``joints`` (the
  actuated joints' names, in the order of ``q[7:]``: checked against PlaCo's);
- ``q_lower``, ``q_upper``, ``v_max``, ``tau_max`` ``(na,)`` or ``null``: limits written into
  PlaCo's robot; ``qdd_safe`` ``(na,)`` or ``null``: its joint-limit safe accelerations;
- ``joint_limits``, ``velocity_limits``, ``torque_limits`` (bool): PlaCo's limit rows;
- ``contacts``: ``[{"frame", "name", "length", "width", "mu", "weight_moments"}]``, each a
  planar contact on a ``hard`` frame task at the frame's placement (``weight_moments``
  ``null``: PlaCo's default);
- ``tasks``: ``[{"name", "kind", "frame", "priority", "weight", "kp", "kd", "target",
  "mask"}]`` with ``kind`` one of ``com`` (``target`` ``[x, y, z]``, ``z`` ``null``: the
  current height; ``mask`` ``"xy"`` or ``null``), ``position`` (``target`` ``[x, y, z]``),
  ``orientation`` (``target`` a 3 x 3 rotation or ``null``: the frame's current one) and
  ``joints`` (``target`` ``{joint: value}`` or ``null``: every joint of ``joints`` where it is);
  ``priority`` ``"hard"`` or ``"soft"``; ``kp``/``kd`` ``null``: PlaCo's defaults.

``step``'s ``refs``: for a ``com`` or ``position`` task ``{"acceleration": [3]}`` (PlaCo's
``ddtarget_world``; with ``kp = kd = 0`` it is the task's acceleration), for an
``orientation`` task ``{"R": 3 x 3, "omega": [3]}`` (its target and target angular velocity),
for a ``joints`` task ``{"joints": {joint: value}}``. Tasks without a reference keep theirs.
"""

from __future__ import annotations

import json
import os
import sys
import time
from importlib import metadata
from typing import Any, TextIO

import numpy as np
import pinocchio as pin
import placo


class Dynamics:
    """PlaCo's robot, solver, contacts and tasks, made from a ``setup`` request."""

    def __init__(self, msg: dict[str, Any]) -> None:
        flags = placo.Flags.ignore_collisions if msg.get("ignore_collisions") else 0
        robot = placo.RobotWrapper(msg["urdf"], flags) if flags else placo.RobotWrapper(
            msg["urdf"])
        self.robot = robot
        names = list(msg["joints"])
        placo_names = list(robot.joint_names())
        if placo_names != names:
            raise ValueError(f"PlaCo's joints {placo_names} are not hqp's {names} "
                             "(same names in the same order needed)")
        q = np.asarray(msg["q"], dtype=float)
        if q.shape != robot.state.q.shape:
            raise ValueError(f"PlaCo's model has nq = {robot.state.q.size}, the state {q.size}")
        for key, write in (("v_max", robot.set_velocity_limit),
                           ("tau_max", robot.set_torque_limit)):
            if msg.get(key) is not None:
                for name, value in zip(names, msg[key], strict=True):
                    write(name, float(value))
        if msg.get("q_lower") is not None:
            for name, lo, hi in zip(names, msg["q_lower"], msg["q_upper"], strict=True):
                robot.set_joint_limits(name, float(lo), float(hi))
        robot.state.q = q.copy()
        robot.state.qd = np.zeros(robot.state.qd.size)
        robot.update_kinematics()
        solver = placo.DynamicsSolver(robot)
        solver.dt = float(msg["dt"])
        solver.mask_fbase(False)
        solver.enable_joint_limits(bool(msg["joint_limits"]))
        solver.enable_velocity_limits(bool(msg["velocity_limits"]))
        solver.enable_torque_limits(bool(msg["torque_limits"]))
        if msg.get("qdd_safe") is not None:
            for name, value in zip(names, msg["qdd_safe"], strict=True):
                solver.set_qdd_safe(name, float(value))
        self.solver = solver
        self.keep: list[Any] = []  # PlaCo's contacts hold their frame tasks by reference
        for c in msg["contacts"]:
            task = solver.add_frame_task(c["frame"], robot.get_T_world_frame(c["frame"]))
            task.configure(c["name"], "hard", 1.0, 1.0)
            contact = solver.add_planar_contact(task)
            contact.length = float(c["length"])
            contact.width = float(c["width"])
            contact.mu = float(c["mu"])
            if c.get("weight_moments") is not None:
                contact.weight_moments = float(c["weight_moments"])
            self.keep += [task, contact]
        self.tasks: dict[str, tuple[str, Any]] = {}
        for spec in msg["tasks"]:
            self.tasks[spec["name"]] = (spec["kind"], self._task(spec, names))
        self.nq, self.nv = robot.state.q.size, robot.state.qd.size
        self.zeros_tau = np.zeros(self.nv - 6)
        self.zeros_qdd = np.zeros(self.nv)

    def _task(self, spec: dict[str, Any], names: list[str]) -> Any:
        """Add one task of the ``setup`` request to the solver and return it."""
        robot, solver, kind, target = self.robot, self.solver, spec["kind"], spec.get("target")
        if kind == "com":
            goal = np.array([np.nan if v is None else float(v) for v in target])
            if np.isnan(goal[2]):
                goal[2] = robot.com_world()[2]
            task = solver.add_com_task(goal)
            if spec.get("mask"):
                task.mask.set_axises(spec["mask"])
        elif kind == "position":
            task = solver.add_position_task(spec["frame"], np.asarray(target, dtype=float))
        elif kind == "orientation":
            rotation = (robot.get_T_world_frame(spec["frame"])[:3, :3] if target is None
                        else np.asarray(target, dtype=float))
            task = solver.add_orientation_task(spec["frame"], rotation)
        elif kind == "joints":
            task = solver.add_joints_task()
            joints = ({n: float(robot.get_joint(n)) for n in names} if target is None
                      else {str(k): float(v) for k, v in target.items()})
            task.set_joints(joints)
        else:
            raise ValueError(f"task {spec['name']!r}: unknown kind {kind!r}")
        if spec.get("kp") is not None:
            task.kp = float(spec["kp"])
        if spec.get("kd") is not None:
            task.kd = float(spec["kd"])
        task.configure(spec["name"], spec["priority"], float(spec["weight"]))
        return task

    def step(self, q: np.ndarray, v: np.ndarray, refs: dict[str, Any]
             ) -> tuple[np.ndarray, np.ndarray, bool]:
        """One control step: state, kinematics, references, solve; torques and accelerations."""
        robot = self.robot
        robot.state.q = q
        robot.state.qd = v
        robot.update_kinematics()
        for name, ref in refs.items():
            kind, task = self.tasks[name]
            if kind == "orientation":
                task.R_world_frame = ref["R"]
                task.omega_world = ref["omega"]
            elif kind == "joints":
                task.set_joints(ref["joints"])
            else:
                task.ddtarget_world = ref["acceleration"]
        result = self.solver.solve(False)
        if not result.success:  # (tau_dict of a failed solve crashes placo 0.10.2)
            return self.zeros_tau, self.zeros_qdd, False
        return np.asarray(result.tau)[6:], np.asarray(result.qdd), True


def _reply(out: TextIO, payload: dict[str, Any]) -> None:
    out.write(json.dumps(payload) + "\n")
    out.flush()


def _refs(raw: dict[str, Any]) -> dict[str, Any]:
    """Return the ``step`` references as numpy arrays (decoded before the step's clock starts)."""
    out: dict[str, Any] = {}
    for name, ref in raw.items():
        if "R" in ref:
            out[name] = {"R": np.asarray(ref["R"], dtype=float),
                         "omega": np.asarray(ref["omega"], dtype=float)}
        elif "joints" in ref:
            out[name] = {"joints": {str(k): float(v) for k, v in ref["joints"].items()}}
        else:
            out[name] = {"acceleration": np.asarray(ref["acceleration"], dtype=float)}
    return out


def serve(inp: TextIO, out: TextIO) -> None:
    """Answer requests until ``quit`` or the end of the input (module docstring)."""
    dynamics: Dynamics | None = None
    for line in inp:
        if not line.strip():
            continue
        try:
            msg = json.loads(line)
            op = msg.get("op")
            if op in ("quit", "hello"):
                _reply(out, {"ok": True})
                if op == "quit":
                    return
                continue
            if op == "setup":
                dynamics = None
                dynamics = Dynamics(msg)
                _reply(out, {"ok": True, "placo_version": metadata.version("placo"),
                             "pinocchio_version": pin.__version__,
                             "nq": dynamics.nq, "nv": dynamics.nv,
                             "com": dynamics.robot.com_world().tolist()})
                continue
            if op == "step":
                if dynamics is None:
                    raise RuntimeError("step before setup")
                q = np.asarray(msg["q"], dtype=float)
                v = np.asarray(msg["v"], dtype=float)
                refs = _refs(msg.get("refs") or {})
                c0, w0 = time.process_time(), time.perf_counter()
                tau, qdd, ok = dynamics.step(q, v, refs)
                w1, c1 = time.perf_counter(), time.process_time()
                _reply(out, {"ok": True, "tau": tau.tolist(), "qdd": qdd.tolist(),
                             "success": ok, "wall_s": w1 - w0, "cpu_s": c1 - c0})
                continue
            if op == "placements":
                if dynamics is None:
                    raise RuntimeError("placements before setup")
                robot = dynamics.robot
                _reply(out, {"ok": True, "com": robot.com_world().tolist(),
                             "T": {f: robot.get_T_world_frame(f).tolist()
                                   for f in msg["frames"]}})
                continue
            raise ValueError(f"unknown op {op!r}")
        except Exception as exc:  # noqa: BLE001 - every failure goes back to the caller
            _reply(out, {"ok": False, "error": f"{type(exc).__name__}: {exc}"})


def _protocol_stdout() -> TextIO:
    """Keep file descriptor 1 for the replies; send everything else written there to stderr."""
    sys.stdout.flush()
    replies = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    return replies


if __name__ == "__main__":
    serve(sys.stdin, _protocol_stdout())
