"""The dependency rules of the package layout, checked on the source (AST) and in a fresh Python.

* **Layers.** :data:`LAYERS` orders fogsim's packages and top-level modules from the top (the
  entry points) to the bottom (errors, the version). Every import of a fogsim module targets the
  importer's own package or a strictly lower layer; packages of one layer never import each
  other; every fogsim module belongs to a layer (a new package fails here until it is placed).
* **No import circles**: the import graph (module → the module an import statement reads from,
  lazy imports and ``__init__`` modules included) has no cycle.
* Only ``fogsim.render.blender`` imports Blender's modules (bpy, mathutils, bpy_extras).
* Only ``fogsim.depth.ila``, ``fogsim.detection.yolo``, ``fogsim.detection.augmented`` and
  ``fogsim.augment.torch_fog`` import torch, torchvision or Ultralytics.
* The core — ``fogsim.fog``, ``fogsim.readers``, ``fogsim.scene``, ``fogsim.dataset``,
  ``fogsim.presets`` and the top-level modules — never reaches ``fogsim.render.blender``,
  ``fogsim.depth.ila``, ``fogsim.detection`` nor those heavy packages, not even through an
  import inside a function (a lazy import runs as soon as that function is called).

Every import statement counts, wherever it sits in a module (module level, functions,
``try`` blocks), and so does ``importlib.import_module("name")`` / ``__import__("name")`` /
``fogsim.deps.require("name", extra)`` with a literal name (probing with
``importlib.util.find_spec`` imports nothing and is not counted); ``if TYPE_CHECKING:`` imports
count too. An import reads from a module: ``from pkg import sub`` reads ``pkg.sub`` when that is
a module, ``pkg`` itself only for a name defined in ``pkg/__init__``. Importing ``fogsim.a.b`` also
runs ``fogsim/__init__`` and ``fogsim/a/__init__``: the closure below includes those parent
packages (what gets loaded), the layer and circle rules do not (a parent's ``__init__`` running
first is Python's order of loading, not a dependency of the importing module on it).
"""
from __future__ import annotations

import ast
import json
import subprocess
import sys
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "fogsim"

BLENDER_MODULES = {"bpy", "mathutils", "bpy_extras"}
TORCH_MODULES = {"torch", "torchvision", "ultralytics"}
HEAVY = BLENDER_MODULES | TORCH_MODULES
TORCH_OWNERS = {"fogsim.depth.ila", "fogsim.detection.yolo", "fogsim.detection.augmented", "fogsim.augment.torch_fog"}
CORE_PACKAGES = ("fogsim.fog", "fogsim.readers", "fogsim.scene", "fogsim.dataset", "fogsim.presets")
FORBIDDEN_IN_CORE = ("fogsim.render.blender", "fogsim.depth.ila", "fogsim.detection")

#: The layers, top first: (name, the packages and top-level modules in it). An entry that is a
#: package holds its whole subtree; ``fogsim`` is the package's own ``__init__`` (the public fog
#: API it re-exports) alone. ``augment`` is placed before it exists.
LAYERS = (
    ("entry points", {"fogsim", "fogsim.__main__"}),
    ("command line", {"fogsim.cli"}),
    ("benchmarks", {"fogsim.bench"}),
    ("renderer and detector study", {"fogsim.render", "fogsim.detection"}),
    ("augmentation", {"fogsim.augment"}),
    ("fog engine and depth", {"fogsim.fog", "fogsim.depth"}),
    ("dataset format", {"fogsim.dataset"}),
    ("dataset readers and scenes", {"fogsim.readers", "fogsim.scene"}),
    ("radar detections and their fog", {"fogsim.radar"}),
    ("LiDAR point clouds and their fog", {"fogsim.lidar"}),
    ("bundled presets", {"fogsim.presets"}),
    ("camera model after the fog", {"fogsim.sensor"}),
    ("document schemas", {"fogsim.schema"}),
    ("run bookkeeping", {"fogsim.runs"}),
    ("file I/O, dependencies, camera, pictures", {"fogsim.io", "fogsim.deps", "fogsim.camera", "fogsim.viz"}),
    ("basics", {"fogsim.errors", "fogsim._version", "fogsim.colour", "fogsim.boxes", "fogsim.rle"}),
    ("terminal output", {"fogsim.console"}),  # below io: its output capture (fogsim.io.integrity) is the one there is
)

#: Rules inside one package: its modules outside the inner package may not import it (the inner
#: package is a floor above them). ``render/`` is renderer-agnostic; only ``render/blender/`` is Blender.
INNER_LAYERS = (("fogsim.render", "fogsim.render.blender"),)


@dataclass(frozen=True)
class Edge:
    """One import statement of ``module`` that brings in ``target`` (a module name)."""

    module: str
    target: str
    line: int
    text: str
    lazy: bool  # inside a function (runs when the function does)

    def __str__(self) -> str:
        if not self.line:
            return f"{self.module} (its parent package)"
        where = "in a function" if self.lazy else "at module level"
        path = MODULES[self.module].relative_to(ROOT).as_posix()
        return f"{self.module} ({path}:{self.line}, {where}): {self.text}"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def discover() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


MODULES = discover()


def _within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def _is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


def resolve_from(module: str, node: ast.ImportFrom) -> str:
    """The absolute module an ``ImportFrom`` reads from, relative levels resolved."""
    if not node.level:
        return node.module or ""
    package = module if _is_package(module) else module.rpartition(".")[0]
    parts = package.split(".")
    if node.level - 1 > len(parts) - 1:
        raise ValueError(f"{module} line {node.lineno}: relative import beyond the top-level package")
    base = ".".join(parts[: len(parts) - (node.level - 1)])
    return f"{base}.{node.module}" if node.module else base


def _parents_and_self(name: str) -> list[str]:
    parts = name.split(".")
    return [".".join(parts[: i + 1]) for i in range(len(parts))]


def _internal(name: str) -> str | None:
    """The fogsim module that importing ``name`` runs last (the longest existing prefix)."""
    for candidate in reversed(_parents_and_self(name)):
        if candidate in MODULES:
            return candidate
    return None


class _Visitor(ast.NodeVisitor):
    def __init__(self, module: str, lines: list[str]):
        self.module, self.lines, self.depth, self.edges, self.dynamic = module, lines, 0, [], []

    def _function(self, node):
        self.depth += 1
        self.generic_visit(node)
        self.depth -= 1

    visit_FunctionDef = visit_AsyncFunctionDef = visit_Lambda = _function

    def _add(self, node, targets: list[str]):
        text = self.lines[node.lineno - 1].strip()
        for t in targets:
            self.edges.append(Edge(self.module, t, node.lineno, text, self.depth > 0))

    def visit_Import(self, node: ast.Import):
        self._add(node, [a.name for a in node.names])

    def visit_Call(self, node: ast.Call):
        # importlib.import_module("x") / __import__("x") / fogsim.deps.require("x", extra): an import too
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None
        if name in ("import_module", "__import__", "require") and node.args:
            if isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
                self._add(node, [node.args[0].value])
            else:  # a computed name: no rule could see where it points
                self.dynamic.append(f"{self.module} line {node.lineno}: {self.lines[node.lineno - 1].strip()}")
        self.generic_visit(node)

    def visit_ImportFrom(self, node: ast.ImportFrom):
        base = resolve_from(self.module, node)
        # ``from pkg import name`` reads pkg.name when that is a fogsim module, else pkg's namespace
        subs = [f"{base}.{a.name}" for a in node.names if a.name != "*" and f"{base}.{a.name}" in MODULES]
        self._add(node, subs + ([base] if len(subs) < len(node.names) else []))


def scan(module: str, source: str | None = None) -> _Visitor:
    source = MODULES[module].read_text(encoding="utf-8") if source is None else source
    visitor = _Visitor(module, source.splitlines())
    visitor.visit(ast.parse(source, filename=str(MODULES.get(module, module))))
    return visitor


def imports_of(module: str) -> list[Edge]:
    return scan(module).edges


EDGES = {m: imports_of(m) for m in MODULES}
#: the one module that may import by a computed name: fogsim.deps.require's own import_module
DYNAMIC_IMPORTER = "fogsim.deps"


def graph_successors(module: str) -> list[tuple[str, Edge]]:
    """(node, edge) pairs: the fogsim modules (with their parent packages) and the external
    top-level packages that the imports of ``module`` run."""
    out = [(parent, Edge(module, parent, 0, "(parent package)", False))
           for parent in _parents_and_self(module)[:-1] if parent in MODULES]
    for e in EDGES[module]:
        if _within(e.target, "fogsim"):
            target = _internal(e.target)
            if target is not None:
                out += [(p, e) for p in _parents_and_self(target) if p in MODULES and p != module]
        else:
            out.append((e.target.split(".")[0], e))
    return out


def core_roots() -> list[str]:
    """The core modules: the core packages and the top-level modules (``fogsim/__main__`` is the
    command line's entry, not core)."""
    top_level = [m for m in MODULES if m == "fogsim" or (m.count(".") == 1 and not _is_package(m)
                                                         and m != "fogsim.__main__")]
    return sorted(set(top_level) | {m for m in MODULES if any(_within(m, p) for p in CORE_PACKAGES)})


def _forbidden(node: str) -> bool:
    return node in HEAVY or any(_within(node, p) for p in FORBIDDEN_IN_CORE)


def closure_violations(roots: list[str] | None = None) -> dict[Edge, list[str]]:
    """Every import edge by which ``roots`` (the core) reach a forbidden module, with one import
    chain (breadth first from a root, so the shortest) that leads to it."""
    found: dict[Edge, list[str]] = {}
    seen: dict[str, list[str]] = {}
    queue = deque()
    for root in core_roots() if roots is None else roots:
        seen[root] = [root]
        queue.append(root)
    while queue:
        node = queue.popleft()
        if node not in MODULES:
            continue  # an external package: not followed
        for succ, edge in graph_successors(node):
            if _forbidden(succ):
                found.setdefault(edge, seen[node] + [f"{succ}   ← {edge}"])
                continue
            if succ not in seen:
                seen[succ] = seen[node] + [f"{succ}   ← {edge}"]
                queue.append(succ)
    return found


def _report(title: str, items: list[str]) -> str:
    return title + "\n  " + "\n  ".join(items)


# ------------------------------------------------------------------------------- layers and circles
Graph = dict[str, list[tuple[str, Edge]]]


def layer_unit(module: str) -> tuple[int, str] | None:
    """(layer index, entry) of a fogsim module: the entry naming it, else the package entry that
    holds it (``fogsim`` holds only itself); None when it is in no layer."""
    for i, (_, entries) in enumerate(LAYERS):
        if module in entries:
            return i, module
    for i, (_, entries) in enumerate(LAYERS):
        for entry in entries:
            if entry != "fogsim" and module.startswith(entry + "."):
                return i, entry
    return None


def import_graph() -> Graph:
    """module → (the fogsim module read, the import) for every import of a fogsim module, lazy
    ones included, parent packages not added (see the module docstring)."""
    graph = {}
    for module, edges in EDGES.items():
        targets = [(_internal(e.target), e) for e in edges if _within(e.target, "fogsim")]
        graph[module] = [(t, e) for t, e in targets if t is not None and t != module]
    return graph


def _layer_name(index: int) -> str:
    return f"layer {index + 1} ({LAYERS[index][0]})"


def layer_violations(graph: Graph) -> list[str]:
    """Every import that does not point into the importer's own package or a strictly lower layer."""
    bad = []
    for module, targets in graph.items():
        here = layer_unit(module)
        for target, edge in targets:
            there = layer_unit(target)
            for package, inner in INNER_LAYERS:
                if _within(module, package) and not _within(module, inner) and _within(target, inner):
                    bad.append(f"{edge}\n      {module} is in {package} outside {inner}, the floor above it "
                               f"(INNER_LAYERS)")
            if here is None or there is None or here[1] == there[1] or there[0] > here[0]:
                continue  # unplaced modules are reported by their own test
            how = "a sibling package of the same layer" if there[0] == here[0] else "a higher layer"
            bad.append(f"{edge}\n      {module} is in {_layer_name(here[0])}; {target} is in "
                       f"{_layer_name(there[0])}, {how}")
    return bad


def import_circles(graph: Graph) -> list[list[tuple[str, Edge]]]:
    """One shortest cycle (as its imports) per strongly connected set of modules."""
    successors = {m: {t for t, _ in targets} for m, targets in graph.items()}

    def reachable(start: str) -> set[str]:
        seen, queue = set(), deque(successors.get(start, ()))
        while queue:
            node = queue.popleft()
            if node not in seen:
                seen.add(node)
                queue.extend(successors.get(node, ()))
        return seen

    reach = {m: reachable(m) for m in graph}
    done, circles = set(), []
    for start in sorted(graph):
        if start in done or start not in reach[start]:
            continue
        done |= {n for n in reach[start] if start in reach.get(n, ())}
        back: dict[str, tuple[str, Edge]] = {}
        queue = deque([start])
        while start not in back:  # breadth first from start until an import leads back to it
            node = queue.popleft()
            for target, edge in graph.get(node, ()):
                if target not in back:
                    back[target] = (node, edge)
                    queue.append(target)
        cycle, node = [], start
        while True:
            prev, edge = back[node]
            cycle.append((node, edge))
            node = prev
            if node == start:
                break
        circles.append(cycle[::-1])
    return circles


# ------------------------------------------------------------------------------- the scanner works
def test_scanner_sees_the_layout_and_the_known_heavy_imports():
    """Guards the rules below against passing vacuously (a scanner that finds nothing)."""
    for name in ("fogsim", "fogsim.fog.model", "fogsim.readers.base", "fogsim.render.blender",
                 "fogsim.depth.ila", "fogsim.detection.yolo", "fogsim.cli"):
        assert name in MODULES, name
    external = lambda m: {e.target.split(".")[0] for e in EDGES[m] if not _within(e.target, "fogsim")}  # noqa: E731
    assert "torch" in external("fogsim.depth.ila")
    assert {"torch", "ultralytics"} <= external("fogsim.detection.yolo")
    assert any(BLENDER_MODULES & external(m) for m in MODULES if _within(m, "fogsim.render.blender"))
    assert any(e.lazy for e in EDGES["fogsim.cli"]) and any(not e.lazy for e in EDGES["fogsim.cli"])
    assert "fogsim.fog.model" in {s for s, _ in graph_successors("fogsim.fog")}
    assert "fogsim" in core_roots() and "fogsim.fog.model" in core_roots() and "fogsim.errors" in core_roots()
    assert "fogsim.render.frame" not in core_roots() and "fogsim.cli" not in core_roots()


def test_closure_follows_lazy_and_transitive_imports():
    """The command line (not core) does reach the heavy parts, through imports inside functions
    and other modules: the closure walk finds those paths."""
    reached = {e.target.split(".")[0] if not _within(e.target, "fogsim") else e.target
               for e in closure_violations(["fogsim.cli"])}
    assert any(_within(t, "fogsim.depth.ila") for t in reached), reached
    assert any(_within(t, "fogsim.render.blender") for t in reached), reached
    assert any(_within(t, "fogsim.detection") for t in reached), reached


def test_dynamic_imports_by_literal_name_count():
    src = ("import importlib\ndef f():\n    importlib.import_module('bpy')\n    __import__('torch.nn')\n"
           "    importlib.util.find_spec('ultralytics')\n    deps.require('ultralytics', 'detect')\n")
    v = _Visitor("fogsim.errors", src.splitlines())
    v.visit(ast.parse(src))
    assert [(e.target, e.line, e.lazy) for e in v.edges] == [("importlib", 1, False), ("bpy", 3, True),
                                                             ("torch.nn", 4, True), ("ultralytics", 6, True)]


def test_imports_by_a_computed_name_are_refused():
    """A name the scanner cannot read (``import_module(TABLE[name])``) would hide an import from every rule."""
    src = "import importlib\nNAMES = {}\ndef f(n):\n    return importlib.import_module(NAMES[n])\n"
    assert scan("fogsim.errors", src).dynamic == ["fogsim.errors line 4: return importlib.import_module(NAMES[n])"]
    bad = [d for m in MODULES if m != DYNAMIC_IMPORTER for d in scan(m).dynamic]
    if bad:
        pytest.fail(_report("imports by a computed name (write the import out, as a lazy import):", bad),
                    pytrace=False)


def test_relative_imports_resolve():
    tree = ast.parse("from . import model\nfrom .levels import FogLevel\nfrom .. import camera\n"
                     "from ..depth.fill import fill_holes\n")
    got = [resolve_from("fogsim.fog.model", n) for n in tree.body]
    assert got == ["fogsim.fog", "fogsim.fog.levels", "fogsim", "fogsim.depth.fill"]
    assert [resolve_from("fogsim.fog", n) for n in tree.body] == got  # a package's own __init__
    with pytest.raises(ValueError, match="beyond"):
        resolve_from("fogsim.errors", ast.parse("from ... import x").body[0])


# ----------------------------------------------------------------------------------------- rules
def test_layers_name_distinct_entries_that_do_not_nest():
    entries = [e for _, layer in LAYERS for e in layer]
    assert len(entries) == len(set(entries)), "an entry is in two layers"
    nested = [(a, b) for a in entries for b in entries if a != "fogsim" and b.startswith(a + ".")]
    assert not nested, f"a layer entry inside another: {nested}"


def test_every_module_belongs_to_a_layer():
    unplaced = sorted(m for m in MODULES if layer_unit(m) is None)
    if unplaced:
        pytest.fail(_report("fogsim modules in no layer (place their package in LAYERS, "
                            "tests/test_import_rules.py):", unplaced), pytrace=False)


def test_every_import_points_down_the_layers():
    bad = layer_violations(import_graph())
    if bad:
        pytest.fail(_report("imports that do not point into their own package or a lower layer "
                            "(LAYERS, tests/test_import_rules.py):", bad), pytrace=False)


def test_no_import_circles():
    circles = import_circles(import_graph())
    if circles:
        pytest.fail(_report("import circles (lazy imports included), each as its imports:",
                            ["\n    ".join(str(edge) for _, edge in cycle) for cycle in circles]), pytrace=False)


def private_imports(module: str, source: str | None = None) -> list[str]:
    """``from fogsim.x import _name`` statements of ``module``: a private name used outside the
    module that defines it (dunders such as ``__version__`` are not private)."""
    source = MODULES[module].read_text(encoding="utf-8") if source is None else source
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and _within(resolve_from(module, node), "fogsim"):
            names = [a.name for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
            out += [f"{module} line {node.lineno}: {resolve_from(module, node)}.{n}" for n in names]
    return out


def test_no_private_name_crosses_modules():
    made_up = "from fogsim.boxes import _Runs, box_convert\nfrom . import __version__\n"
    assert private_imports("fogsim.errors", made_up) == ["fogsim.errors line 1: fogsim.boxes._Runs"]  # it works
    bad = [item for m in MODULES for item in private_imports(m)]
    if bad:
        pytest.fail(_report("private names imported from another module (make them public or move them):", bad),
                    pytrace=False)


def defined_names(source: str) -> set[str]:
    """The names a module defines at its top level (functions, classes, assignments; inside a
    top-level ``if`` / ``try`` too), not those it imports."""
    names: set[str] = set()

    def take(nodes):
        for node in nodes:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.add(node.name)
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                    names.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
            elif isinstance(node, (ast.If, ast.Try)):
                take(node.body + node.orelse + getattr(node, "finalbody", [])
                     + [n for h in getattr(node, "handlers", []) for n in h.body])
    take(ast.parse(source).body)
    return names


DEFINED = {m: defined_names(p.read_text(encoding="utf-8")) for m, p in MODULES.items()}


def second_doors(module: str, source: str | None = None) -> list[str]:
    """``from fogsim.x import Name`` where x is a module (not a package face) that does not define
    Name but only imports it: the name has a first door, its defining module."""
    source = MODULES[module].read_text(encoding="utf-8") if source is None else source
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.ImportFrom):
            continue
        base = resolve_from(module, node)
        if base not in MODULES or _is_package(base):
            continue  # package __init__ faces may re-export
        for a in node.names:
            if f"{base}.{a.name}" not in MODULES and a.name not in DEFINED[base] and a.name != "*":
                out.append(f"{module} line {node.lineno}: {base}.{a.name} (not defined there)")
    return out


def test_a_name_is_imported_from_the_module_that_defines_it():
    assert second_doors("fogsim.errors", "from fogsim.fog.scatter import Intrinsics, scatter\n") == [
        "fogsim.errors line 1: fogsim.fog.scatter.Intrinsics (not defined there)"]  # it works
    bad = [item for m in MODULES for item in second_doors(m)]
    if bad:
        pytest.fail(_report("names imported through a module that only re-exports them (import from where "
                            "they are defined):", bad), pytrace=False)


def test_the_layer_and_circle_checks_catch_what_they_forbid():
    """Guards the two rules above against passing vacuously, on made-up imports."""
    def edge(module, target, line=1):
        return Edge(module, target, line, f"import {target}", False)

    assert layer_unit("fogsim") == (0, "fogsim") and layer_unit("fogsim.fog.model") == layer_unit("fogsim.fog")
    assert layer_unit("fogsim.newpackage.x") is None and layer_unit("fogsim.newmodule") is None
    up = {"fogsim.dataset.writer": [("fogsim.render.labels", edge("fogsim.dataset.writer", "fogsim.render.labels"))],
          "fogsim.readers.base": [("fogsim.scene.classes", edge("fogsim.readers.base", "fogsim.scene.classes"))],
          "fogsim.fog.model": [("fogsim.fog.levels", edge("fogsim.fog.model", "fogsim.fog.levels")),
                               ("fogsim.errors", edge("fogsim.fog.model", "fogsim.errors"))]}
    bad = layer_violations(up)
    assert len(bad) == 2 and "fogsim/dataset/writer.py:1" in bad[0] and "a higher layer" in bad[0]
    assert "layer 7 (dataset format)" in bad[0] and "layer 4 (renderer and detector study)" in bad[0]
    assert "sibling" in bad[1]
    loop = {"fogsim.camera": [("fogsim.errors", edge("fogsim.camera", "fogsim.errors", 3))],
            "fogsim.errors": [("fogsim.io", edge("fogsim.errors", "fogsim.io", 5))],
            "fogsim.io": [("fogsim.camera", edge("fogsim.io", "fogsim.camera", 7))],
            "fogsim.colour": [("fogsim.errors", edge("fogsim.colour", "fogsim.errors"))]}
    # a lazy import of render.blender from render/ (outside it), and an upward import_module literal
    lazy = scan("fogsim.render.frame", MODULES["fogsim.render.frame"].read_text()
                + "\n\ndef _x():\n    from fogsim.render.blender import build\n")
    upward = scan("fogsim.fog.model",
                  "import importlib\ndef f():\n    importlib.import_module('fogsim.render.frame')\n")
    made = {"fogsim.render.frame": [(_internal(e.target), e) for e in lazy.edges if _within(e.target, "fogsim")],
            "fogsim.fog.model": [(_internal(e.target), e) for e in upward.edges if _within(e.target, "fogsim")]}
    found = layer_violations(made)
    assert any("INNER_LAYERS" in b and "fogsim.render.blender" in b for b in found), found
    assert any("fogsim.fog.model" in b and "a higher layer" in b and "import_module" in b for b in found), found
    assert not layer_violations({"fogsim.render.blender.job": [("fogsim.render.blender.build",
                                                                edge("fogsim.render.blender.job", "x"))]})
    circles = import_circles(loop)
    assert len(circles) == 1 and sorted(m for m, _ in circles[0]) == ["fogsim.camera", "fogsim.errors", "fogsim.io"]
    assert import_circles({k: v for k, v in loop.items() if k != "fogsim.io"}) == []


def test_only_render_blender_imports_blender_modules():
    bad = [str(e) for m, edges in EDGES.items() if not _within(m, "fogsim.render.blender")
           for e in edges if e.target.split(".")[0] in BLENDER_MODULES]
    if bad:
        pytest.fail(_report("bpy/mathutils/bpy_extras imported outside fogsim.render.blender:", bad), pytrace=False)


def test_only_ila_and_yolo_import_torch_or_ultralytics():
    bad = [str(e) for m, edges in EDGES.items() if m not in TORCH_OWNERS
           for e in edges if e.target.split(".")[0] in TORCH_MODULES]
    if bad:
        pytest.fail(_report("torch/torchvision/ultralytics imported outside fogsim.depth.ila, "
                            "fogsim.augment.torch_fog and fogsim.detection.{yolo,augmented}:", bad), pytrace=False)


def test_core_never_reaches_blender_ila_detection_or_heavy_packages():
    violations = closure_violations()
    if violations:
        pytest.fail(_report(
            "the core (fog, readers, scene, dataset, presets, top-level modules) reaches a forbidden module; "
            "each offending import, then the chain from a core module:",
            [f"{edge}\n      via: " + "\n           ".join(chain) for edge, chain in violations.items()]),
            pytrace=False)


# ------------------------------------------------------------------------------- a fresh interpreter
PROBE = """
import json, sys
{body}
print("MODULES " + json.dumps(sorted(sys.modules)))
"""


def _probe(body: str) -> list[str]:
    """The modules a fresh Python holds after running ``body``."""
    code = PROBE.format(body=body)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("MODULES "))
    return json.loads(line[len("MODULES "):])


def _heavy(modules: list[str]) -> list[str]:
    return [m for m in modules if m.split(".")[0] in HEAVY]


def test_import_fogsim_leaves_heavy_modules_out():
    loaded = _probe("import fogsim\nimport fogsim.fog, fogsim.camera, fogsim.readers, fogsim.dataset.writer")
    assert "fogsim.fog.model" in loaded and "fogsim.dataset.writer" in loaded  # the probe works
    assert _heavy(loaded) == [] and [m for m in loaded if _forbidden(m)] == []


def test_cli_help_and_levels_leave_heavy_modules_out():
    body = ("import fogsim.cli\n"
            "from fogsim.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit as e:\n    assert e.code == 0, e.code\n"
            "assert main(['levels']) == 0\n")
    loaded = _probe(body)
    assert "fogsim.cli" in loaded and "fogsim.fog.levels" in loaded
    assert _heavy(loaded) == []


def test_python_m_fogsim_help_imports_no_heavy_module():
    """The real entry (``python -m fogsim --help``), watched by ``-X importtime``."""
    if not (PACKAGE / "__main__.py").is_file():
        pytest.skip("fogsim has no __main__ (python -m fogsim)")
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "fogsim", "--help"], capture_output=True,
                       text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0 and "usage" in r.stdout, r.stderr[-3000:]
    imported = [ln.rsplit("|", 1)[-1].strip() for ln in r.stderr.splitlines() if ln.startswith("import time:")]
    assert "fogsim.cli" in imported  # the probe works
    assert _heavy(imported) == []
