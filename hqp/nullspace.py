"""Re-exports of the null-space cross-check, which now lives in :mod:`hqp.control.nullspace`.

The law (``prioritized_torques``, ``LawLevel``, ``LawSolution``): ``law.py``; the multi-contact
form (``law_problem``, ``floating_base_metric``): ``multicontact.py``; activation zones, support
polygon, centre of pressure: ``zones.py``; ``NullSpaceController`` (the servo with a
``NullSpaceResolver``): ``resolver.py``; the standing controllers by name:
:mod:`hqp.control.presets`. Derivation and measured results: docs/design/nullspace.md.
"""

from hqp.control import nullspace as _nullspace
from hqp.control.nullspace import *  # noqa: F403
from hqp.control.presets import (
    CONTROLLER_NAMES,
    make_standing_controller,
    papers_joint_limits,
    standing_nullspace_controller,
)

__all__ = [*_nullspace.__all__, "CONTROLLER_NAMES", "make_standing_controller",
           "papers_joint_limits", "standing_nullspace_controller"]
