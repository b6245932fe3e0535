"""The docs' generated reference is complete: every command-line option and every schema key is on its page.

The generators of ``docs/_ext/camsim_reference.py`` are called as the docs build calls them (without Sphinx: they
return docutils nodes), and their text is checked against the parser and the schema walked here independently, so
that a new option or key cannot go undocumented. The API page is checked against ``camsim.__all__``.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import re
import sys
from pathlib import Path

import pytest

pytest.importorskip("docutils")  # installed with Sphinx (the docs extra)

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


@pytest.fixture(scope="module")
def reference():
    spec = importlib.util.spec_from_file_location("camsim_reference", DOCS / "_ext" / "camsim_reference.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("camsim_reference", module)
    spec.loader.exec_module(module)
    return module


def _text(node_list) -> str:
    return "\n".join(node.astext() for node in node_list)


def _parsers(parser: argparse.ArgumentParser, prog: str = "camsim"):
    """(prog, parser) of the parser and every sub-parser, walked here without the generator's help."""
    yield prog, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, f"{prog} {name}")


def _sections(node_list) -> dict:
    """The generated sections by title (``camsim render`` → its node)."""
    from docutils import nodes

    out = {}
    for node in node_list:
        for sec in ([node] if isinstance(node, nodes.section) else []) + list(node.findall(nodes.section)):
            out.setdefault(sec[0].astext(), sec)
    return out


def _terms(node_list) -> str:
    """The option labels (definition-list terms) of these nodes, not inside a sub-section: not the usage line,
    nor another option's help text, which may name an option too."""
    from docutils import nodes

    out = []

    def walk(node):
        if isinstance(node, nodes.term):
            out.append(node.astext())
        elif isinstance(node, nodes.Element):
            for child in node.children:
                if not isinstance(child, nodes.section):
                    walk(child)

    for node in node_list:
        if isinstance(node, nodes.section) and len(node_list) > 1:
            continue  # the page's top level: the sub-commands' sections are checked on their own
        walk(node)
    return "\n".join(out)


def _literals(node_list) -> set[str]:
    """The texts set as code (``literal``) in these nodes: a key's name in its table's first column."""
    from docutils import nodes

    return {lit.astext() for node in node_list for lit in node.findall(nodes.literal)}


def test_cli_reference_has_every_command_and_option(reference):
    from camsim.cli import build_parser

    generated = reference.cli_nodes(build_parser())
    sections = _sections(generated)
    missing = []
    for prog, parser in _parsers(build_parser()):
        if prog == "camsim":
            terms, text = _terms(generated), _text(generated)
        elif prog not in sections:
            missing.append(f"{prog}: no section")
            continue
        else:
            terms, text = _terms([sections[prog]]), sections[prog].astext()
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction) or action.help is argparse.SUPPRESS:
                continue
            # a positional is shown by its metavar, or by its choices (checked below) where it has none
            names = action.option_strings or [action.metavar or ("" if action.choices else action.dest)]
            for name in filter(None, names):
                if not re.search(rf"(?<![\w-]){re.escape(str(name))}(?![\w-])", terms):
                    missing.append(f"{prog}: {name}")
            for choice in action.choices or ():
                if str(choice) not in text:
                    missing.append(f"{prog}: {names[0] or action.dest} choice {choice}")
    assert not missing, "options missing from the command reference: " + ", ".join(missing)


def test_cli_reference_expands_help_and_shows_defaults(reference):
    from camsim.cli import build_parser

    text = _text(reference.cli_nodes(build_parser()))
    assert "%(" not in text  # argparse's %(default)s and friends are expanded
    render = reference.commands_of(build_parser()).subcommands[0]
    assert render.name == "camsim render"
    assert render.usage.startswith("usage: camsim render")


def _declared(cls) -> set[str]:
    """The fields of a dataclass declared as schema parameters (``camsim.schema.param`` stores a Param in the
    field's metadata)."""
    return {f.name for f in dataclasses.fields(cls) if "param" in f.metadata}


def test_scene_key_reference_has_every_schema_key(reference):
    import camsim

    SOURCES = sys.modules[camsim.load_scene.__module__].SOURCES  # the scene reader's (module paths move)
    shown = _literals(reference.scene_key_nodes())
    keys = _declared(camsim.SensorParams) | _declared(camsim.Scene)
    keys |= {"preset", "iso"} | {key for cls in SOURCES.values() for key in cls.keys}
    keys |= {f"[{name}]" for name in SOURCES}
    from camsim.optics.params import TABLE_ONLY_KEYS, OpticsParams

    keys |= _declared(OpticsParams) | set(TABLE_ONLY_KEYS)  # [optics]
    missing = sorted(k for k in keys if k not in shown)
    assert not missing, f"scene-file keys missing from the reference: {missing}"


def test_dataset_key_reference_has_every_parameter(reference):
    import camsim.dataset
    from camsim.dataset import raws, spec_parts

    spec = sys.modules[camsim.dataset.load_spec.__module__]
    shown = _literals(reference.dataset_key_nodes())
    keys = set(spec_parts.PARAMETERS) | set(spec._TOP_KEYS) | set(spec.IMAGES_TABLE_KEYS) | set(raws.RAWS_TABLE_KEYS)
    keys |= set(spec_parts.VIRTUAL_CAMERA_TABLE_KEYS) | set(spec_parts.DISTRIBUTIONS) | set(spec_parts.GRID_ALIASES)
    missing = sorted(k for k in keys if k not in shown)
    assert not missing, f"dataset-spec keys missing from the reference: {missing}"


def test_sidecar_key_reference_has_every_checked_key(reference):
    import camsim

    schema = reference.sidecar_module()
    shown = _literals(reference.sidecar_key_nodes())
    # the checker's keys, and every key the sensor writes to a frame's sidecar (the stage switches under "stages")
    record = camsim.SensorParams().sidecar_record()
    keys = set(schema.REQUIRED) | set(schema.FRAME_KEYS) | set(record) | set(record["stages"])
    missing = sorted(k for k in keys if k not in shown)
    assert not missing, f"sidecar keys missing from the reference: {missing}"


def test_sidecar_requirements_come_from_the_checker(reference):
    schema = reference.sidecar_module()
    messages, nullable = reference.sidecar_requirements(schema.FRAME_KEYS["width_px"])
    assert any("≥ 1" in m for m in messages) and not nullable
    messages, nullable = reference.sidecar_requirements(schema.FRAME_KEYS["exposure_max_s"])
    assert nullable


def test_api_page_lists_every_public_name():
    import camsim
    import camsim.pairs
    import camsim.pairs_torch

    page = (DOCS / "reference" / "api.md").read_text(encoding="utf-8")
    listed = {}
    for block in re.findall(r"\.\. currentmodule:: (\S+)\s*\n\s*\n\.\. autosummary::\n(.*?)\n```", page, re.S):
        module, body = block
        listed[module] = {line.strip() for line in body.splitlines()
                          if line.startswith("   ") and not line.strip().startswith(":")} - {""}
    expected = {"camsim": set(camsim.__all__) - {"__version__"}, "camsim.pairs": set(camsim.pairs.__all__),
                "camsim.pairs_torch": set(camsim.pairs_torch.__all__)}
    for module, names in expected.items():
        assert names <= listed.get(module, set()), f"{module}: not on the API page: {sorted(names - listed[module])}"
