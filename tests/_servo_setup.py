"""A controller over the stand-in tasks of ``_h5_standins`` (servo and diagnostics tests)."""

import numpy as np
from _h5_standins import ComStandIn, PostureStandIn, sample_humanoid

from hqp.control import WholeBodyController
from hqp.stack import Stack
from hqp.tasks.contact import Contact
from hqp.tasks.dynamics import FloatingBaseDynamics

DT = 1e-3


def make(extra=(), posture=True, backend="proxsuite", **kwargs):
    m, q = sample_humanoid()
    m.update(q, np.zeros(m.nv))
    st = Stack(**kwargs)
    st.add(FloatingBaseDynamics())
    st.add(ComStandIn("com", m.com[:2] + np.array([0.01, 0.0])))
    if posture:
        st.add(PostureStandIn("posture", q))
    for task, level in extra:
        st.add(task, level)
    c = WholeBodyController(m, [Contact("right", "right_sole"), Contact("left", "left_sole")], st,
                            dt=DT, backend=backend)
    return c, m, q
