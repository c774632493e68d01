"""Closed-loop traces whose bits a change to the loop must not change, on one machine.

A developer's check, not a test: the digests depend on the machine (its instruction set, the
native core's build flags, the memory layout of the process), so they are compared before and
after a change on the same machine: ``PYTHONPATH=. python scripts/loop_traces.py --record``
before, ``PYTHONPATH=. python scripts/loop_traces.py`` after (exit 1 where a digest differs).

Each trace maps a name to an array of one run: a behavior run (g1 walking) through
:func:`hqp.sim.closed_loop` as ``hqp run`` drives it, and a pushed standing run through
:func:`hqp.sim.simulate`. :func:`digests` hashes them (SHA-256 of each float64 array's bytes).

Record again only before a loop change, never to make one pass.
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
    """Return the float arrays of :func:`hqp.sim.simulate`'s log of a pushed standing run."""
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
    """Return a float standing for a text (its digest's first 6 bytes), hashed with the arrays."""
    return float(int.from_bytes(hashlib.sha256(text.encode()).digest()[:6], "big"))


def digests(trace: dict[str, np.ndarray]) -> dict[str, str]:
    """SHA-256 of each array's float64 bytes (C order), with its shape."""
    return {k: f"{v.shape}:" + hashlib.sha256(np.ascontiguousarray(v, dtype=np.float64)
                                                  .tobytes()).hexdigest()
            for k, v in sorted(trace.items())}


def record() -> dict[str, dict[str, str]]:
    """Return the digests of both traces."""
    return {"walk_g1": digests(behavior_trace()), "stand_push_g1": digests(stand_trace())}


def main() -> int:
    """``--record``: write the digests of this machine; else compare with the recorded ones."""
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", action="store_true", help="record the digests")
    args = parser.parse_args()
    now = record()
    if args.record:
        FIXTURE.write_text(json.dumps(now, indent=1, sort_keys=True) + "\n")
        print(f"wrote {FIXTURE}")
        return 0
    before = json.loads(FIXTURE.read_text())
    changed = [f"{run}/{key}" for run, arrays in now.items() for key, digest in arrays.items()
               if before.get(run, {}).get(key) != digest]
    print("identical" if not changed else "changed: " + ", ".join(changed))
    return 1 if changed else 0


if __name__ == "__main__":
    raise SystemExit(main())
