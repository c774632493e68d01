"""The distribution of control-step times: the README's controller beside PlaCo and TSID.

Every controller steps in order through the controller suite's closed-loop sequence of a robot
(200 consecutive states of a standing run pushed forward, :func:`hqp.bench.suite_controller.
states`), ``--passes`` times, one configuration after the other per state; PlaCo and TSID are
timed inside their workers (their environments: ``python -m hqp.bench.peer_env placo``,
``tsid``). The figure shows each controller's CPU time per step as a complementary cumulative
distribution (the fraction of steps slower than a time, log scales: the tail a servo is
judged by)::

    OMP_NUM_THREADS=1 python scripts/latency_plot.py --robot g1 --out docs/figures/latency-g1.png
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hqp.bench.suite_controller import NATIVE_STEP, PLACO, TSID, _Stepper, states  # noqa: E402
from hqp.bench.worker import PeerUnavailable  # noqa: E402
from hqp.robots import load  # noqa: E402

LABELS = {NATIVE_STEP: "hqp (README's controller)", PLACO: "PlaCo", TSID: "TSID"}


def measure(robot_name: str, passes: int) -> dict[str, np.ndarray]:
    """CPU time per step [ms] of each available controller over the sequence."""
    robot = load(robot_name)
    sts = states(robot_name)
    steppers = {}
    for name in LABELS:
        try:
            steppers[name] = _Stepper(name, robot, sts)
        except PeerUnavailable as exc:
            print(f"{name} skipped: {exc}")
    cpu: dict[str, list[float]] = {name: [] for name in steppers}
    try:
        for _ in range(passes):
            for _state in sts:
                for name, st in steppers.items():
                    c0 = time.thread_time()
                    st()
                    if st.peer is None:
                        cpu[name].append(time.thread_time() - c0)
        for name, st in steppers.items():
            if st.peer is not None:
                cpu[name] = list(st.peer.cpu)
    finally:
        for st in steppers.values():
            if st.peer is not None:
                st.peer.close()
    return {name: 1e3 * np.asarray(v) for name, v in cpu.items()}


def plot(times: dict[str, np.ndarray], robot: str, out: Path) -> None:
    """Write the complementary cumulative distributions to ``out``."""
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    for name, t in times.items():
        x = np.sort(t)
        y = 1.0 - np.arange(x.size) / x.size
        ax.step(x, y, where="post", label=f"{LABELS[name]}: median {np.median(t):.2f} ms, "
                f"p99 {np.percentile(t, 99):.2f} ms, max {t.max():.1f} ms")
    ax.axvline(1.0, color="0.5", linestyle=":", linewidth=1)
    ax.text(1.02, 0.6, "1 ms (1 kHz)", color="0.4", fontsize=8, transform=ax.get_xaxis_transform())
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU time of a control step [ms]")
    ax.set_ylabel("fraction of steps slower")
    ax.set_title(f"{robot}: 200 consecutive closed-loop states, a forward push of 1.5 N/kg")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)


def main() -> int:
    """Measure and plot."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--passes", type=int, default=5, help="passes over the sequence")
    parser.add_argument("--out", type=Path, default=Path("latency.png"))
    args = parser.parse_args()
    times = measure(args.robot, args.passes)
    plot(times, args.robot, args.out)
    for name, t in times.items():
        print(f"{name}: median {np.median(t):.3f} p99 {np.percentile(t, 99):.3f} "
              f"max {t.max():.2f} ms over {t.size} steps")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
