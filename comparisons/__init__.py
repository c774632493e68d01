"""The seed papers' experiments, run in MuJoCo by every controller (``hqp compare``).

One module per scenario; :data:`SCENARIOS` is the registry:

- ``hand-reach``: hierarchy paper, section 5, Figures 3-5 (joint limits,
  centre of gravity, right hand, symmetry posture; hierarchies ``shared``
  (eq. 29-30) and ``cog-first`` (eq. 31));
- ``obstacle``: hierarchy paper, Figure 2 (obstacle avoidance in the
  collision sub-level while the right hand holds still);
- ``box-grab``: hierarchy paper, Figure 1 (both hands to goals, centre of
  gravity over the feet, torso upright);
- ``screwgun``: architecture paper, Table 1 / Figure 7 (hybrid hand task,
  gaze, posture switching, internal forces between the feet).
"""

from __future__ import annotations

import importlib

from comparisons.base import CONTROLLERS, RunResult, RunSpec, Scenario, ScenarioResult
from hqp.errors import UnknownName

_MODULES: dict[str, tuple[str, str]] = {
    "hand-reach": ("comparisons.hand_reach", "HandReach"),
    "obstacle": ("comparisons.obstacle", "Obstacle"),
    "box-grab": ("comparisons.box_grab", "BoxGrab"),
    "screwgun": ("comparisons.screwgun", "Screwgun"),
}
"""Module and class of each scenario (imported on demand: they import the simulator)."""

SCENARIOS: tuple[str, ...] = tuple(_MODULES)
"""Names of the registered scenarios, in the order ``hqp compare --all`` runs them."""


def get_scenario(name: str) -> Scenario:
    """Return a new scenario object by name.

    Raises:
        UnknownName: Not a registered scenario (the message lists them).

    """
    if name not in _MODULES:
        raise UnknownName("scenario", name, SCENARIOS)
    module, cls = _MODULES[name]
    return getattr(importlib.import_module(module), cls)()


__all__ = [
    "CONTROLLERS",
    "SCENARIOS",
    "RunResult",
    "RunSpec",
    "Scenario",
    "ScenarioResult",
    "get_scenario",
]
