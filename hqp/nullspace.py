"""Re-exports of the null-space cross-check, which now lives in :mod:`hqp.control.nullspace`.

The law (``prioritized_torques``, ``LawLevel``, ``LawSolution``): ``law.py``; the multi-contact
form (``law_problem``, ``floating_base_metric``): ``multicontact.py``; activation zones, support
polygon, centre of pressure: ``zones.py``; ``NullSpaceController`` (the servo with a
``NullSpaceResolver``): ``resolver.py``; the standing controllers by name:
:mod:`hqp.control.presets`. Derivation and measured results: docs/nullspace.md.
"""

from hqp.control.nullspace import (
    EIG_TOL,
    PHI_TOL,
    SUPPORT_ZONE,
    TORQUE_ZONE,
    LawLevel,
    LawProblem,
    LawSolution,
    NullSpaceController,
    NullSpaceResolver,
    center_of_pressure,
    floating_base_metric,
    law_problem,
    prioritized_torques,
    project_to_polygon,
    support_moment_rows,
    support_polygon,
)
from hqp.control.presets import (
    CONTROLLER_NAMES,
    make_standing_controller,
    papers_joint_limits,
    standing_nullspace_controller,
)

__all__ = [
    "CONTROLLER_NAMES",
    "EIG_TOL",
    "PHI_TOL",
    "SUPPORT_ZONE",
    "TORQUE_ZONE",
    "LawLevel",
    "LawProblem",
    "LawSolution",
    "NullSpaceController",
    "NullSpaceResolver",
    "center_of_pressure",
    "floating_base_metric",
    "law_problem",
    "make_standing_controller",
    "papers_joint_limits",
    "prioritized_torques",
    "project_to_polygon",
    "standing_nullspace_controller",
    "support_moment_rows",
    "support_polygon",
]
