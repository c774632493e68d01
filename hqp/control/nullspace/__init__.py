"""The papers' null-space torque law (seed 003 eq. 11-23; Sentis 2010), as a servo resolver.

- :mod:`~hqp.control.nullspace.law`: :func:`prioritized_torques` on plain matrices;
- :mod:`~hqp.control.nullspace.multicontact`: a built stack as the law's matrices and back;
- :mod:`~hqp.control.nullspace.zones`: contact and actuation limits as activation zones;
- :mod:`~hqp.control.nullspace.resolver`: :class:`NullSpaceResolver` and
  :class:`NullSpaceController`;
- :mod:`~hqp.control.nullspace.native`: the law's native step (the controller's default on a
  bundled robot).

Derivations and measured results: docs/design/nullspace.md.
"""

from hqp.control.nullspace.law import EIG_TOL, PHI_TOL, LawLevel, LawSolution, prioritized_torques
from hqp.control.nullspace.multicontact import (
    LawProblem,
    decision_vector,
    floating_base_metric,
    law_problem,
    utilization_weights,
)
from hqp.control.nullspace.resolver import (
    INTERNAL_FORCES,
    NullSpaceController,
    NullSpaceResolver,
)
from hqp.control.nullspace.zones import (
    SUPPORT_ZONE,
    TORQUE_ZONE,
    ZoneSettings,
    ZoneState,
    center_of_pressure,
    constraint_zones,
    project_to_polygon,
    support_moment_rows,
    support_polygon,
)

__all__ = [
    "EIG_TOL",
    "INTERNAL_FORCES",
    "PHI_TOL",
    "SUPPORT_ZONE",
    "TORQUE_ZONE",
    "LawLevel",
    "LawProblem",
    "LawSolution",
    "NullSpaceController",
    "NullSpaceResolver",
    "ZoneSettings",
    "ZoneState",
    "center_of_pressure",
    "constraint_zones",
    "decision_vector",
    "floating_base_metric",
    "law_problem",
    "prioritized_torques",
    "project_to_polygon",
    "support_moment_rows",
    "support_polygon",
    "utilization_weights",
]
