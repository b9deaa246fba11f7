"""The package's architecture, read from the source with ``ast``: every import counts (module level, inside
functions, under ``if TYPE_CHECKING:``), so an import circle cannot hide behind a function-level import.

Rules: no import cycle among hound_id modules; each room imports only the rooms :data:`ALLOWED` gives it (the arrows
of ARCHITECTURE.md); mor, foot and export never import dyno; no module imports another module's private (``_name``)
names; the trainer runtime imports only numpy, the standard library and
the few hound_id modules of :data:`RUNTIME_IMPORTS` (torch only inside the functions given tensors); no function is
over :data:`LONG_FUNCTION` lines unless :data:`LONG_FUNCTIONS` says why.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

from tests.conftest import ROOT

PACKAGE = ROOT / "hound_id"
#: hound_id modules runtime.py may import (directly, at any level): the clip and what it stands on, and io
#: (PyYAML) inside the function that reads a YAML bundle.
RUNTIME_IMPORTS = {
    "hound_id.arrays",
    "hound_id.errors",
    "hound_id.io",
    "hound_id.mor.clip_bounds",
    "hound_id.mor.clip_turn",
    "hound_id.mor.current_curve",
    "hound_id.mor.friction",
    "hound_id.mor.fused",
    "hound_id.mor.saturation",
    "hound_id.mor.thermal",
}
#: hound_id modules ``import hound_id.runtime`` loads (its module-level imports, followed through every module).
RUNTIME_LOADS = {
    "hound_id",
    "hound_id.arrays",
    "hound_id.errors",
    "hound_id.mor",
    "hound_id.mor.clip_bounds",
    "hound_id.mor.clip_operators",
    "hound_id.mor.clip_paths",
    "hound_id.mor.clip_turn",
    "hound_id.mor.current_curve",
    "hound_id.mor.drive",
    "hound_id.mor.friction",
    "hound_id.mor.fused",
    "hound_id.mor.region",
    "hound_id.mor.saturation",
    "hound_id.runtime",
}
#: Libraries outside the standard library that runtime.py may import (torch only inside functions).
RUNTIME_LIBRARIES = {"numpy", "torch"}


#: The rooms of the package, most specific first; a module belongs to the first room it is in or under. Modules in
#: none of them (errors, units, io, tables, arrays, parameter, samples, the package itself) are the ground floor.
ROOMS = (
    "hound_id.__main__",
    "hound_id.entry",
    "hound_id.cli",
    "hound_id.demo",
    "hound_id.dyno.fleet",
    "hound_id.dyno.acquire",
    "hound_id.dyno.current",
    "hound_id.dyno.envelope",
    "hound_id.dyno.identify",
    "hound_id.dyno.simulate",
    "hound_id.dyno.logs",
    "hound_id.dyno.artefacts",
    "hound_id.dyno",
    "hound_id.export",
    "hound_id.runtime",
    "hound_id.foot",
    "hound_id.mor",
)
GROUND = "ground"
#: The arrows: which rooms each room may import (besides itself and the ground floor). ARCHITECTURE.md draws this.
ALLOWED = {
    "hound_id.__main__": {"hound_id.entry"},
    "hound_id.entry": {"hound_id.cli"},
    "hound_id.cli": {
        "hound_id.demo", "hound_id.dyno.fleet", "hound_id.dyno.envelope", "hound_id.dyno.acquire",
        "hound_id.dyno.current", "hound_id.dyno.simulate", "hound_id.export", "hound_id.foot", "hound_id.mor",
    },
    "hound_id.demo": {"hound_id.dyno.fleet", "hound_id.dyno.current", "hound_id.dyno.envelope",
                      "hound_id.export", "hound_id.foot", "hound_id.mor"},
    "hound_id.dyno.fleet": {"hound_id.dyno.current", "hound_id.dyno.logs"},
    "hound_id.dyno.acquire": {"hound_id.dyno.logs", "hound_id.dyno.simulate"},
    "hound_id.dyno.current": {"hound_id.dyno.identify", "hound_id.dyno.logs", "hound_id.dyno.artefacts",
                              "hound_id.mor"},
    "hound_id.dyno.envelope": {"hound_id.dyno.identify", "hound_id.dyno.logs", "hound_id.mor"},
    "hound_id.dyno.identify": set(),
    "hound_id.dyno.simulate": {"hound_id.mor"},
    "hound_id.dyno.logs": {"hound_id.dyno.artefacts"},
    "hound_id.dyno.artefacts": set(),
    "hound_id.dyno": set(),
    "hound_id.export": {"hound_id.runtime", "hound_id.foot", "hound_id.mor"},
    "hound_id.runtime": {"hound_id.mor"},
    "hound_id.foot": {"hound_id.mor"},
    "hound_id.mor": set(),
    GROUND: set(),
}  # fmt: skip


def room_of(module: str) -> str:
    """The room a module belongs to (:data:`ROOMS`), or :data:`GROUND`."""
    return next((r for r in ROOMS if module == r or module.startswith(r + ".")), GROUND)


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def imports(name: str) -> list[tuple[str, tuple[str, ...], bool]]:
    """(imported module, names taken from it, eager) for every import in module ``name``; eager means it runs
    when the module is imported (module level, not under TYPE_CHECKING)."""
    path = MODULES[name]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: list[tuple[str, tuple[str, ...], bool]] = []

    def visit(node: ast.AST, eager: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import):
                out.extend((a.name, (), eager) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    up = package.split(".")
                    up = up[: len(up) - (child.level - 1)]
                    base = ".".join([*up, base] if base else up)
                names = tuple(a.name for a in child.names)
                for n in names:  # ``from hound_id.mor import spec`` imports the module hound_id.mor.spec
                    if f"{base}.{n}" in MODULES:
                        out.append((f"{base}.{n}", (), eager))
                out.append((base, tuple(n for n in names if f"{base}.{n}" not in MODULES), eager))
            elif isinstance(child, ast.If) and _type_checking(child):
                for part in child.body:
                    visit(ast.Module(body=[part], type_ignores=[]), False)
                for part in child.orelse:
                    visit(ast.Module(body=[part], type_ignores=[]), eager)
            elif isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                visit(child, False)
            else:
                visit(child, eager)

    visit(ast.parse(path.read_text(), str(path)), True)
    return out


IMPORTS = {name: imports(name) for name in MODULES}


def internal(target: str) -> str | None:
    """The hound_id module an import names (the module itself, or the nearest package above it), or None."""
    while target and target not in MODULES:
        target = target.rpartition(".")[0]
    return target or None


def graph(eager_only: bool = False) -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {name: set() for name in MODULES}
    for name, found in IMPORTS.items():
        for target, _, eager in found:
            dep = internal(target)
            if dep is not None and dep != name and (eager or not eager_only):
                edges[name].add(dep)
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected groups of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(edges)))

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    for v in sorted(edges):
        if v not in index:
            strong(v)
    return out


def test_the_checker_sees_every_kind_of_import():
    found = {(t, names, eager) for t, names, eager in IMPORTS["hound_id.mor.saturation"]}
    assert ("hound_id.mor.region", ("OperatingRegion", "operating_region"), True) in found
    assert ("hound_id.mor.robot", ("Robot",), False) in found  # under TYPE_CHECKING
    assert ("torch", (), False) in found  # inside a function
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycle():
    assert cycles(graph()) == []


def test_each_room_imports_only_the_rooms_its_arrows_allow():
    assert set(ALLOWED) == {*ROOMS, GROUND}
    assert room_of("hound_id.dyno.current.fit") == "hound_id.dyno.current" and room_of("hound_id.io") == GROUND
    wrong = sorted(
        f"{name} -> {dep}"
        for name, deps in graph().items()
        for dep in deps
        if room_of(dep) not in {room_of(name), GROUND, *ALLOWED[room_of(name)]}
    )
    assert wrong == []


def test_the_arrows_have_no_circle():
    assert cycles({room: set(allowed) for room, allowed in ALLOWED.items()}) == []


def test_mor_foot_and_export_never_import_dyno():
    edges = graph()
    wrong = sorted(
        f"{name} -> {dep}"
        for name, deps in edges.items()
        if name.startswith(("hound_id.mor", "hound_id.foot", "hound_id.export"))
        for dep in deps
        if dep.startswith("hound_id.dyno")
    )
    assert wrong == []


def test_no_module_imports_another_modules_private_names():
    wrong = sorted(
        f"{name}: {n} from {target}"
        for name, found in IMPORTS.items()
        for target, names, _ in found
        if internal(target) not in (None, name)
        for n in names
        if n.startswith("_") and not n.startswith("__")
    )
    assert wrong == []


def test_runtime_imports_only_what_its_docstring_says():
    direct = {internal(t) for t, _, _ in IMPORTS["hound_id.runtime"]} - {None}
    assert direct <= RUNTIME_IMPORTS, direct - RUNTIME_IMPORTS
    libraries = {t.partition(".")[0] for t, _, _ in IMPORTS["hound_id.runtime"] if internal(t) is None}
    assert libraries - set(sys.stdlib_module_names) <= RUNTIME_LIBRARIES
    # what importing it loads: its module-level imports, followed, and the packages above each module
    eager = graph(eager_only=True)
    loaded, todo = set(), ["hound_id.runtime"]
    while todo:
        name = todo.pop()
        if name in loaded:
            continue
        loaded.add(name)
        parts = name.split(".")
        todo.extend(".".join(parts[:k]) for k in range(1, len(parts)))
        todo.extend(eager[name])
    assert loaded == RUNTIME_LOADS
    outside = {
        t.partition(".")[0]
        for name in loaded
        for t, _, eager_import in IMPORTS[name]
        if eager_import and internal(t) is None
    }
    assert outside - set(sys.stdlib_module_names) == {"numpy"}


#: The longest a function of hound_id may be, in lines (``def`` line to last line, decorators not counted).
LONG_FUNCTION = 80
#: "module:function" (a method as ``Class.method``) -> why it stays longer than :data:`LONG_FUNCTION`. Every entry must
#: still be over it: one split below it is dropped from here.
LONG_FUNCTIONS = {
    "hound_id.cli.foot:foot": "Typer command: its signature is its 31 option declarations; the body builds the options",
    "hound_id.dyno.current.effects:_builtin": "registry table of the shipped effects",
    "hound_id.export.mjlab:mjlab_module": "text template of the generated module",
    "hound_id.export.newton:newton_module": "text template of the generated module",
}


def long_functions(source: str, limit: int = LONG_FUNCTION) -> dict[str, int]:
    """Qualified name (``Class.method``, ``outer.inner``) -> length in lines of each function in ``source`` longer
    than ``limit`` lines."""
    found: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                assert child.end_lineno is not None
                if child.end_lineno - child.lineno + 1 > limit:
                    found[prefix + child.name] = child.end_lineno - child.lineno + 1
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(source), "")
    return found


def long_function_problems(sources: dict[str, str], allowed: dict[str, str], limit: int = LONG_FUNCTION) -> list[str]:
    """What the long-function rule finds in ``sources`` (module -> text) against ``allowed`` ("module:function" ->
    reason): a function over ``limit`` lines without a reason, an entry no longer over it, an entry without a reason."""
    found = {
        f"{module}:{name}": n for module, text in sources.items() for name, n in long_functions(text, limit).items()
    }
    problems = [
        f"{key}: {n} lines, over {limit}: split it into named steps, or state in LONG_FUNCTIONS why it stays whole"
        for key, n in sorted(found.items())
        if key not in allowed
    ]
    problems += [
        f"{key}: not over {limit} lines (or gone): drop it from LONG_FUNCTIONS"
        for key in sorted(allowed)
        if key not in found
    ]
    problems += [f"{key}: no reason given" for key, why in sorted(allowed.items()) if not why.strip()]
    return problems


def test_no_function_is_long_without_a_stated_reason():
    assert long_function_problems({name: path.read_text() for name, path in MODULES.items()}, LONG_FUNCTIONS) == []


def test_the_long_function_rule_catches_a_new_long_function_and_a_stale_reason():
    steps = "".join(f"    x = {i}\n" for i in range(LONG_FUNCTION - 1))
    at_limit = f"def at_limit():\n{steps}"  # 80 lines
    grown = f"def grown():\n{steps}    return x\n"  # 81 lines
    method = "class Clip:\n    def call(self):\n" + "".join(f"        x = {i}\n" for i in range(LONG_FUNCTION))
    assert long_functions(at_limit) == {} and long_functions(grown) == {"grown": LONG_FUNCTION + 1}
    assert long_functions(method) == {"Clip.call": LONG_FUNCTION + 1}
    # one long function added to the package fails the rule, until its reason is given
    package = {name: path.read_text() for name, path in MODULES.items()}
    added = {**package, "hound_id.grown": f"{at_limit}\n\n{grown}\n\n{method}"}
    assert long_function_problems(added, LONG_FUNCTIONS) == [
        "hound_id.grown:Clip.call: 81 lines, over 80: split it into named steps, or state in LONG_FUNCTIONS why it "
        "stays whole",
        "hound_id.grown:grown: 81 lines, over 80: split it into named steps, or state in LONG_FUNCTIONS why it stays "
        "whole",
    ]
    reasons = {**LONG_FUNCTIONS, "hound_id.grown:grown": "a reason", "hound_id.grown:Clip.call": "a reason"}
    assert long_function_problems(added, reasons) == []
    # an entry whose function was split (or removed), and an entry without a reason, fail it too
    assert long_function_problems(added, {**reasons, "hound_id.grown:at_limit": "a reason"}) == [
        "hound_id.grown:at_limit: not over 80 lines (or gone): drop it from LONG_FUNCTIONS"
    ]
    assert long_function_problems(added, {**reasons, "hound_id.grown:grown": " "}) == [
        "hound_id.grown:grown: no reason given"
    ]


#: No module longer than this many lines: a module over it does more than one job.
LONG_MODULE = 700


def long_modules(sources: dict[str, str], limit: int = LONG_MODULE) -> dict[str, int]:
    """Module -> its line count, for every module over ``limit`` lines."""
    return {name: n for name, text in sources.items() if (n := len(text.splitlines())) > limit}


def test_no_module_is_over_700_lines():
    assert long_modules({name: path.read_text() for name, path in MODULES.items()}) == {}
    assert long_modules({"hound_id.big": "x = 1\n" * (LONG_MODULE + 1), "hound_id.ok": "x = 1\n" * LONG_MODULE}) == {
        "hound_id.big": LONG_MODULE + 1
    }
