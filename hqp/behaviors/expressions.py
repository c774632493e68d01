"""A small, safe expression language for behavior files.

Transition conditions (``when = "phase_time > 0.5 and contacts == 0"``) and
task goals (``goal = "initial + [0, 0, -0.12]"``) are written as Python-like
expressions and evaluated each control step against a namespace of sensed
quantities (simulated time, contacts, centre of gravity, task errors,
feasibility flags, runtime inputs, planner outputs). Only literals, names,
attribute access, indexing, arithmetic, comparisons, boolean operators, list
literals (turned into arrays) and a few whitelisted functions are allowed;
anything else is rejected when the file is loaded, never at run time.

A behavior file is user input, so an expression is bounded when it is parsed: at most
:data:`MAX_LENGTH` characters, :data:`MAX_NODES` syntax nodes and :data:`MAX_DEPTH` levels of
nesting; every constant part is evaluated once at load (``9 ** 9 ** 9`` overflows there, not
at run time) and powers are computed in floating point, so no expression runs unbounded.
String constants are not values of this language (``when = "'abc'"`` would always be true).
"""

from __future__ import annotations

import ast
import operator
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hqp.tasks.reference import min_jerk

MAX_LENGTH = 1000
"""Longest expression [characters]."""
MAX_NODES = 400
"""Most syntax nodes in one expression."""
MAX_DEPTH = 50
"""Deepest nesting of one expression's syntax tree."""
MAX_EXPONENT = 1e3
"""Largest magnitude of an exponent (``a ** b``)."""


class ExpressionError(Exception):
    """An expression is malformed or refers to a name that does not exist."""


def _pow(base: Any, exponent: Any) -> Any:
    """Return ``base ** exponent`` in floating point, with the exponent bounded."""
    e = np.asarray(exponent, dtype=float)
    if not np.all(np.abs(e) <= MAX_EXPONENT):
        raise ExpressionError(f"exponent {exponent!r} out of range (|exponent| <= "
                              f"{MAX_EXPONENT:g})")
    with np.errstate(all="ignore"):
        value = np.power(np.asarray(base, dtype=float), e)
    return float(value) if value.ndim == 0 else value


_BINARY: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: _pow,
}
_UNARY: dict[type, Callable[[Any], Any]] = {
    ast.USub: operator.neg,
    ast.UAdd: operator.pos,
    ast.Not: operator.not_,
}
_COMPARE: dict[type, Callable[[Any, Any], Any]] = {
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
}


def _norm(x: object) -> float:
    return float(np.linalg.norm(np.asarray(x, dtype=float)))


FUNCTIONS: dict[str, Callable[..., Any]] = {
    "abs": lambda x: np.abs(x) if isinstance(x, np.ndarray) else abs(x),
    "min": min,
    "max": max,
    "norm": _norm,
    "clip": lambda x, lo, hi: np.clip(x, lo, hi),
    "all": lambda x: bool(np.all(x)),
    "any": lambda x: bool(np.any(x)),
    "min_jerk": lambda u: min_jerk(float(u)),
}
"""Functions callable from an expression."""


class Namespace:
    """Attribute-style access to a mapping: ``contact.left_foot``, ``error.hand``.

    Args:
        values: The names and their values.
        kind: Name of the namespace, for error messages (e.g. ``"contact"``).

    """

    def __init__(self, values: Mapping[str, Any], kind: str) -> None:
        self._values = dict(values)
        self._kind = kind

    def get(self, name: str) -> Any:
        """Value of ``name``.

        Raises:
            ExpressionError: Unknown name (the message lists the known ones).

        """
        try:
            return self._values[name]
        except KeyError:
            known = ", ".join(sorted(self._values)) or "none"
            raise ExpressionError(f"unknown name {self._kind}.{name}; known: {known}") from None

    def names(self) -> list[str]:
        """Return the names it holds."""
        return sorted(self._values)


@dataclass(frozen=True)
class Expression:
    """A parsed expression.

    Attributes:
        source: The text as written in the file.
        tree: Its syntax tree (validated).
        names: Top-level names it reads (``t``, ``contact``, ``input``, ...).
        attributes: ``(namespace, attribute)`` pairs it reads (``("input", "goal")``).

    """

    source: str
    tree: ast.Expression
    names: frozenset[str]
    attributes: frozenset[tuple[str, str]]

    def __post_init__(self) -> None:
        # compiled once: the per-step evaluation runs one closure per syntax node
        object.__setattr__(self, "_compiled", _compile(self.tree.body))

    def __reduce__(self) -> tuple[Any, ...]:
        # the closures are not pickled: they are compiled again from the tree
        return (Expression, (self.source, self.tree, self.names, self.attributes))

    def evaluate(self, env: Mapping[str, Any]) -> Any:
        """Value of the expression in ``env`` (names to values or :class:`Namespace`).

        Runs the closures :func:`_compile` made of the syntax tree when the expression was
        parsed; :func:`evaluate_tree` is the reference evaluator they follow.

        Raises:
            ExpressionError: Unknown name, or an operation that fails on the values.

        """
        try:
            return self._compiled(env)  # type: ignore[attr-defined]
        except ExpressionError:
            raise
        except (TypeError, ValueError, IndexError, ZeroDivisionError, OverflowError) as exc:
            raise ExpressionError(f"cannot evaluate {_short(self.source)!r}: {exc}") from None

    def evaluate_tree(self, env: Mapping[str, Any]) -> Any:
        """Value of the expression in ``env`` by a walk of its syntax tree (the reference).

        Raises:
            ExpressionError: As :meth:`evaluate`.

        """
        try:
            return _eval(self.tree.body, env)
        except ExpressionError:
            raise
        except (TypeError, ValueError, IndexError, ZeroDivisionError, OverflowError) as exc:
            raise ExpressionError(f"cannot evaluate {_short(self.source)!r}: {exc}") from None


def parse(source: str, allowed_names: Iterable[str] | None = None) -> Expression:
    """Parse and validate an expression.

    Args:
        source: The expression text.
        allowed_names: Top-level names that may appear (``None``: any).

    Raises:
        ExpressionError: Syntax error, a forbidden construct, or a name not allowed.

    """
    if not isinstance(source, str) or not source.strip():
        raise ExpressionError("expected a non-empty expression string")
    if len(source) > MAX_LENGTH:
        raise ExpressionError(f"expression of {len(source)} characters; at most {MAX_LENGTH} "
                              "are allowed (split it into tasks or inputs)")
    try:
        tree = ast.parse(source.strip(), mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(f"syntax error in {_short(source)!r}: {exc.msg}") from None
    except (RecursionError, MemoryError):
        raise ExpressionError(f"in {_short(source)!r}: nested too deeply") from None
    _check_size(tree, source)
    names: set[str] = set()
    attributes: set[tuple[str, str]] = set()
    allowed = None if allowed_names is None else set(allowed_names)
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
                raise ExpressionError(
                    f"in {source!r}: only these functions may be called: "
                    f"{', '.join(sorted(FUNCTIONS))}"
                )
            if node.keywords:
                raise ExpressionError(f"in {source!r}: keyword arguments are not allowed")
        elif isinstance(node, ast.Attribute):
            if not isinstance(node.value, ast.Name):
                if node.attr in ("x", "y", "z"):
                    continue  # frame.trunk.z: a coordinate of a vector value
                raise ExpressionError(f"in {source!r}: write attributes as namespace.name "
                                      "(then .x, .y or .z)")
            if node.attr.startswith("_"):
                raise ExpressionError(f"in {source!r}: attribute {node.attr!r} is not allowed")
            attributes.add((node.value.id, node.attr))
        elif isinstance(node, ast.Name):
            if node.id in FUNCTIONS or node.id in ("true", "false", "True", "False"):
                continue
            names.add(node.id)
            if allowed is not None and node.id not in allowed:
                raise ExpressionError(
                    f"in {source!r}: unknown name {node.id!r}; known names: "
                    f"{', '.join(sorted(allowed))}"
                )
        elif not isinstance(
            node,
            (
                ast.Expression, ast.BoolOp, ast.BinOp, ast.UnaryOp, ast.Compare, ast.Constant,
                ast.List, ast.Tuple, ast.Subscript, ast.Slice, ast.Load, ast.IfExp, ast.And, ast.Or,
                *_BINARY, *_UNARY, *_COMPARE,
            ),
        ):
            raise ExpressionError(f"in {source!r}: {type(node).__name__} is not allowed")
        if isinstance(node, ast.Constant) and (
                isinstance(node.value, str) or not isinstance(node.value, (int, float, bool))):
            raise ExpressionError(f"in {source!r}: constant {node.value!r} is not allowed "
                                  "(expected numbers, names and lists)")
    _fold_constants(tree.body, source)
    return Expression(source, tree, frozenset(names), frozenset(attributes))


def _short(source: str, n: int = 60) -> str:
    return source if len(source) <= n else source[:n] + "..."


def _check_size(tree: ast.AST, source: str) -> None:
    """Reject a tree of more than :data:`MAX_NODES` nodes or :data:`MAX_DEPTH` levels."""
    count = 0
    todo: list[tuple[ast.AST, int]] = [(tree, 0)]
    while todo:
        node, depth = todo.pop()
        count += 1
        if count > MAX_NODES:
            raise ExpressionError(f"in {_short(source)!r}: more than {MAX_NODES} terms")
        if depth > MAX_DEPTH:
            raise ExpressionError(f"in {_short(source)!r}: nested deeper than {MAX_DEPTH} "
                                  "levels")
        todo.extend((child, depth + 1) for child in ast.iter_child_nodes(node))


def _constant(node: ast.AST) -> bool:
    """Whether a subtree reads no name and calls nothing (its value is known at load)."""
    return not any(isinstance(n, (ast.Name, ast.Attribute, ast.Call)) for n in ast.walk(node))


def _fold_constants(node: ast.AST, source: str) -> None:
    """Evaluate every largest constant arithmetic part once: it must give finite numbers."""
    if isinstance(node, (ast.BinOp, ast.UnaryOp)) and _constant(node):
        try:
            with np.errstate(all="ignore"):
                value = _eval(node, {})
        except (ExpressionError, TypeError, ValueError, ZeroDivisionError,
                OverflowError) as exc:
            raise ExpressionError(f"in {_short(source)!r}: {exc}") from None
        if not np.all(np.isfinite(np.asarray(value, dtype=float))):
            raise ExpressionError(f"in {_short(source)!r}: {ast.unparse(node)} is not a "
                                  "finite number")
        return
    for child in ast.iter_child_nodes(node):
        _fold_constants(child, source)


def _eval(node: ast.AST, env: Mapping[str, Any]) -> Any:
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name):
        if node.id in ("true", "True"):
            return True
        if node.id in ("false", "False"):
            return False
        try:
            return env[node.id]
        except KeyError:
            raise ExpressionError(f"unknown name {node.id!r}") from None
    if isinstance(node, ast.Attribute):
        base = _eval(node.value, env)
        if isinstance(base, Namespace):
            return base.get(node.attr)
        if isinstance(base, np.ndarray) and node.attr in ("x", "y", "z") and base.size >= 3:
            return float(base["xyz".index(node.attr)])
        raise ExpressionError(f"{ast.unparse(node.value)} has no attribute {node.attr!r}")
    if isinstance(node, (ast.List, ast.Tuple)):
        return np.array([_eval(e, env) for e in node.elts], dtype=float)
    if isinstance(node, ast.BinOp):
        left, right = _eval(node.left, env), _eval(node.right, env)
        return _BINARY[type(node.op)](_arr(left), _arr(right))
    if isinstance(node, ast.UnaryOp):
        return _UNARY[type(node.op)](_eval(node.operand, env))
    if isinstance(node, ast.BoolOp):
        if isinstance(node.op, ast.And):
            return all(bool(_eval(v, env)) for v in node.values)
        return any(bool(_eval(v, env)) for v in node.values)
    if isinstance(node, ast.Compare):
        left = _eval(node.left, env)
        for op, comp in zip(node.ops, node.comparators):
            right = _eval(comp, env)
            if not bool(_COMPARE[type(op)](left, right)):
                return False
            left = right
        return True
    if isinstance(node, ast.IfExp):
        return _eval(node.body if _eval(node.test, env) else node.orelse, env)
    if isinstance(node, ast.Subscript):
        base = _eval(node.value, env)
        if isinstance(node.slice, ast.Slice):
            lo, hi = (None if b is None else int(_eval(b, env))
                      for b in (node.slice.lower, node.slice.upper))
            if node.slice.step is not None:
                raise ExpressionError("slices with a step are not allowed")
            return np.asarray(base)[lo:hi]
        index = _eval(node.slice, env)
        return base[int(index)]
    if isinstance(node, ast.Call):
        fname = node.func.id  # type: ignore[attr-defined]
        return FUNCTIONS[fname](*[_eval(a, env) for a in node.args])
    raise ExpressionError(f"{type(node).__name__} is not allowed")  # pragma: no cover


def _arr(x: Any) -> Any:
    return np.asarray(x, dtype=float) if isinstance(x, (list, tuple)) else x


Compiled = Callable[[Mapping[str, Any]], Any]
"""An expression (or one of its nodes) compiled: ``env -> value``."""


def _compile(node: ast.AST) -> Compiled:
    """Return a closure computing what :func:`_eval` computes for ``node``, operation by operation.

    The tree is walked once, here; each node becomes a closure over its children's, so a
    step evaluates the same operations in the same order, on the same values, without the
    dispatch on node types. A part that reads no name (``[0, 0, -0.12]``) is evaluated once
    and each evaluation returns a copy of its value.
    """
    if isinstance(node, (ast.BinOp, ast.UnaryOp, ast.List, ast.Tuple)) and _constant(node):
        try:
            with np.errstate(all="ignore"):
                value = _eval(node, {})
        except (ExpressionError, TypeError, ValueError, IndexError, ZeroDivisionError,
                OverflowError):
            value = None  # (a ragged list: it fails at each evaluation, as the reference's)
        if isinstance(value, np.ndarray):
            return lambda env: value.copy()
        if value is not None:
            return lambda env: value
    if isinstance(node, ast.Constant):
        const = node.value
        return lambda env: const
    if isinstance(node, ast.Name):
        if node.id in ("true", "True"):
            return lambda env: True
        if node.id in ("false", "False"):
            return lambda env: False
        name = node.id

        def read(env: Mapping[str, Any]) -> Any:
            try:
                return env[name]
            except KeyError:
                raise ExpressionError(f"unknown name {name!r}") from None
        return read
    if isinstance(node, ast.Attribute):
        base_of = _compile(node.value)
        attr = node.attr
        where = ast.unparse(node.value)
        xyz = "xyz".index(attr) if attr in ("x", "y", "z") else None

        def attribute(env: Mapping[str, Any]) -> Any:
            base = base_of(env)
            if isinstance(base, Namespace):
                return base.get(attr)
            if xyz is not None and isinstance(base, np.ndarray) and base.size >= 3:
                return float(base[xyz])
            raise ExpressionError(f"{where} has no attribute {attr!r}")
        return attribute
    if isinstance(node, (ast.List, ast.Tuple)):
        elements = [_compile(e) for e in node.elts]
        return lambda env: np.array([e(env) for e in elements], dtype=float)
    if isinstance(node, ast.BinOp):
        left, right, binary = _compile(node.left), _compile(node.right), _BINARY[type(node.op)]

        def binop(env: Mapping[str, Any]) -> Any:
            a = left(env)
            b = right(env)
            return binary(_arr(a), _arr(b))
        return binop
    if isinstance(node, ast.UnaryOp):
        operand, unary = _compile(node.operand), _UNARY[type(node.op)]
        return lambda env: unary(operand(env))
    if isinstance(node, ast.BoolOp):
        values = [_compile(v) for v in node.values]
        if isinstance(node.op, ast.And):
            def conjunction(env: Mapping[str, Any]) -> bool:
                for v in values:
                    if not bool(v(env)):
                        return False
                return True
            return conjunction

        def disjunction(env: Mapping[str, Any]) -> bool:
            for v in values:
                if bool(v(env)):
                    return True
            return False
        return disjunction
    if isinstance(node, ast.Compare):
        first = _compile(node.left)
        chain = [(_COMPARE[type(op)], _compile(c)) for op, c in zip(node.ops, node.comparators)]
        if len(chain) == 1:
            (compare, second), = chain
            return lambda env: bool(compare(first(env), second(env)))

        def comparison(env: Mapping[str, Any]) -> bool:
            left = first(env)
            for compare, comp in chain:
                right = comp(env)
                if not bool(compare(left, right)):
                    return False
                left = right
            return True
        return comparison
    if isinstance(node, ast.IfExp):
        test, body, orelse = _compile(node.test), _compile(node.body), _compile(node.orelse)
        return lambda env: body(env) if test(env) else orelse(env)
    if isinstance(node, ast.Subscript):
        base_of = _compile(node.value)
        if isinstance(node.slice, ast.Slice):
            lower = None if node.slice.lower is None else _compile(node.slice.lower)
            upper = None if node.slice.upper is None else _compile(node.slice.upper)
            stepped = node.slice.step is not None

            def sliced(env: Mapping[str, Any]) -> Any:
                base = base_of(env)
                lo = None if lower is None else int(lower(env))
                hi = None if upper is None else int(upper(env))
                if stepped:
                    raise ExpressionError("slices with a step are not allowed")
                return np.asarray(base)[lo:hi]
            return sliced
        index_of = _compile(node.slice)

        def indexed(env: Mapping[str, Any]) -> Any:
            base = base_of(env)
            return base[int(index_of(env))]
        return indexed
    if isinstance(node, ast.Call):
        function = FUNCTIONS[node.func.id]  # type: ignore[attr-defined]
        arguments = [_compile(a) for a in node.args]
        return lambda env: function(*[a(env) for a in arguments])
    raise ExpressionError(f"{type(node).__name__} is not allowed")  # pragma: no cover
