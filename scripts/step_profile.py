"""What the Python around the engine costs in each control step of a library behavior.

For each behavior run in MuJoCo (``hqp.app.run.run_behavior``, its own robot unless
``--robot``), per control step: whether the step ran on the native engine, whether it built
the engine's copy of the stack, the Python function calls inside ``controller.step``
(``sys.setprofile``) and its CPU time. Prints one JSON object per behavior:

    OMP_NUM_THREADS=1 python scripts/step_profile.py stand reach squat-jump walk mimic screwgun
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from hqp.app.run import run_behavior
from hqp.control import native
from hqp.control.servo import WholeBodyController


def profile(behavior: str, robot: str | None, limit: int) -> dict[str, object]:
    """Run ``behavior`` and return its per-step figures (see the module docstring)."""
    steps: list[tuple[bool, bool, int, float]] = []
    builds = [0]
    step, build = WholeBodyController.step, native.NativeStepMirror.__init__

    def counted_build(self, *args, **kwargs):
        builds[0] += 1
        build(self, *args, **kwargs)

    def counted_step(self, state, t):
        calls = 0

        def count(frame, event, arg):
            nonlocal calls
            calls += event == "call"

        before, built = self.native.steps, builds[0]
        start = time.process_time()
        sys.setprofile(count)
        try:
            return step(self, state, t)
        finally:
            sys.setprofile(None)
            steps.append((self.native.steps > before, builds[0] > built, calls,
                          time.process_time() - start))

    WholeBodyController.step = counted_step
    native.NativeStepMirror.__init__ = counted_build
    try:
        run = run_behavior(behavior, robot=robot)
    finally:
        WholeBodyController.step, native.NativeStepMirror.__init__ = step, build
    ran, built, calls, cpu = (np.array(c) for c in zip(*steps[1:]))  # (the first builds)
    return {
        "behavior": behavior, "robot": run.robot, "fell": run.fell, "steps": len(steps),
        "python_steps": int((~ran).sum()), "builds": int(builds[0]),
        "calls_median": float(np.median(calls)), "calls_max": int(calls.max()),
        f"share_within_{limit}_calls": round(float(np.mean(calls <= limit)), 3),
        "cpu_median_ms": round(1e3 * float(np.median(cpu)), 3),
        "cpu_p99_ms": round(1e3 * float(np.percentile(cpu, 99)), 3),
        "cpu_max_ms": round(1e3 * float(cpu.max()), 2),
        "cpu_max_without_build_ms": round(1e3 * float(cpu[~built].max()), 2),
    }


def main() -> None:
    """Profile the behaviors named on the command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("behaviors", nargs="+")
    parser.add_argument("--robot", default=None)
    parser.add_argument("--limit", type=int, default=20, help="calls per step counted within")
    args = parser.parse_args()
    for behavior in args.behaviors:
        print(json.dumps(profile(behavior, args.robot, args.limit)), flush=True)


if __name__ == "__main__":
    main()
