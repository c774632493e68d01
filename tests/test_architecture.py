"""The import graph of ``hqp/`` and ``comparisons/`` against docs/concepts/architecture.md.

Every module is parsed with :mod:`ast` (nothing is imported). An import of a project module
is an edge of the graph, wherever it stands: at module level, inside a function (or a
lambda), or under ``if TYPE_CHECKING:``; relative imports are resolved, ``from pkg import
name`` points at ``pkg.name`` when that is a module, and ``importlib.import_module`` of a
literal name (or of a literal prefix plus an expression) counts as an import of that module
(or package).

Checked here:

- every module belongs to one layer of docs/concepts/architecture.md ("Layers as they are today");
- the layer rules, counting every import; the imports that break a rule today are listed in
  :data:`KNOWN_VIOLATIONS`, which may only shrink (a new violation fails, and so does an
  entry that no longer occurs);
- no cycle of module-level imports (those under ``if TYPE_CHECKING:`` included, although
  they do not run);
- no cycle through a module of the application (``hqp/app``) even counting imports inside
  functions.

Imports inside functions are not failed here, except in the control layer (``hqp/stack.py``,
``hqp/control/`` and its re-export modules), which has none. Issue 15 took them from 145 to about 40
(most left in ``comparisons/``), and one cycle only they close:
``comparisons.common`` <-> ``comparisons.placo_runner``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("hqp", "comparisons")

LAYERS: dict[str, tuple[str, ...]] = {
    "package root": ("hqp", "hqp.errors", "hqp.threads"),
    "robot model": ("hqp.model.*", "hqp.layout", "hqp.world", "hqp.geometry", "hqp.robots.*"),
    "control primitives": ("hqp.tasks.*",),
    "solver": ("hqp.solver.*", "hqp._core.*"),
    "execution layer": ("hqp.stack", "hqp.controller", "hqp.control.*"),
    "null-space cross-check": ("hqp.nullspace", "hqp.control.nullspace.*"),
    "simulation": ("hqp.sim.*",),
    "action layer": ("hqp.behaviors.*",),
    "benchmarks": ("hqp.bench.*",),
    "figures": ("hqp.plots", "hqp.tables"),
    "application": ("hqp.app.*", "hqp.cli", "hqp.study.*"),
    "comparisons": ("comparisons.*",),
}
"""Layer -> its modules: exact names, or ``pkg.*`` for a package and everything below it.
The most specific pattern wins (an exact name over a package, a longer package over a
shorter one)."""

HQP_BELOW_APPLICATION = frozenset(LAYERS) - {"application", "comparisons"}

RULES: dict[str, tuple[frozenset[str], frozenset[str]]] = {
    "solver imports nothing of the robot model or the tasks": (
        frozenset({"solver"}), frozenset({"robot model", "control primitives"})),
    "tasks never import the solver": (
        frozenset({"control primitives"}), frozenset({"solver"})),
    "the controller never imports sim, behaviors or the application": (
        frozenset({"execution layer", "null-space cross-check"}),
        frozenset({"simulation", "action layer", "application"})),
    "behaviors never import sim or the application": (
        frozenset({"action layer"}), frozenset({"simulation", "application"})),
    "nothing in hqp/ but hqp/app imports comparisons": (
        HQP_BELOW_APPLICATION, frozenset({"comparisons"})),
    "only the application imports the application": (
        frozenset(LAYERS) - {"application"}, frozenset({"application"})),
}
"""Rule -> (layers it applies to, layers they must not import)."""

KNOWN_VIOLATIONS: set[tuple[str, str, str]] = set()
"""(rule, importing module, imported module) that break a rule today; may only shrink."""


@dataclass(frozen=True)
class Import:
    """One import of a project module."""

    source: str
    target: str
    line: int
    where: str  # "module", "function" or "type-checking"


def find_modules(root: Path, packages: Iterable[str]) -> dict[str, tuple[Path, bool]]:
    """Module name -> (file, is a package), for every module of the packages under root."""
    modules: dict[str, tuple[Path, bool]] = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            rel = path.relative_to(root)
            # only files inside packages (every folder on the way holds an __init__.py)
            if not all((root / Path(*rel.parts[:k]) / "__init__.py").is_file()
                       for k in range(1, len(rel.parts))):
                continue
            parts = list(rel.with_suffix("").parts)
            is_package = parts[-1] == "__init__"
            if is_package:
                parts.pop()
            modules[".".join(parts)] = (path, is_package)
    return modules


def _resolve(name: str, modules: Mapping[str, object]) -> str | None:
    """The longest project module that ``name`` starts with (None: not the project's)."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _import_module_target(call: ast.Call) -> str | None:
    """The literal module name of ``importlib.import_module("x")`` or of ``("x." + ...)``."""
    func = call.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    if name != "import_module" or not call.args:
        return None
    arg = call.args[0]
    if isinstance(arg, ast.BinOp) and isinstance(arg.op, ast.Add):
        arg = arg.left
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value.rstrip(".")
    return None


def module_imports(name: str, path: Path, is_package: bool,
                   modules: Mapping[str, object]) -> list[Import]:
    """Every import of a project module by one module."""
    package = name if is_package else name.rpartition(".")[0]
    found: list[Import] = []

    def add(target: str | None, line: int, where: str) -> None:
        if target is not None and target != name:
            found.append(Import(name, target, line, where))

    def visit(node: ast.AST, where: str) -> None:
        for child in ast.iter_child_nodes(node):
            inner = where
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                inner = "function"
            elif isinstance(child, ast.If) and where == "module" and _is_type_checking(child.test):
                for stmt in child.body:
                    visit(ast.Module(body=[stmt], type_ignores=[]), "type-checking")
                for stmt in child.orelse:
                    visit(ast.Module(body=[stmt], type_ignores=[]), "module")
                continue
            if isinstance(child, ast.Import):
                for alias in child.names:
                    add(_resolve(alias.name, modules), child.lineno, where)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split(".")[: len(package.split(".")) - (child.level - 1)]
                    source = ".".join(base + ([child.module] if child.module else []))
                else:
                    source = child.module or ""
                for alias in child.names:
                    sub = f"{source}.{alias.name}"
                    add(sub if sub in modules else _resolve(source, modules), child.lineno,
                        where)
            elif isinstance(child, ast.Call):
                literal = _import_module_target(child)
                if literal is not None:
                    add(_resolve(literal, modules), child.lineno, where)
            visit(child, inner)

    visit(ast.parse(path.read_text(encoding="utf-8"), str(path)), "module")
    return found


def import_graph(root: Path = ROOT, packages: Iterable[str] = PACKAGES) -> list[Import]:
    """Every import between project modules."""
    modules = find_modules(root, packages)
    return [imp for name, (path, is_package) in modules.items()
            for imp in module_imports(name, path, is_package, modules)]


def find_cycles(graph: Mapping[str, Iterable[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[set[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(component)

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return cycles


def _graph(imports: Iterable[Import], where: Iterable[str]) -> dict[str, set[str]]:
    kinds = set(where)
    graph: dict[str, set[str]] = {}
    for imp in imports:
        if imp.where in kinds:
            graph.setdefault(imp.source, set()).add(imp.target)
    return graph


def layer_of(module: str) -> str | None:
    """The layer of a module (most specific pattern of :data:`LAYERS`), None if none."""
    best: tuple[tuple[bool, int], str] | None = None
    for layer, patterns in LAYERS.items():
        for pattern in patterns:
            prefix = pattern.removesuffix(".*")
            exact = not pattern.endswith(".*")
            if module == prefix or (not exact and module.startswith(prefix + ".")):
                rank = (exact, len(prefix))
                assert best is None or best[0] != rank, f"{module}: two layers {best[1]}, {layer}"
                if best is None or rank > best[0]:
                    best = (rank, layer)
    return None if best is None else best[1]


def violations(imports: Iterable[Import]) -> dict[tuple[str, str, str], list[int]]:
    """(rule, source, target) -> lines of the imports that break a rule."""
    found: dict[tuple[str, str, str], list[int]] = {}
    for imp in imports:
        source, target = layer_of(imp.source), layer_of(imp.target)
        for rule, (sources, forbidden) in RULES.items():
            if source in sources and target in forbidden:
                found.setdefault((rule, imp.source, imp.target), []).append(imp.line)
    return found


# ------------------------------------------------------------------ tests
IMPORTS = import_graph()


def test_the_graph_is_read() -> None:
    modules = find_modules(ROOT, PACKAGES)
    assert {"hqp.cli", "hqp.controller", "hqp.solver", "hqp.app.compare"} <= set(modules)
    edges = {(imp.source, imp.target) for imp in IMPORTS}
    assert ("hqp.app.cli", "hqp.app.compare") in edges  # from a package import a module
    assert ("hqp.app.compare", "comparisons") in edges  # from a package import names
    assert layer_of("hqp.control.servo") == "execution layer"
    assert layer_of("hqp.control.nullspace.law") == "null-space cross-check"


def test_every_module_has_a_layer() -> None:
    missing = [m for m in find_modules(ROOT, PACKAGES) if layer_of(m) is None]
    assert not missing, f"modules in no layer of docs/concepts/architecture.md: {missing}"


def test_layer_rules() -> None:
    found = violations(IMPORTS)
    new = {key: lines for key, lines in found.items() if key not in KNOWN_VIOLATIONS}
    listed = "\n".join(f"  {source} -> {target} (lines {lines}): {rule}"
                       for (rule, source, target), lines in sorted(new.items()))
    assert not new, f"imports that break a layer rule of docs/concepts/architecture.md:\n{listed}"
    gone = KNOWN_VIOLATIONS - set(found)
    assert not gone, f"remove from KNOWN_VIOLATIONS, they no longer occur: {sorted(gone)}"


def test_console_imports_nothing_of_the_project() -> None:
    assert not [imp for imp in IMPORTS if imp.source == "hqp.app.console"]


def test_no_cycle_of_module_level_imports() -> None:
    cycles = find_cycles(_graph(IMPORTS, ["module", "type-checking"]))
    assert not cycles, f"import cycles at module level: {[sorted(c) for c in cycles]}"


def test_no_cycle_through_the_application() -> None:
    application = {m for m in find_modules(ROOT, PACKAGES) if layer_of(m) == "application"}
    cycles = find_cycles(_graph(IMPORTS, ["module", "function", "type-checking"]))
    through = [sorted(c) for c in cycles if c & application]
    assert not through, f"import cycles through the application: {through}"


def test_the_cycle_finder_finds_a_cycle(tmp_path: Path) -> None:
    assert find_cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [{"a", "b"}]
    assert find_cycles({"a": {"b"}, "b": {"c"}}) == []
    # a synthetic two-module cycle, through the whole reader: relative and absolute,
    # module level and inside a function
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from . import b\n")
    (pkg / "b.py").write_text("def f():\n    import pkg.a\n")
    (pkg / "c.py").write_text("from pkg.a import something\n")
    imports = import_graph(tmp_path, ["pkg"])
    assert {(i.source, i.target, i.where) for i in imports} == {
        ("pkg.a", "pkg.b", "module"), ("pkg.b", "pkg.a", "function"),
        ("pkg.c", "pkg.a", "module")}
    assert find_cycles(_graph(imports, ["module"])) == []
    assert find_cycles(_graph(imports, ["module", "function"])) == [{"pkg.a", "pkg.b"}]
    (pkg / "b.py").write_text("import pkg.a\n")
    assert find_cycles(_graph(import_graph(tmp_path, ["pkg"]), ["module"])) == [
        {"pkg.a", "pkg.b"}]


CONTROL_MODULES = ("hqp.stack", "hqp.controller", "hqp.nullspace", "hqp.control")


def test_the_control_layer_imports_at_module_level() -> None:
    """No import of a project module inside a function of the control layer (issue 15)."""
    inside = [f"{imp.source} -> {imp.target} (line {imp.line})" for imp in IMPORTS
              if imp.where == "function"
              and any(imp.source == m or imp.source.startswith(m + ".") for m in CONTROL_MODULES)]
    assert not inside, "imports inside functions of the control layer:\n" + "\n".join(inside)


def test_the_servo_knows_no_particular_resolver_but_hqp() -> None:
    """The step skeleton calls a resolver; the null-space law plugs in, the servo never names it."""
    core = ("hqp.control.command", "hqp.control.servo", "hqp.control.resolver")
    found = [(imp.source, imp.target) for imp in IMPORTS
             if imp.source in core and imp.target.startswith("hqp.control.nullspace")]
    assert not found, found
