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

from comparisons.base import CONTROLLERS, RunResult, RunSpec, Scenario, ScenarioResult
from hqp.errors import UnknownName


def _registry() -> dict[str, type[Scenario]]:
    """Scenario classes by name (imported lazily: they import the simulator)."""
    from comparisons.box_grab import BoxGrab
    from comparisons.hand_reach import HandReach
    from comparisons.obstacle import Obstacle
    from comparisons.screwgun import Screwgun

    return {cls.name: cls for cls in (HandReach, Obstacle, BoxGrab, Screwgun)}


SCENARIOS: tuple[str, ...] = ("hand-reach", "obstacle", "box-grab", "screwgun")
"""Names of the registered scenarios, in the order ``hqp compare --all`` runs them."""


def get_scenario(name: str) -> Scenario:
    """Return a new scenario object by name.

    Raises:
        UnknownName: Not a registered scenario (the message lists them).

    """
    registry = _registry()
    if name not in registry:
        raise UnknownName("scenario", name, SCENARIOS)
    return registry[name]()


__all__ = [
    "CONTROLLERS",
    "SCENARIOS",
    "RunResult",
    "RunSpec",
    "Scenario",
    "ScenarioResult",
    "get_scenario",
]
