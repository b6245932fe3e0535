"""The package layout is camsim's layers (docs/architecture.md): each module imports only its own layer and the
layers below it, the packages import one another without a cycle, and so do the modules, within each package
and across the whole tree (:func:`module_graph`).

Every module of ``camsim/`` is parsed with :mod:`ast` (nothing is imported): its ``import`` statements at the top
and inside functions, and the modules it imports by name (a string constant that is a module's dotted name, as in
``_EXPORTS`` tables, ``import_module(...)`` and the samplers' ``draw_module``). ``from camsim import NAME`` counts
as an import of the module that defines NAME (``camsim._EXPORTS``), and so does ``import camsim`` for each
``camsim.NAME`` the module reads; ``from camsim import __version__`` (or ``camsim.__version__``) imports nothing: the
package itself is loaded before any of its modules. A new package or top-level module must be given its layer in
:data:`LAYERS` (and in the architecture page).
"""

from __future__ import annotations

import ast
import tomllib
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "camsim"

#: The layers, bottom to top: each unit (a package or a module directly in ``camsim/``) and its layer's number.
LAYERS = {
    "core": 1,        # errors, names, schema, pixel_limit, optional_numbers, seeding, xp, signals
    "light": 2,       # spectra, photons, rates
    "colour": 3,      # colorimetry, recovery, colour_names, rawcolour
    "sensor": 4,      # params, stages, kernels, dn_law, black_level, fixed_pattern, expected, noise_profile, cfa,
                      # camera, presets
    "optics": 5,      # the lens's parameters ([optics]) and its stages: OTFs, vignetting, lateral CA, FFT convolution
    "io": 6,          # the file-format codecs, atomic writes, figures
    "methods": 7,     # the samplers
    "scene": 8,       # scene files, sources, chart, built-in scenes, regions, radiance
    "render": 9,      # frame, pipeline, run, frame files, manifest, sidecar schema, preview, backends, optics
    # the applications: one layer, they may import one another (without a cycle)
    "analysis": 10, "calibration": 10, "dataset": 10, "denoise": 10, "emva": 10, "experiments": 10, "isp": 10,
    "optimise": 10, "pairs": 10, "pairs_torch": 10,
    "cli": 11,        # the command line and its sub-commands
    "__main__": 12,   # python -m camsim
}
LAYER_NAMES = {1: "core", 2: "light", 3: "colour", 4: "sensor", 5: "optics", 6: "io", 7: "methods", 8: "scene",
               9: "render", 10: "applications", 11: "cli", 12: "__main__"}

#: Package-level import edges allowed to close a cycle, with the reason (none: applications are one layer, so one
#: may import another, but never back; ``camsim analyze`` and the experiments draw their figures with the makers of
#: ``camsim.analysis.figures``, below both).
CYCLE_EXCEPTIONS: dict[tuple[str, str], str] = {}

#: Import edges between modules (:func:`module_graph`) allowed to close a cycle, with the reason. Each must still
#: close one: the tests fail when the edge is gone or no longer part of a cycle.
MODULE_CYCLE_EXCEPTIONS = {
    ("camsim.dataset._pool", "camsim.dataset._preload"): "the pool names _preload for its fork server to import "
                                                         "(set_forkserver_preload): another process imports it, not "
                                                         "the pool",
}

#: The only modules directly in camsim/ (everything else sits in the package of its layer).
TOP_LEVEL_MODULES = {"__init__", "__main__", "pairs", "pairs_torch"}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py")) if "scenes" not in p.relative_to(PACKAGE).parts}


def _root_exports() -> dict[str, str]:
    """``camsim._EXPORTS`` (public name -> defining module), read from the source."""
    tree = ast.parse((PACKAGE / "__init__.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_EXPORTS" for t in node.targets):
            return ast.literal_eval(node.value)
    raise AssertionError("camsim/__init__.py has no _EXPORTS")


ROOT_EXPORTS = _root_exports()


def _target(name: str) -> str | None:
    """The camsim module an import of the dotted ``name`` loads (its longest prefix that is a module)."""
    parts = name.split(".")
    while parts:
        if ".".join(parts) in MODULES:
            return ".".join(parts)
        parts.pop()
    return None


def imports_of(module: str) -> list[tuple[str, int]]:
    """``(imported camsim module, line)`` for every import in ``module``, at the top or inside functions."""
    path = MODULES[module]
    return imports_in(path.read_text(), module, is_package=path.name == "__init__.py")


def imports_in(source: str, module: str, is_package: bool = False) -> list[tuple[str, int]]:
    """``(imported camsim module, line)`` for every import in ``source``, the text of ``module``."""
    tree = ast.parse(source, filename=module)
    found = []
    # the names ``import camsim`` binds: the module imports what it reads of them (camsim.NAME), not the package
    front_door = {alias.asname or "camsim" for node in ast.walk(tree) if isinstance(node, ast.Import)
                  for alias in node.names if alias.name == "camsim" or (alias.name.startswith("camsim.")
                                                                        and not alias.asname)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(_target(alias.name), node.lineno) for alias in node.names
                      if alias.name.split(".")[0] == "camsim" and alias.name != "camsim"]
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in front_door \
                and node.attr in ROOT_EXPORTS:  # camsim.NAME: a lazy re-export, its defining module
            found.append((ROOT_EXPORTS[node.attr], node.lineno))
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: from the module's package, one level up per extra dot
                base = module.split(".") if is_package else module.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            if source.split(".")[0] != "camsim":
                continue
            for alias in node.names:
                if source == "camsim" and alias.name in ROOT_EXPORTS:  # a lazy re-export: its defining module
                    found.append((ROOT_EXPORTS[alias.name], node.lineno))
                elif f"{source}.{alias.name}" in MODULES:  # a submodule
                    found.append((f"{source}.{alias.name}", node.lineno))
                elif source != "camsim":  # a name of a module (camsim's own names, __version__, import nothing)
                    found.append((_target(source), node.lineno))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in MODULES \
                and node.value != "camsim":  # a module imported by name
            found.append((node.value, node.lineno))
    assert all(target is not None for target, _ in found), f"{module}: an import of no camsim module: {found}"
    return [(target, line) for target, line in found if target != module]


def unit_of(module: str) -> str:
    """The layer unit of a module: the package (or top-level module) directly under camsim that holds it."""
    return module.split(".")[1]


def layer_of(module: str) -> int:
    unit = unit_of(module)
    assert unit in LAYERS, (f"camsim.{unit} has no layer: give it one in LAYERS (tests/test_layers.py) and in "
                            "docs/architecture.md")
    return LAYERS[unit]


def _violations() -> list[str]:
    bad = []
    for module in MODULES:
        if module == "camsim":  # the front door: its names load, lazily, modules of every layer
            continue
        own = layer_of(module)
        for target, line in imports_of(module):
            if target != "camsim" and layer_of(target) > own:
                bad.append(f"{MODULES[module].relative_to(ROOT)}:{line}: {module} (layer {own}, "
                           f"{LAYER_NAMES[own]}) imports {target} (layer {layer_of(target)}, "
                           f"{LAYER_NAMES[layer_of(target)]})")
    return bad


def package_graph() -> dict[str, set[str]]:
    """Unit -> the units it imports (lazy imports included)."""
    graph = defaultdict(set)
    for module in MODULES:
        if module == "camsim":
            continue
        for target, _ in imports_of(module):
            if target != "camsim" and unit_of(target) != unit_of(module):
                graph[unit_of(module)].add(unit_of(target))
    return graph


def module_graph(unit: str | None = None) -> dict[str, set[str]]:
    """Module -> the modules it imports (lazy and by-name imports included): of the same package, for the modules
    of ``camsim.<unit>``; every camsim module, for all of them, without ``unit``."""
    graph = defaultdict(set)
    for module in MODULES:
        if unit is None:
            graph[module] |= {target for target, _ in imports_of(module)}
        elif module.startswith(f"camsim.{unit}.") or module == f"camsim.{unit}":
            graph[module] |= {target for target, _ in imports_of(module) if unit_of(target) == unit}
    return graph


#: The packages of camsim's layers (a unit that is a package, not a module directly in camsim/).
LAYER_PACKAGES = sorted(unit for unit in LAYERS if f"camsim.{unit}" in MODULES
                        and MODULES[f"camsim.{unit}"].name == "__init__.py")


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of ``graph`` as a path that ends where it starts, or None."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        state[node] = "done"
        stack.pop()
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def reaches(graph: dict[str, set[str]], start: str, goal: str) -> bool:
    """Whether a path of ``graph`` leads from ``start`` to ``goal``."""
    seen, todo = set(), [start]
    while todo:
        node = todo.pop()
        if node == goal:
            return True
        if node not in seen:
            seen.add(node)
            todo += graph.get(node, ())
    return False


def all_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle (:func:`find_cycle`) of each strongly connected part of ``graph`` that has one: however many
    cycles there are, each part of them is named."""
    nodes = set(graph) | {n for targets in graph.values() for n in targets}
    parts, placed = [], set()
    for node in sorted(nodes):
        if node in placed:
            continue
        part = {other for other in nodes if reaches(graph, node, other) and reaches(graph, other, node)}
        placed |= part | {node}
        if len(part) > 1 or node in graph.get(node, ()):
            parts.append(find_cycle({n: graph.get(n, set()) & part for n in part}))
    return parts


def _drop_exceptions(graph: dict[str, set[str]], exceptions: dict, name=lambda n: n) -> None:
    """Remove each excepted edge ``a -> b`` from ``graph``; it must be there and close a cycle (a path b → a)."""
    for (a, b), reason in exceptions.items():
        assert b in graph.get(a, set()), f"the exception {name(a)} -> {name(b)} ({reason}) is no longer needed: " \
                                         "remove it"
        assert reaches(graph, b, a), f"the exception {name(a)} -> {name(b)} ({reason}) closes no cycle any more: " \
                                     "remove it"
        graph[a].discard(b)


def _cycles_text(cycles: list[list[str]], name=lambda n: n) -> str:
    return "\n".join(" -> ".join(name(n) for n in cycle) for cycle in cycles)


def test_every_module_has_a_layer():
    units = {unit_of(m) for m in MODULES if m != "camsim"}
    assert units <= set(LAYERS), f"no layer for {sorted(units - set(LAYERS))}: add them to LAYERS"
    assert set(LAYERS) <= units, f"LAYERS names what camsim does not have: {sorted(set(LAYERS) - units)}"


def test_only_the_front_door_and_the_pairs_are_top_level_modules():
    top = {p.stem for p in PACKAGE.glob("*.py")}
    assert top == TOP_LEVEL_MODULES, f"modules directly in camsim/: {sorted(top - TOP_LEVEL_MODULES)} belong in " \
                                     "the package of their layer"


def test_imports_go_only_downwards():
    bad = _violations()
    assert not bad, "imports of a higher layer:\n" + "\n".join(bad)


def test_the_parser_sees_lazy_and_by_name_imports():
    """The check reads imports inside functions and by name, not only the top of a module."""
    assert "camsim.analysis.temporal" in {t for t, _ in imports_of("camsim.analysis.analyze")}
    assert "camsim.methods.fused" in {t for t, _ in imports_of("camsim.methods")}
    assert "camsim.scene.scene_file" in {t for t, _ in imports_of("camsim.scene")}


@pytest.mark.parametrize("source, imported", [
    ("import camsim\nversion = camsim.__version__", set()),
    ("from camsim import __version__", set()),
    ("def f():\n    import camsim\n    return camsim.load_scene", {"camsim.scene.scene_file"}),
    ("import camsim as c\nc.render_scene", {"camsim.render.run"}),
    ("import camsim.core.errors\ncamsim.scene_frame", {"camsim.core.errors", "camsim.render.pipeline"}),
    ("from camsim import SensorParams", {"camsim.sensor.params"}),
    ("from . import plan", {"camsim.methods.plan"}),
])
def test_the_parser_reads_the_front_door_as_the_names_it_gives(source, imported):
    """``import camsim`` loads nothing (the package is loaded before its modules); what a module reads of it
    (``camsim.NAME``) loads the module that defines NAME."""
    assert {t for t, _ in imports_in(source, "camsim.methods.fused")} == imported


def test_the_packages_import_one_another_without_a_cycle():
    graph = package_graph()
    _drop_exceptions(graph, CYCLE_EXCEPTIONS, name=lambda u: f"camsim.{u}")
    cycles = all_cycles(graph)
    assert not cycles, "cycles of package imports:\n" + _cycles_text(cycles, name=lambda u: f"camsim.{u}")


@pytest.mark.parametrize("unit", LAYER_PACKAGES)
def test_the_modules_of_a_package_import_one_another_without_a_cycle(unit):
    """Within a package too, imports go one way (an import inside a function counts: it only hides a cycle): the
    shared parts sit in a module below the modules that use them, as ``camsim.dataset.spec_parts`` below
    ``spec`` and ``raws`` and ``camsim.methods.tolerance`` below the registry (``camsim.methods``) and ``plan``; a
    package's ``__init__`` that its own modules import is no hub of names they need."""
    graph = module_graph(unit)
    _drop_exceptions(graph, {edge: why for edge, why in MODULE_CYCLE_EXCEPTIONS.items() if unit_of(edge[0]) == unit})
    cycles = all_cycles(graph)
    assert not cycles, "cycles of module imports:\n" + _cycles_text(cycles)


def test_the_modules_import_one_another_without_a_cycle():
    """Across the whole tree (the front door, every package, the top-level modules), imports go one way."""
    graph = module_graph()
    _drop_exceptions(graph, MODULE_CYCLE_EXCEPTIONS)
    cycles = all_cycles(graph)
    assert not cycles, "cycles of module imports:\n" + _cycles_text(cycles)


def test_every_package_is_checked():
    assert set(LAYERS) - set(LAYER_PACKAGES) == TOP_LEVEL_MODULES - {"__init__"}  # pairs, pairs_torch, __main__


def test_the_cycle_finder_finds_one():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_every_cycle_is_named():
    graph = {"a": {"b"}, "b": {"a", "c"}, "c": {"d"}, "d": {"c"}, "e": {"e"}, "f": {"a"}}
    assert sorted(all_cycles(graph)) == [["a", "b", "a"], ["c", "d", "c"], ["e", "e"]]
    assert all_cycles({"a": {"b", "c"}, "b": {"c"}, "c": set()}) == []


def test_an_exception_must_close_a_cycle():
    graph = {"a": {"b"}, "b": {"a"}}
    _drop_exceptions(graph, {("a", "b"): "why"})
    assert graph == {"a": set(), "b": {"a"}}
    with pytest.raises(AssertionError, match="no longer needed"):
        _drop_exceptions({"a": {"c"}, "b": {"a"}}, {("a", "b"): "why"})
    with pytest.raises(AssertionError, match="closes no cycle"):
        _drop_exceptions({"a": {"b"}, "b": set()}, {("a", "b"): "why"})


def test_the_public_paths_are_kept():
    import importlib.util

    import camsim
    import camsim.scene
    import camsim.sensor
    from camsim.scene.scene_file import Scene, load_scene
    from camsim.sensor.params import PRESETS, SensorParams, preset

    for name in camsim.__all__:
        assert getattr(camsim, name) is not None, name
    assert camsim.sensor.SensorParams is SensorParams and camsim.sensor.PRESETS is PRESETS
    assert camsim.sensor.preset is preset
    assert camsim.scene.load_scene is load_scene and camsim.scene.Scene is Scene
    for module in ("camsim.pairs", "camsim.pairs_torch", "camsim.cli", "camsim.__main__"):
        assert importlib.util.find_spec(module) is not None, module
    from camsim.cli import main, main_entry
    assert callable(main) and callable(main_entry)
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {"camsim": "camsim.cli:main_entry"}


@pytest.mark.parametrize("unit", ["core", "light", "colour", "sensor", "io", "methods", "scene", "render", "cli"])
def test_each_layer_package_says_what_it_holds(unit):
    """A reader of the tree learns what a layer's package holds, and what it may import, from its docstring."""
    module = f"camsim.{unit}"
    assert ast.get_docstring(ast.parse(MODULES[module].read_text())), f"{module} has no docstring"
