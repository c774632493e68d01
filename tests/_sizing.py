"""The first steps of a native-step mirror, which may allocate (they size everything)."""

import numpy as np


def sized(robot, ctrl, mirror, seed):
    """Three steps at a state near standing (allowed to allocate: they size everything);
    returns ``(core, q, v)``."""
    core, model = mirror.step_core, ctrl.model
    rng = np.random.default_rng(seed)
    q = robot.q_standing.copy()
    q[7:] += rng.normal(scale=0.003, size=model.na)
    v = rng.normal(scale=0.01, size=model.nv)
    for i in range(3):
        mirror.push_goals(0.001 * i)
        core.step(q, v, ctrl.dt)
    return core, q, v
