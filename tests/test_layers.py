"""The import rules of docs/architecture.md, read statically (``ast``) from every module of the
product and of the tests, imports inside functions included:

* a layer imports only the layers below it (``ALLOWED``);
* no module imports a private name (leading underscore) of another module;
* no import cycle between modules;
* the product never imports the tests' code, and no test edits ``sys.path`` (code the tests of
  several folders share is the package ``tests/harness``).

The allow-lists below name what a later redesign removes; they must only shrink. Anything not on
them fails the test, and so does an entry that no longer happens (so the list cannot go stale).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"

#: Which layers each layer may import (product.md "Layout": data flows kinematics → synth → atlas
#: → db ← query (synth) → report → cli). The arrows are the data's way, the imports follow them
#: except at the database: ``db/`` implements the query's ``SegmentSource`` and owns the row format
#: of synth's records, so ``db`` imports ``synth`` and ``synth`` never imports ``db``. ``report``
#: works on candidates the query returned and needs no database; only ``cli`` sees every layer.
ALLOWED: dict[str, frozenset[str]] = {
    "kinematics": frozenset(),
    "synth": frozenset({"kinematics"}),
    "db": frozenset({"kinematics", "synth"}),
    "atlas": frozenset({"kinematics", "synth", "db"}),
    "report": frozenset({"kinematics", "synth"}),
    "cli": frozenset({"kinematics", "synth", "db", "atlas", "report"}),
}
LAYERS = tuple(ALLOWED)

#: Import cycles that exist today, each broken only by an import inside a function (none: the
#: query's contract, its figures test and the angle wrap sit in modules both sides import). Only shrinks.
KNOWN_CYCLES: frozenset[frozenset[str]] = frozenset()

#: (importing module, imported module, private name) allowed to cross a module boundary (none:
#: what a test needs is public, in its module's ``__all__``). Only shrinks.
KNOWN_PRIVATE_IMPORTS: frozenset[tuple[str, str, str]] = frozenset()


#: Test files that put a folder on ``sys.path`` (none: shared test code is the package ``tests/harness``).
KNOWN_PATH_EDITS: frozenset[str] = frozenset()


@dataclass(frozen=True)
class Import:
    """One imported module (and the name taken from it, if any), where it is written."""

    importer: str  # dotted name of the importing module
    module: str  # dotted name of the module the statement reads
    name: str | None  # the name taken from it (``from module import name``), None for ``import``
    line: int


def module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def read_imports(path: Path, name: str) -> list[Import]:
    """Every import statement of a file, at any depth (functions, ``if TYPE_CHECKING``, ...)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            out += [Import(name, alias.name, None, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolved against the importing package
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            out += [Import(name, module, alias.name, node.lineno) for alias in node.names]
    return out


def _files(root: Path, top: str) -> list[Path]:
    return sorted(p for p in (root / top).rglob("*.py") if ".venv" not in p.parts)


PRODUCT = {module_name(p, ROOT): p for top in LAYERS for p in _files(ROOT, top)}
PRODUCT_IMPORTS = [imp for name, path in PRODUCT.items() for imp in read_imports(path, name)]
TEST_FILES = {("tests." + module_name(p, TESTS)): p for p in _files(ROOT, "tests")}
TEST_IMPORTS = [imp for name, path in TEST_FILES.items() for imp in read_imports(path, name)]
#: Top-level names the tests' own modules are importable by (pytest puts their folders on the path).
TEST_TOP_NAMES = {p.stem for p in TESTS.rglob("*.py")} | {p.name for p in TESTS.rglob("*") if p.is_dir()} | {"tests"}


def target(imp: Import) -> str | None:
    """The product module an import loads (``from pkg import mod`` loads ``pkg.mod``), else None."""
    if imp.name and f"{imp.module}.{imp.name}" in PRODUCT:
        return f"{imp.module}.{imp.name}"
    return imp.module if imp.module in PRODUCT else None


def layer(module: str) -> str:
    return module.split(".")[0]


def test_the_scan_sees_the_product_and_its_function_level_imports():
    """A scan that found nothing would pass everything: the product has well over a hundred
    modules, and the six-bar imports its compiled kernel inside a function (numba's start-up
    cost is paid on first use)."""
    assert len(PRODUCT) > 100 and {layer(m) for m in PRODUCT} == set(LAYERS)
    assert len(TEST_FILES) > 50
    nested = {(i.importer, target(i)) for i in PRODUCT_IMPORTS}
    assert ("synth.mechanism.sixbar", "synth.mechanism.sixbar_kernel") in nested
    assert all(any(a in c and b in c and a != b for a, b in nested) for c in KNOWN_CYCLES)


def test_no_layer_imports_a_layer_above_it():
    wrong = sorted(
        f"{i.importer}:{i.line} imports {target(i)}"
        for i in PRODUCT_IMPORTS
        if target(i) and layer(target(i)) != layer(i.importer) and layer(target(i)) not in ALLOWED[layer(i.importer)]
    )
    assert not wrong, "upward imports (see ALLOWED):\n" + "\n".join(wrong)


def test_the_product_never_imports_the_tests():
    wrong = sorted(
        f"{i.importer}:{i.line} imports {i.module}"
        for i in PRODUCT_IMPORTS
        if i.module.split(".")[0] in TEST_TOP_NAMES and i.module.split(".")[0] not in LAYERS
    )
    assert not wrong, "\n".join(wrong)


def private_imports(imports: list[Import]) -> set[tuple[str, str, str]]:
    """(importer, module, name) of every private name taken from another module: ``from m import
    _x`` or ``import pkg._mod``. A module's own dunders (``__version__``) are not private."""
    out = set()
    for i in imports:
        if i.module == i.importer:
            continue
        if i.name and i.name.startswith("_") and not i.name.startswith("__"):
            out.add((i.importer, i.module, i.name))
        private_parts = [p for p in i.module.split(".") if p.startswith("_") and not p.startswith("__")]
        if private_parts and not i.module.startswith(i.importer.rpartition(".")[0] + "."):
            out.add((i.importer, i.module, private_parts[0]))
    return out


def test_no_module_imports_a_private_name_of_another():
    found = private_imports(PRODUCT_IMPORTS) | private_imports(TEST_IMPORTS)
    new = sorted(found - KNOWN_PRIVATE_IMPORTS)
    assert not new, "private names imported (make them public in __all__, or use the public name):\n" + "\n".join(
        f"{a} imports {c} from {b}" for a, b, c in new
    )
    gone = sorted(KNOWN_PRIVATE_IMPORTS - found)
    assert not gone, f"no longer imported, remove from KNOWN_PRIVATE_IMPORTS: {gone}"


def import_graph() -> dict[str, set[str]]:
    """Module → product modules it imports (at any depth). A package's ``__init__`` counts as a
    module: a submodule taking names from it while it imports that submodule is a cycle too."""
    graph: dict[str, set[str]] = {m: set() for m in PRODUCT}
    for i in PRODUCT_IMPORTS:
        t = target(i)
        if t and t != i.importer:
            graph[i.importer].add(t)
    return graph


def strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's components with more than one module (iterative: no recursion limit)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = set()
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.add(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(component)
    return found


def test_no_import_cycle_between_modules():
    components = strongly_connected(import_graph())
    unknown = [sorted(c) for c in components if frozenset(c) not in KNOWN_CYCLES]
    assert not unknown, f"import cycles (functions' imports included): {unknown}"
    gone = KNOWN_CYCLES - {frozenset(c) for c in components}
    assert not gone, f"no longer a cycle, remove from KNOWN_CYCLES: {[sorted(c) for c in gone]}"


def test_the_cycle_finder_finds_a_cycle():
    assert strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
    assert strongly_connected({"a": {"b"}, "b": set()}) == []


def edits_sys_path(path: Path) -> bool:
    """A call of ``sys.path.<anything>`` (insert, append, extend ...) or an assignment to it."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        target = node.func.value if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) else None
        if isinstance(node, (ast.Assign, ast.AugAssign)):
            target = node.targets[0] if isinstance(node, ast.Assign) else node.target
        if isinstance(target, ast.Attribute) and target.attr == "path" and getattr(target.value, "id", None) == "sys":
            return True
    return False


def test_no_test_edits_sys_path():
    found = {str(p.relative_to(ROOT)) for p in TEST_FILES.values() if edits_sys_path(p)}
    assert found <= KNOWN_PATH_EDITS, f"sys.path edited in {sorted(found - KNOWN_PATH_EDITS)}: use tests/harness"
    assert found == KNOWN_PATH_EDITS, f"remove from KNOWN_PATH_EDITS: {sorted(KNOWN_PATH_EDITS - found)}"
