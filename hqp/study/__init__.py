"""Studies at scale: push-recovery maps and parameter grids, each simulation a Ray task.

* :mod:`hqp.study.spec`: a study's definition (:class:`Study`, :func:`load_study`) and the
  params that name one simulation (:func:`simulation_id`);
* :mod:`hqp.study.simulation`: one simulation, params in, record out
  (:func:`run_simulation`), deterministic, re-run alone by the record's ``command``;
* :mod:`hqp.study.pushmap` (largest push survived per direction, by bisection) and
  :mod:`hqp.study.grid` (a Cartesian product of parameters): the plans of the two studies;
* :mod:`hqp.study.records`: the JSON Lines results file (streamed, resumable);
* :mod:`hqp.study.execute`: the simulations on Ray, local or on a cluster (:func:`run_study`);
* :mod:`hqp.study.plot`: the push map as a polar plot, a grid as heat maps.

``hqp sweep`` (:mod:`hqp.app.sweep`) is the command line over it.
"""

from hqp.study.execute import ClusterUnreachable, RayUnavailable, connect, make_plan, run_study
from hqp.study.records import RecordFile, read_records
from hqp.study.simulation import run_simulation
from hqp.study.spec import KINDS, PushSearch, Study, load_study, simulation_id, study_from_dict

__all__ = [
    "KINDS",
    "PushSearch",
    "ClusterUnreachable",
    "RayUnavailable",
    "RecordFile",
    "Study",
    "connect",
    "load_study",
    "make_plan",
    "read_records",
    "run_simulation",
    "run_study",
    "simulation_id",
    "study_from_dict",
]
