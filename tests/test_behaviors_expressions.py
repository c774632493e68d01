"""Compiled expressions against the reference tree walk, value for value and bit for bit."""

from __future__ import annotations

import pickle
from typing import Any

import numpy as np
import pytest

from hqp.behaviors import library_names
from hqp.behaviors.expressions import Expression, ExpressionError, Namespace, parse
from hqp.behaviors.spec import BehaviorSpec

# the library's behaviors in closed loop: long enough for their first transitions
# (walk: the plan starts at 0.3 s, the first unload follows)
SECONDS = {"walk": 1.2, "squat-jump": 0.8}
DEFAULT_SECONDS = 0.4


def outcome(expr: Expression, evaluate: str, env: Any) -> tuple[str, Any]:
    """``("value", v)`` or ``("error", message)`` of one evaluator."""
    try:
        return "value", getattr(expr, evaluate)(env)
    except ExpressionError as exc:
        return "error", str(exc)


def assert_same(compiled: tuple[str, Any], reference: tuple[str, Any], source: str) -> None:
    """The same kind of outcome, type, shape and bits."""
    assert compiled[0] == reference[0], source
    a, b = compiled[1], reference[1]
    assert type(a) is type(b), source
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, source
        assert a.tobytes() == b.tobytes(), source
    elif isinstance(a, float) and np.isnan(a):
        assert np.isnan(b), source
    else:
        assert a == b, source


def expressions(spec: BehaviorSpec) -> list[tuple[str | None, Expression]]:
    """Every goal and transition of a spec, goals with the task whose ``initial`` they read."""
    out: list[tuple[str | None, Expression]] = []
    for name, task in spec.tasks.items():
        out.extend((name, e) for e in task.goals.values())
    for phase in spec.phases.values():
        for name, goals in phase.goals.items():
            out.extend((name, e) for e in goals.values())
        out.extend((None, tr.when) for tr in phase.transitions)
    return out


@pytest.mark.parametrize("name", library_names())
def test_compiled_expressions_match_the_reference_in_a_run(name: str) -> None:
    from hqp.behaviors.setup import prepare
    from hqp.sim import Simulator, closed_loop

    behavior, ctrl, robot = prepare(name)
    sim = Simulator(robot)
    ctrl.dt = sim.dt
    behavior.start(sim.state(), 0.0)
    exprs = expressions(behavior.spec)
    assert exprs
    checked = [0, 0]  # values, errors

    def compare(step: Any) -> None:
        env = behavior._env(step.state, step.t)
        for task, expr in exprs:
            scope = env if task is None else env.with_value("initial",
                                                            behavior._initial.get(task))
            reference = outcome(expr, "evaluate_tree", scope)
            assert_same(outcome(expr, "evaluate", scope), reference, expr.source)
            checked[reference[0] == "error"] += 1

    closed_loop(sim, behavior, SECONDS.get(name, DEFAULT_SECONDS), before_step=compare,
                clock="steps")
    assert checked[0] > 0


def test_compiled_expressions_match_the_reference_on_every_construct() -> None:
    env = {"t": 1.5, "u": 0.25, "k": 2, "com": np.array([0.1, -0.2, 0.9]),
           "q": np.linspace(-1.0, 1.0, 7), "none": None,
           "contact": Namespace({"left_foot": True, "right_foot": False}, "contact"),
           "frame": Namespace({"trunk": np.array([0.3, 0.1, 1.2])}, "frame")}
    sources = [
        "t", "-t", "+t", "not t", "true", "False", "3", "2 ** 0.5", "t ** 2", "t ** 1e4",
        "[0, 0, -0.12]", "com + [0, 0, -0.12]", "com * 2 - com / 4", "(1, 2) + com[:2]",
        "com.x", "com.z", "frame.trunk.y", "frame.trunk + [0, 0, 1]", "contact.left_foot",
        "contact.left_hoof", "contact.left_foot and not contact.right_foot or t > 2",
        "t > 1 and contact.right_foot", "t < 1 or u > 0 or k", "0 < u < 1 < t",
        "0 < t < 1", "t == 1.5 != u", "com[k]", "com[-1]", "q[1:3]", "q[:k]", "q[k:]",
        "q[::2]", "com if t > 1 else -com", "abs(-t)", "abs(com - 1)", "min(t, u, 1)",
        "max(u, 0.1)", "norm(com)", "clip(com, -0.1, 0.5)", "all(com > -1)", "any(q > 0.9)",
        "min_jerk(t / 3)", "min_jerk(u)", "missing + 1", "com.w", "t.x", "com[7]", "u / 0",
        "com + [1, 2]", "none + 1", "[[1, 2], [3]]", "[t, u, k]", "-[1, 2]",
    ]
    for source in sources:
        expr = parse(source)
        assert_same(outcome(expr, "evaluate", env), outcome(expr, "evaluate_tree", env),
                    source)


def test_a_constant_list_is_a_new_array_each_evaluation() -> None:
    expr = parse("[0, 0, -0.12]")
    first = expr.evaluate({})
    first[2] = 5.0
    np.testing.assert_array_equal(expr.evaluate({}), [0.0, 0.0, -0.12])


def test_an_expression_pickles_and_compiles_again() -> None:
    expr = parse("com + [0, 0, -0.12]")
    back = pickle.loads(pickle.dumps(expr))
    assert back.source == expr.source and back.names == expr.names
    np.testing.assert_array_equal(back.evaluate({"com": np.ones(3)}), [1.0, 1.0, 0.88])
