"""TSID's control step on the standing task set, served to the controller suite over a pipe.

This file runs in TSID's own environment (``python -m hqp.bench.peer_env tsid`` makes it:
TSID's wheel needs another pinocchio than hqp's), started by :func:`hqp.bench.worker.start` as
``<tsid python> -I tsid_worker.py``. It imports nothing of hqp: numpy, pinocchio and tsid only.

Protocol: one JSON object per line on stdin, one JSON reply per line on stdout.

- ``{"op": "hello"}`` -> ``{"ok": true}``;
- ``{"op": "setup", "urdf": ..., "q": [...], "feet": [{"frame", "half_length",
  "half_width", "mu"}], "trunk": ..., "dt": ..., "gains": {...}, "weights": {...}}`` ->
  ``{"ok": true, "tsid_version": ..., "pinocchio_version": ..., "nq": ..., "nv": ...}``;
- ``{"op": "step", "q": [...], "v": [...], "t": ...}`` -> ``{"ok": true, "tau": [...],
  "wall_s": ..., "cpu_s": ..., "success": ...}``: the step's own wall-clock and CPU time
  (problem data, solve, torques), measured here so the pipe is not counted;
- ``{"op": "quit"}`` -> ``{"ok": true}``, then the worker exits.

A request that fails gets ``{"ok": false, "error": "<type>: <message>"}``.

The task set is hqp's standing set (:func:`hqp.control.presets.standing_controller`), the way
TSID's own demos write it: both soles as ``Contact6d`` (four corners, friction, normal force
bounds) with their motion at priority 0; actuation and joint position/velocity bounds at
priority 0; centre of mass, trunk orientation (``TaskSE3Equality`` masked to the rotation)
and posture as weighted tasks of priority 1 (TSID has two levels: strict priority between
the centre of mass and the posture cannot be expressed).
"""

from __future__ import annotations

import json
import sys
import time
from importlib import metadata
from typing import Any, TextIO

import numpy as np
import pinocchio as pin
import tsid

if not hasattr(tsid, "RobotWrapper"):  # tsid 1.7.1's wheel: the bindings beside the package
    from tsid import tsid_pywrap as tsid  # type: ignore[no-redef]


def _kd(kp: float) -> float:
    """Critical damping of a PD of stiffness ``kp``."""
    return 2.0 * float(np.sqrt(kp))


class Standing:
    """TSID's inverse-dynamics formulation holding a humanoid on both feet."""

    def __init__(self, msg: dict[str, Any]) -> None:
        gains = msg["gains"]
        weights = msg["weights"]
        self.robot = tsid.RobotWrapper(msg["urdf"], [], pin.JointModelFreeFlyer(), False)
        model = self.robot.model()
        q = np.asarray(msg["q"], dtype=float)
        if q.size != model.nq:
            raise ValueError(f"TSID's model has nq = {model.nq}, the state {q.size}")
        v = np.zeros(model.nv)
        self.dt = float(msg["dt"])
        self.form = tsid.InverseDynamicsFormulationAccForce("tsid", self.robot, False)
        self.form.computeProblemData(0.0, q, v)
        data = self.form.data()
        self.keep: list[Any] = []  # TSID's bindings hold raw pointers to tasks and references
        for foot in msg["feet"]:
            hl, hw = foot["half_length"], foot["half_width"]
            corners = np.array([[hl, hl, -hl, -hl], [hw, -hw, -hw, hw], [0.0, 0.0, 0.0, 0.0]])
            contact = tsid.Contact6d(foot["frame"], self.robot, foot["frame"], corners,
                                     np.array([0.0, 0.0, 1.0]), foot["mu"], foot["f_min"],
                                     foot["f_max"])
            contact.setKp(gains["contact"] * np.ones(6))
            contact.setKd(_kd(gains["contact"]) * np.ones(6))
            fid = self.robot.model().getFrameId(foot["frame"])
            contact.setReference(self.robot.framePosition(data, fid))
            self.form.addRigidContact(contact, weights["force_regularization"], 1.0, 0)
            self.keep.append(contact)
        com = tsid.TaskComEquality("com", self.robot)
        com.setKp(gains["com"] * np.ones(3))
        com.setKd(_kd(gains["com"]) * np.ones(3))
        self.form.addMotionTask(com, weights["com"], 1, 0.0)
        feet_center = np.asarray(msg["com_goal"], dtype=float)
        com_ref = tsid.TrajectoryEuclidianConstant("com_ref", feet_center)
        com_sample = com_ref.computeNext()
        com.setReference(com_sample)
        trunk = tsid.TaskSE3Equality("trunk", self.robot, msg["trunk"])
        trunk.setKp(gains["trunk"] * np.ones(6))
        trunk.setKd(_kd(gains["trunk"]) * np.ones(6))
        trunk.setMask(np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]))
        trunk_pose = self.robot.framePosition(data, model.getFrameId(msg["trunk"]))
        trunk_ref = tsid.TrajectorySE3Constant("trunk_ref", trunk_pose)
        trunk_sample = trunk_ref.computeNext()
        trunk.setReference(trunk_sample)
        self.form.addMotionTask(trunk, weights["trunk"], 1, 0.0)
        na = model.nv - 6
        posture = tsid.TaskJointPosture("posture", self.robot)
        posture.setKp(gains["posture"] * np.ones(na))
        posture.setKd(_kd(gains["posture"]) * np.ones(na))
        posture_ref = tsid.TrajectoryEuclidianConstant("posture_ref", q[7:])
        posture_sample = posture_ref.computeNext()
        posture.setReference(posture_sample)
        self.form.addMotionTask(posture, weights["posture"], 1, 0.0)
        tau_max = np.asarray(msg["tau_max"], dtype=float)
        actuation = tsid.TaskActuationBounds("actuation", self.robot)
        actuation.setBounds(-tau_max, tau_max)
        self.form.addActuationTask(actuation, 1.0, 0, 0.0)
        bounds = tsid.TaskJointPosVelAccBounds("joint_bounds", self.robot, self.dt, False)
        bounds.setPositionBounds(np.asarray(msg["q_lower"]), np.asarray(msg["q_upper"]))
        bounds.setVelocityBounds(np.asarray(msg["v_max"]))
        bounds.setAccelerationBounds(np.asarray(msg["a_max"]))
        self.form.addMotionTask(bounds, 1.0, 0, 0.0)
        self.keep += [com, com_ref, com_sample, trunk, trunk_ref, trunk_sample, posture,
                      posture_ref, posture_sample, actuation, bounds]
        self.solver = tsid.SolverHQuadProgFast("qp")
        self.solver.resize(self.form.nVar, self.form.nEq, self.form.nIn)
        self.nq, self.nv = model.nq, model.nv

    def step(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, bool]:
        """One control step: problem data at ``(q, v)``, solve, actuator torques."""
        problem = self.form.computeProblemData(t, q, v)
        sol = self.solver.solve(problem)
        ok = sol.status == 0
        tau = self.form.getActuatorForces(sol) if ok else np.zeros(self.nv - 6)
        return np.asarray(tau), ok


def _reply(out: TextIO, payload: dict[str, Any]) -> None:
    out.write(json.dumps(payload) + "\n")
    out.flush()


def serve(inp: TextIO, out: TextIO) -> None:
    """Answer requests until ``quit`` or the end of the input (module docstring)."""
    standing: Standing | None = None
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
                standing = Standing(msg)
                _reply(out, {"ok": True, "tsid_version": metadata.version("tsid"),
                             "pinocchio_version": pin.__version__,
                             "nq": standing.nq, "nv": standing.nv})
                continue
            if op == "step":
                if standing is None:
                    raise RuntimeError("step before setup")
                q = np.asarray(msg["q"], dtype=float)
                v = np.asarray(msg["v"], dtype=float)
                c0, w0 = time.process_time(), time.perf_counter()
                tau, ok = standing.step(q, v, float(msg.get("t", 0.0)))
                w1, c1 = time.perf_counter(), time.process_time()
                _reply(out, {"ok": True, "tau": tau.tolist(), "success": ok,
                             "wall_s": w1 - w0, "cpu_s": c1 - c0})
                continue
            raise ValueError(f"unknown op {op!r}")
        except Exception as exc:  # noqa: BLE001 - every failure goes back to the caller
            _reply(out, {"ok": False, "error": f"{type(exc).__name__}: {exc}"})


if __name__ == "__main__":
    serve(sys.stdin, sys.stdout)
