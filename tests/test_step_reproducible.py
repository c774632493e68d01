"""The README's controller gives the same torques, bit for bit, in every process, whatever its
memory layout (docs/concepts/architecture.md, "Determinism").

One closed loop in MuJoCo: ``hqp.standing_controller`` on g1 through its native step, the right
hand sent out of reach (the hand and the posture levels in conflict) and the base pushed for
0.1 s. It runs in fresh processes whose memory layouts differ, and the digests of every step's
torques must be equal:

- heaps of different histories: dummy ``malloc`` blocks whose sizes move glibc's next blocks
  by 16 bytes, dummy NumPy arrays, different ``PYTHONHASHSEED`` (Python's objects and their
  order), environments of different sizes (the initial stack pointer);
- every heap block at a chosen offset from a 64-byte boundary, drawn per block
  (``tests/_malloc_offsets.c`` preloaded; compiled here with the C compiler that builds the
  core, the test skips where there is none).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("hqp._core._ext")

STEPS = 300
"""Control steps of the closed loop (1 kHz): the push spans steps 50 to 149."""

LOOP = """
import ctypes, hashlib, json, sys
import numpy as np
libc = ctypes.CDLL(None)
libc.malloc.restype = ctypes.c_void_p
dummies = [libc.malloc(int(k)) for k in sys.argv[2].split(",")]
arrays = [np.empty(int(k)) for k in sys.argv[3].split(",")]
import hqp
from hqp.tasks.base import Category
from hqp.tasks.position import PositionTask
robot = hqp.robots.load("g1")
controller = hqp.standing_controller(robot)
model = controller.model
hand = PositionTask(model, robot.hands[1], name="hand", kp=30.0)
model.update(robot.q_standing, np.zeros(model.nv))
hand.set_goal(model.frame_placement(robot.hands[1]).translation + np.array([1.5, 0.0, 0.0]))
controller.add_task(hand, Category.OPERATIONAL, t=0.0)
sim = hqp.Simulator(robot)
push = np.array([60.0, 0.0, 0.0])  # [N] on the base, about 1.7 N/kg
digests, conflicts = [], set()
for k in range(int(sys.argv[1])):
    command = controller.step(sim.state(), k * sim.dt)
    digests.append(hashlib.sha256(np.ascontiguousarray(command.tau).tobytes()).hexdigest())
    conflicts |= {s.name for s in command.report.tasks if s.status.value == "conflict"}
    sim.step(command.tau, force=push if 50 <= k < 150 else None)
native = controller.native
print(json.dumps({"digests": digests, "conflicts": sorted(conflicts),
                  "native_steps": native.steps if native is not None else 0,
                  "fallen": sim.fallen()}))
"""

HEAPS = (
    # (malloc sizes [bytes], NumPy array sizes, PYTHONHASHSEED, environment padding [bytes])
    ("8", "1", "0", 0),
    ("40,24,1000", "3,517,12", "1", 1000),
    ("72,40000,8", "40000,7", "2", 4099),
)
"""The processes of different heap histories compared."""

MALLOC_SEEDS = ("0", "1", "2")
"""The seeds of the preloaded malloc's per-block offsets (0: every block 64-byte aligned)."""


def _loop(env: dict[str, str], malloc: str = "8", arrays: str = "1") -> dict:
    proc = subprocess.run([sys.executable, "-c", LOOP, str(STEPS), malloc, arrays],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "OMP_NUM_THREADS": "1", **env})
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.splitlines()[-1])


def _assert_identical(runs: list[dict]) -> None:
    first = runs[0]
    assert first["native_steps"] == STEPS  # every step ran in the engine
    assert not first["fallen"]
    assert {"hand", "posture"} <= set(first["conflicts"]), first["conflicts"]
    for run in runs[1:]:
        differ = [k for k, (a, b) in enumerate(zip(first["digests"], run["digests"])) if a != b]
        assert not differ, f"torques differ from step {differ[0]} on ({len(differ)} steps)"
        assert run["digests"] == first["digests"]


def test_torques_identical_across_heap_histories():
    runs = [_loop({"PYTHONHASHSEED": seed, "HQP_TEST_PADDING": "x" * pad}, malloc, arrays)
            for malloc, arrays, seed, pad in HEAPS]
    _assert_identical(runs)


@pytest.fixture(scope="module")
def malloc_offsets(tmp_path_factory) -> Path:
    """``tests/_malloc_offsets.c`` built as a shared library for ``LD_PRELOAD``."""
    if not sys.platform.startswith("linux"):
        pytest.skip("the preloaded malloc is glibc's interposition (Linux)")
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler to build tests/_malloc_offsets.c")
    out = tmp_path_factory.mktemp("malloc") / "malloc_offsets.so"
    source = Path(__file__).with_name("_malloc_offsets.c")
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(out), str(source)], check=True)
    return out


def test_torques_identical_whatever_each_blocks_alignment(malloc_offsets):
    runs = [_loop({"LD_PRELOAD": str(malloc_offsets), "HQP_MALLOC_SEED": seed,
                   "PYTHONHASHSEED": "0"}) for seed in MALLOC_SEEDS]
    _assert_identical(runs)


def test_the_preloaded_malloc_moves_blocks(malloc_offsets):
    """The offsets it draws are the ones the test relies on: a seed other than 0 puts blocks
    off 32-byte boundaries, seed 0 puts every block on a 64-byte boundary."""
    code = ("import numpy as np; print(*[np.empty(k).ctypes.data % 64 "
            "for k in range(200, 264)])")
    offsets = {}
    for seed in MALLOC_SEEDS[:2]:
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              env={**os.environ, "LD_PRELOAD": str(malloc_offsets),
                                   "HQP_MALLOC_SEED": seed}, timeout=120, check=True)
        offsets[seed] = {int(o) for o in proc.stdout.split()}
    assert offsets["0"] == {0}
    assert offsets["1"] == {0, 16, 32, 48}
