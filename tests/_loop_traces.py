"""Closed-loop traces whose bits the loop's speed-ups must not change (tests/test_loop_bits.py).

Each trace maps a name to an array of one run: a behavior run (g1 walking) through
:func:`hqp.sim.closed_loop` as ``hqp run`` drives it, and a pushed standing run through
:func:`hqp.sim.simulate`. :func:`digests` hashes them (SHA-256 of each float64 array's bytes).

Record again (only when the controller or the robot files change on purpose, never to make a
loop change pass): ``PYTHONPATH=. python tests/_loop_traces.py``.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

FIXTURE = Path(__file__).parent / "data" / "loop_traces.json"
WALK_SECONDS = 3.0
STAND_SECONDS = 1.5


def behavior_trace(name: str = "walk", robot: str = "g1",
                   duration: float = WALK_SECONDS) -> dict[str, np.ndarray]:
    """Per-step state, torques and MuJoCo contacts of a behavior run (clock ``k dt``)."""
    from hqp.behaviors.setup import prepare
    from hqp.sim import Simulator, closed_loop

    behavior, ctrl, robot_obj = prepare(name, robot=robot)
    sim = Simulator(robot_obj)
    ctrl.dt = sim.dt
    behavior.start(sim.state(), 0.0)
    rows: dict[str, list[np.ndarray]] = {k: [] for k in ("q", "v", "tau", "fc", "fp", "fn")}

    def before(step) -> None:
        rows["q"].append(np.array(step.state.q))
        rows["v"].append(np.array(step.state.v))
        rows["tau"].append(np.array(step.command.tau))

    def after(step, reading) -> None:
        rows["fc"].append(np.array(reading.foot_contact, dtype=float))
        rows["fp"].append(np.array(reading.foot_position))
        rows["fn"].append(np.array(reading.normal_force))

    closed_loop(sim, behavior, duration, before_step=before, after_step=after, clock="steps")
    out = {k: np.array(v) for k, v in rows.items()}
    out["phases"] = np.array([hash_text(" ".join(behavior.visited))])
    return out


def stand_trace(robot: str = "g1", duration: float = STAND_SECONDS) -> dict[str, np.ndarray]:
    """The float arrays of :func:`hqp.sim.simulate`'s log of a pushed standing run."""
    import hqp.robots as robots
    from hqp.controller import standing_controller
    from hqp.sim import Push, simulate

    r = robots.load(robot)
    log = simulate(r, standing_controller(r), duration, [Push(0.5, (40.0, 25.0, 0.0), 0.1)])
    out = {k: np.asarray(getattr(log, k), dtype=float) for k in (
        "t", "q", "v", "tau", "com", "base_height", "foot_contact", "foot_position",
        "normal_force", "other_contact", "cop", "support_margin", "safe_mode",
        "strictness_suspended", "clipped")}
    for name, values in sorted(log.task_errors.items()):
        out[f"error:{name}"] = values
    for name, values in sorted(log.residuals.items()):
        out[f"residual:{name}"] = values
    out["status"] = np.array([hash_text(json.dumps(log.status, sort_keys=True))])
    return out


def hash_text(text: str) -> float:
    """A float standing for a text (its digest's first 6 bytes) so it hashes with the arrays."""
    return float(int.from_bytes(hashlib.sha256(text.encode()).digest()[:6], "big"))


def digests(trace: dict[str, np.ndarray]) -> dict[str, str]:
    """SHA-256 of each array's float64 bytes (C order), with its shape."""
    return {k: f"{v.shape}:" + hashlib.sha256(np.ascontiguousarray(v, dtype=np.float64)
                                                  .tobytes()).hexdigest()
            for k, v in sorted(trace.items())}


def record() -> dict[str, dict[str, str]]:
    """Return the digests of both traces."""
    return {"walk_g1": digests(behavior_trace()), "stand_push_g1": digests(stand_trace())}


if __name__ == "__main__":
    FIXTURE.write_text(json.dumps(record(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {FIXTURE}")
