"""The generated reference pages of camsim's docs: commands, scene-file keys, dataset-spec keys, sidecar keys.

Each directive reads the code at build time, so the pages cannot drift from it:

``camsim-cli``
    every command and option of ``camsim``, from ``camsim.cli.build_parser()`` (the argparse parser itself);
``camsim-scene-keys``
    the scene file's tables and keys: the declared parameters (:class:`camsim.core.schema.Param`) of ``[sensor]`` and
    ``[render]`` with type, unit, default, bounds and description, the tables a scene file may have, and the keys
    of each scene source's table, of ``[camera.scale]`` and of ``[[region]]``;
``camsim-dataset-keys``
    the dataset spec's parameters (the same declarations) and its tables;
``camsim-sidecar-keys``
    the JSON sidecar's keys, as :func:`camsim.render.sidecar_schema.check_sidecar` checks them.

The module paths below ``camsim.`` are resolved through public names where there is one
(``camsim.load_scene.__module__``), so that moving a module does not break the docs. Each directive is a thin
layer over a function that returns docutils nodes (``cli_nodes``, ``scene_key_nodes``, …), which
``tests/docs/test_reference.py`` calls without Sphinx.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import math
import re
import sys
import warnings

from docutils import nodes
from docutils.parsers.rst import Directive

# -------------------------------------------------------------------------------------------------------------------
# Where the declarations live (resolved at build time)
# -------------------------------------------------------------------------------------------------------------------


def _module_of(obj):
    return sys.modules[obj.__module__] if obj.__module__ in sys.modules else importlib.import_module(obj.__module__)


def build_parser() -> argparse.ArgumentParser:
    from camsim.cli import build_parser as build

    return build()


def scene_module():
    import camsim

    return _module_of(camsim.load_scene)


def sensor_module():
    import camsim

    return _module_of(camsim.SensorParams)


def spec_module():
    import camsim.dataset

    return _module_of(camsim.dataset.load_spec)


def spec_parts_module():
    """The module of what every dataset spec is made of: its parameters and their tables, its frames."""
    import camsim.dataset

    return _module_of(camsim.dataset.FrameSpec)


def raws_module():
    """The module of a ``[raws]`` spec (its table's keys), beside the spec's."""
    return importlib.import_module(spec_module().__name__.rsplit(".", 1)[0] + ".raws")


def sidecar_module():
    import camsim

    frame_files = camsim.write_frame.__module__  # the sidecar checker sits beside the frame files
    return importlib.import_module(frame_files.rsplit(".", 1)[0] + ".sidecar_schema")


def scale_classes() -> dict:
    """The ``[camera.scale]`` kinds: ``kind`` → dataclass (from the scene's default scale's module)."""
    import camsim

    scene_cls = camsim.Scene
    anchor = type(next(f for f in dataclasses.fields(scene_cls) if f.name == "scale").default_factory())
    module = _module_of(anchor)
    return {"anchor": anchor, "physical": module.PhysicalScale}


# -------------------------------------------------------------------------------------------------------------------
# Node helpers
# -------------------------------------------------------------------------------------------------------------------


def _slug(text: str) -> str:
    return nodes.make_id(text)


def section(title: str, ident: str | None = None) -> nodes.section:
    """A section node with an id (the page's ``#anchor``) and a title."""
    ident = ident or _slug(title)
    sec = nodes.section(ids=[ident], names=[nodes.fully_normalize_name(title)])
    sec += nodes.title(title, title)
    return sec


def text_block(text: str) -> nodes.literal_block:
    """A block of text laid out by hand (a usage, an epilog), shown as it is: no syntax highlighting."""
    return nodes.literal_block(text, text, language="text")


def para(*parts) -> nodes.paragraph:
    """A paragraph of text and nodes (a str is text)."""
    node = nodes.paragraph()
    for part in parts:
        node += nodes.Text(part) if isinstance(part, str) else part
    return node


def literal(text: str) -> nodes.literal:
    return nodes.literal(text, text)


def _inline(node) -> bool:
    return isinstance(node, (str, nodes.Text, nodes.Inline))


def table(headers: list[str], rows: list[list], widths: list[int] | None = None, classes=()) -> nodes.table:
    """A docutils table; a cell is a str (text), a node, or a list of nodes."""
    widths = widths or [1] * len(headers)
    tab = nodes.table(classes=list(classes))
    group = nodes.tgroup(cols=len(headers))
    tab += group
    for width in widths:
        group += nodes.colspec(colwidth=width)

    def row_of(cells):
        row = nodes.row()
        for cell in cells:
            entry = nodes.entry()
            if isinstance(cell, str):
                if cell:
                    entry += nodes.paragraph(cell, cell)
            elif isinstance(cell, list):
                entry += para(*cell) if cell and _inline(cell[0]) else cell
            else:
                entry += para(cell) if _inline(cell) else cell
            row += entry
        return row

    head = nodes.thead()
    head += row_of(headers)
    group += head
    body = nodes.tbody()
    for cells in rows:
        body += row_of(cells)
    group += body
    return tab


# -------------------------------------------------------------------------------------------------------------------
# The command line
# -------------------------------------------------------------------------------------------------------------------

USAGE_WIDTH = 100


@dataclasses.dataclass
class Option:
    """One argument of a command, as the reference shows it."""

    flags: tuple[str, ...]  # option strings ('-o', '--out'), or () for a positional
    metavar: str  # as the usage prints it ('DIR', 'NAME [NAME ...]'); '' for a switch
    help: str
    default: str | None  # shown default, None when there is nothing to show
    choices: tuple[str, ...] | None
    required: bool
    repeatable: bool

    @property
    def positional(self) -> bool:
        return not self.flags

    @property
    def label(self) -> str:
        if self.positional:
            return self.metavar
        return ", ".join(f"{flag} {self.metavar}".strip() for flag in self.flags)


@dataclasses.dataclass
class Command:
    """One command (``camsim`` itself, or a sub-command), with its usage, texts and options."""

    name: str  # 'camsim render'
    summary: str  # the one line ``camsim --help`` shows for it
    usage: str
    description: str
    epilog: str
    raw_text: bool  # description/epilog laid out by hand (RawDescriptionHelpFormatter)
    options: list[Option]
    subcommands: list[Command]


def _formatter(parser: argparse.ArgumentParser):
    try:
        return parser.formatter_class(prog=parser.prog, width=USAGE_WIDTH)
    except TypeError:
        return parser._get_formatter()


def _usage(parser: argparse.ArgumentParser) -> str:
    formatter = _formatter(parser)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return formatter.format_help().strip()


def _shown_default(value) -> str:
    if isinstance(value, (list, tuple)):
        return " ".join(_shown_default(v) for v in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _option(parser: argparse.ArgumentParser, action: argparse.Action) -> Option | None:
    if action.help is argparse.SUPPRESS:
        return None
    formatter = _formatter(parser)
    if action.option_strings:
        metavar = "" if action.nargs == 0 else formatter._format_args(
            action, formatter._get_default_metavar_for_optional(action))
    else:
        metavar = formatter._format_args(action, formatter._get_default_metavar_for_positional(action))
    try:
        text = formatter._expand_help(action) if action.help else ""
    except (KeyError, TypeError, ValueError):
        text = action.help or ""
    flagless = isinstance(action, (argparse._HelpAction, argparse._VersionAction))
    default = action.default
    shown = None
    if not flagless and action.nargs != 0 and default not in (None, argparse.SUPPRESS) and not (
            isinstance(default, (list, tuple)) and not default):
        shown = _shown_default(default)
    choices = tuple(str(c) for c in action.choices) if action.choices is not None else None
    return Option(tuple(action.option_strings), metavar, " ".join(text.split()), shown, choices,
                  bool(action.required), isinstance(action, (argparse._AppendAction, argparse._CountAction,
                                                             argparse._AppendConstAction)))


def commands_of(parser: argparse.ArgumentParser, name: str | None = None, summary: str = "") -> Command:
    """The parser as a :class:`Command` tree (every sub-command, recursively)."""
    options, subcommands = [], []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            summaries = {a.dest: a.help or "" for a in action._choices_actions}
            seen = set()
            for sub_name, sub in action.choices.items():
                if id(sub) in seen:  # an alias
                    continue
                seen.add(id(sub))
                subcommands.append(commands_of(sub, sub.prog, summaries.get(sub_name, "")))
            continue
        option = _option(parser, action)
        if option is not None:
            options.append(option)
    raw = issubclass(parser.formatter_class, argparse.RawDescriptionHelpFormatter)
    return Command(name or parser.prog, " ".join(summary.split()), _usage(parser), parser.description or "",
                   parser.epilog or "", raw, options, subcommands)


def _text_nodes(text: str, raw: bool) -> list[nodes.Node]:
    """A description or epilog: paragraphs, or (laid out by hand) a literal block."""
    if not text.strip():
        return []
    if raw and "\n  " in text:
        return [text_block(text.rstrip())]
    return [nodes.paragraph(" ".join(p.split()), " ".join(p.split())) for p in re.split(r"\n\s*\n", text)
            if p.strip()]


def _option_item(option: Option) -> nodes.definition_list_item:
    item = nodes.definition_list_item()
    term = nodes.term()
    labels = [option.metavar] if option.positional else [f"{f} {option.metavar}".strip() for f in option.flags]
    for i, label in enumerate(labels):
        if i:
            term += nodes.Text(", ")
        term += literal(label)
    item += term
    definition = nodes.definition()
    if option.help:
        definition += nodes.paragraph(option.help, option.help)
    facts = []
    if option.positional and not option.required:
        facts.append("optional")
    elif option.required and not option.positional:
        facts.append("required")
    if option.repeatable:
        facts.append("repeatable")
    if facts or option.default is not None or option.choices:
        line = para()
        if facts:
            line += nodes.emphasis(", ".join(facts).capitalize() + ".", ", ".join(facts).capitalize() + ".")
        if option.choices:
            line += nodes.Text((" " if facts else "") + "Choices: ")
            for i, choice in enumerate(option.choices):
                line += nodes.Text(", " if i else "")
                line += literal(choice)
            line += nodes.Text(".")
        if option.default is not None:
            line += nodes.Text((" " if facts or option.choices else "") + "Default: ")
            line += literal(option.default)
            line += nodes.Text(".")
        definition += line
    item += definition
    return item


def _command_section(command: Command) -> nodes.section:
    sec = section(command.name)
    if command.summary:
        sec += para(nodes.emphasis(command.summary, command.summary))
    sec += text_block(command.usage)
    sec.extend(_text_nodes(command.description, command.raw_text))
    positionals = [o for o in command.options if o.positional]
    optionals = [o for o in command.options if not o.positional]
    for title, group in (("Arguments", positionals), ("Options", optionals)):
        if group:
            sec += para(nodes.strong(title, title))
            items = nodes.definition_list(classes=["camsim-options"])
            for option in group:
                items += _option_item(option)
            sec += items
    sec.extend(_text_nodes(command.epilog, command.raw_text))
    return sec


def cli_nodes(parser: argparse.ArgumentParser | None = None) -> list[nodes.Node]:
    """The command reference: ``camsim``'s own options, a table of its commands, then one section per command."""
    root = commands_of(parser or build_parser())
    out: list[nodes.Node] = [text_block(root.usage)]
    out.extend(_text_nodes(root.description, root.raw_text))
    rows = [[[nodes.reference("", "", literal(c.name), refid=_slug(c.name))], c.summary] for c in root.subcommands]
    out.append(table(["Command", "What it does"], rows, [2, 7]))
    items = nodes.definition_list(classes=["camsim-options"])
    for option in root.options:
        items += _option_item(option)
    out += [para(nodes.strong("Options of camsim itself", "Options of camsim itself")), items]
    out.extend(_command_section(c) for c in root.subcommands)
    return out


# -------------------------------------------------------------------------------------------------------------------
# Declared parameters (camsim.core.schema.Param)
# -------------------------------------------------------------------------------------------------------------------


def toml_value(value) -> str:
    """A value as a scene file writes it."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) and abs(value) < 1e16 else f"{value:g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return str(value)


def type_text(p) -> str:
    kinds = {"float": "number", "int": "integer", "bool": "boolean", "str": "string",
             "rgb": "number or [R, G, B]"}
    text = kinds.get(p.kind, p.kind)
    return text + " or none" if p.optional else text


def bounds_text(p) -> str:
    parts = []
    if p.low is not None:
        parts.append(f"≥ {p.low:g}")
    if p.above is not None:
        parts.append(f"> {p.above:g}")
    if p.below is not None:
        parts.append(f"< {p.below:g}")
    if p.high is not None:
        parts.append(f"≤ {p.high:g}")
    return ", ".join(parts)


def _description(p) -> list:
    cells: list = [p.doc]  # as the help texts give it (not capitalised: it may start with a symbol, σ_read)
    if p.choices:
        cells.append("; one of " if p.doc else "One of ")
        choices = list(p.choices) + (["none"] if p.optional and "none" not in p.choices else [])
        for i, choice in enumerate(choices):
            cells.append(", " if i else "")
            cells.append(literal(str(choice)))
        cells.append(".")
    if p.stage:
        cells.append("; a stage switch (off with --disable NAME)" if p.doc else "A stage switch")
    return cells


def param_table(params, extra_rows: list | None = None, defaults: bool = True) -> nodes.table:
    """One row per declared parameter: key, type, unit, default (unless not ``defaults``), bounds, description."""
    rows = [list(r) for r in (extra_rows or [])]
    for p in params:
        rows.append([[literal(p.name)], type_text(p), p.unit, [literal(toml_value(p.default))], bounds_text(p),
                     _description(p)])
    headers, widths = ["Key", "Type", "Unit", "Default", "Bounds", "Description"], [3, 2, 1, 2, 1, 8]
    if not defaults:
        for row in (headers, widths, *rows):
            del row[3]
    return table(headers, rows, widths, classes=["camsim-keys"])


def _key_list(keys) -> nodes.paragraph:
    out = para()
    for i, key in enumerate(sorted(keys)):
        out += nodes.Text(", " if i else "")
        out += literal(key)
    return out


def _attribute_docs(cls) -> dict[str, str]:
    """``name → description`` from a class's numpydoc ``Attributes`` section."""
    doc = (cls.__doc__ or "").expandtabs()
    match = re.search(r"^\s*Attributes\n\s*-+\n(.*?)(?:\n\s*\n\s*\w[^\n]*\n\s*-+\n|\Z)", doc, re.S | re.M)
    if not match:
        return {}
    out, name = {}, None
    lines = match.group(1).splitlines()
    indent = min((len(line) - len(line.lstrip()) for line in lines if line.strip()), default=0)
    for line in lines:
        if not line.strip():
            continue
        if len(line) - len(line.lstrip()) == indent:
            name = line.strip().split(" :")[0].split(":")[0].strip()
            out[name] = ""
        elif name:
            out[name] = (out[name] + " " + line.strip()).strip()
    return out


def scene_key_nodes() -> list[nodes.Node]:
    """The scene file's reference: its tables, then [sensor], [render], the scene sources, [camera.scale] and
    [[region]]."""
    scene = scene_module()
    sensor = sensor_module()
    SOURCES = scene.SOURCES  # the registry of scene sources, as the scene reader has it (wherever it is defined)

    frame_params = {p.name: p for p in scene.FRAME_PARAMS}
    out: list[nodes.Node] = []

    sec = section("Tables of a scene file", "scene-file-tables")
    sec += para("A scene file may have these top-level keys and tables (any other is an error): ")
    sec += _key_list(scene._TOP_KEYS)
    sec += para("It has exactly one scene-source table: ", *_joined(sorted(SOURCES), "[{}]", " or "), ".")
    out.append(sec)

    sec = section("[sensor]", "sensor-table")
    sec += para("The sensor: a preset and the parameters that override it. ", literal("preset"), " and ",
                literal("iso"), " pick the preset; every other key is a sensor parameter, also settable on the "
                "command line as ", literal("--sensor NAME=VALUE"), " and in a dataset spec.")
    preset_row = [[literal("preset")], "string", "", [literal(toml_value(frame_params["preset"].default))], "",
                  _description(frame_params["preset"])]
    iso = frame_params["iso"]
    iso_row = [[literal("iso")], type_text(iso), iso.unit, [literal(toml_value(iso.default))], bounds_text(iso),
               _description(iso)]
    sec += param_table(sensor.SENSOR_PARAMS, [preset_row, iso_row])
    out.append(sec)

    sec = section("[render]", "render-table")
    sec += para("How the frames are drawn; each has a ", literal("camsim render"), " option that overrides it.")
    sec += param_table(scene.RENDER_PARAMS)
    out.append(sec)

    sec = section("Scene sources", "scene-source-tables")
    sec += para("The keys each scene-source table may hold (any other is an error):")
    rows = [[[literal(f"[{name}]")], [_key_list(cls.keys)], (cls.__doc__ or "").strip().splitlines()[0]]
            for name, cls in sorted(SOURCES.items())]
    sec += table(["Table", "Keys", "Source"], rows, [1, 5, 4])
    out.append(sec)

    sec = section("[camera.scale]", "camera-scale-table")
    sec += para("The absolute scale of the camera's quantum efficiency, one of two kinds (", literal("kind"),
                " = ", *_joined(scale_classes(), '"{}"', " or "), "; default ", literal('"anchor"'), ").")
    for kind, cls in scale_classes().items():
        docs = _attribute_docs(cls)
        rows = [[[literal(f.name)], [literal(toml_value(f.default))], docs.get(f.name, "")]
                for f in dataclasses.fields(cls)]
        sub = section(f'kind = "{kind}"', f"camera-scale-{kind}")
        sub += para((cls.__doc__ or "").strip().split("\n\n")[0].replace("\n", " "))
        sub += table(["Key", "Default", "Description"], rows, [3, 2, 8])
        sec += sub
    out.append(sec)

    region_keys = _module_of(scene.Region).REGION_KEYS  # the scene reader's Region, wherever it is defined
    if region_keys:
        sec = section("[[region]]", "region-table")
        sec += para("Named rectangles that become the frame's patches, for a source without patches of its own; "
                    "each ", literal("[[region]]"), " has the keys ", *_joined(sorted(region_keys), "{}", " and ",
                                                                               code=True), ".")
        out.append(sec)

    sequence_module = sys.modules.get("camsim.scene.sequence") or importlib.import_module("camsim.scene.sequence")
    from camsim.core.schema import params_of

    seq_cls = sequence_module.SequenceParams
    sec = section("[sequence]", "sequence-table")
    sec += para("Frames of the scene with camera motion (", literal("camsim.scene.sequence"), "): ",
                (sequence_module.__doc__ or "").strip().split("\n\n")[0].replace("\n", " "))
    docs = _attribute_docs(seq_cls)
    extra = [[[literal("pan_px_per_s")], "list of 2 numbers", "px/s", [literal("[0.0, 0.0]")], "",
              "constant pan: " + docs.get("pan_px_per_s", "(vx, vy)")],
             [[literal("homographies")], "list of 3×3 matrices", "", [literal("none")], "one per frame",
              "one 3 × 3 homography (reference pixel → sensor pixel) per frame, constant over its exposure"]]
    params = params_of(seq_cls)
    sec += param_table(params, extra)
    out.append(sec)

    optics_module = sys.modules.get("camsim.optics.params") or importlib.import_module("camsim.optics.params")
    sec = section("[optics]", "optics-table")
    sec += para("The lens in front of the sensor (", literal("camsim.optics"), "), applied to the expected electrons "
                "before the noise is drawn; also settable on the command line as ", literal("--optics NAME=VALUE"),
                ". Each stage is switchable: diffraction of a circular pupil per wavelength, defocus (",
                literal("defocus_waves"), " or ", literal("defocus_um"), "; Hopkins's exact OTF), the 4-spot "
                "optical low-pass filter, the pixel aperture (relative to the source's full-pixel sampling: none at "
                "fill_factor = 1), vignetting (cos⁴ or a table) and lateral chromatic "
                "aberration. The frame's sidecar records the table as ", literal("optics"), " with each channel's ",
                literal("channel_wavelength_weights"), ", the ", literal("otf_model"), " applied and the electrons "
                "the clip of the expectation at 0 added (", literal("negative_clipped_e"), ", ",
                literal("negative_clipped_fraction"), ").")
    extra = [[[literal("relative_illumination")], "list of [angle, value] pairs", "deg, —", [literal("none")],
              "angles from 0, increasing; values > 0",
              "with vignetting = \"table\": the relative illumination at each field angle, taken relative to the "
              "value at 0° and interpolated linearly in the angle"]]
    sec += param_table(optics_module.OPTICS_PARAMS, extra)
    out.append(sec)
    return out


def _joined(items, fmt: str, last: str, code: bool = True) -> list:
    items = [fmt.format(i) for i in items]
    parts: list = []
    for i, item in enumerate(items):
        if i:
            parts.append(last if i == len(items) - 1 else ", ")
        parts.append(literal(item) if code else item)
    return parts


def dataset_key_nodes() -> list[nodes.Node]:
    """The dataset spec's reference: its tables and keys, then every parameter a frame may vary."""
    spec, parts, raws = spec_module(), spec_parts_module(), raws_module()
    out: list[nodes.Node] = []

    sec = section("Tables and keys of a spec", "spec-tables")
    sec += para("A dataset spec may have these top-level keys and tables (any other is an error): ")
    sec += _key_list(spec._TOP_KEYS)
    rows = [[[literal("[images]")], [_key_list(spec.IMAGES_TABLE_KEYS)]],
            [[literal("[raws]")], [_key_list(raws.RAWS_TABLE_KEYS)]],
            [[literal("[virtual_camera]")], [_key_list(parts.VIRTUAL_CAMERA_TABLE_KEYS)]],
            [[literal("[random]")], [para(literal("count"), nodes.Text(" (draws per grid point), and per parameter "
                                                                       "one distribution, "),
                                          literal("{ NAME = [...] }"), nodes.Text(" with NAME one of "),
                                          *_joined(parts.DISTRIBUTIONS, "{}", " or "))]]]
    sec += table(["Table", "Keys"], rows, [1, 4])
    aliases = []
    for plural, single in parts.GRID_ALIASES.items():
        aliases += [", " if aliases else "", literal(plural), f" (for {single})"]
    sec += para("Plural spellings accepted in ", literal("[grid]"), ": ", *aliases, ".")
    out.append(sec)

    sec = section("Parameters", "spec-parameters")
    sec += para("Each may be set in ", literal("[fixed]"), ", ", literal("[grid]"), " (a list) or ",
                literal("[random]"), " (a distribution), at most one of them; a parameter the spec does not set "
                "keeps the scene file's value.")
    sec += param_table(parts.PARAMETERS.values())
    out.append(sec)
    return out


# -------------------------------------------------------------------------------------------------------------------
# The sidecar
# -------------------------------------------------------------------------------------------------------------------

_PROBES = (object(), "x", True, -1e30, -0.5, 0, 1e30, [0.0], [[0.0]])


def sidecar_requirements(check) -> tuple[list[str], bool]:
    """What ``check`` (a :data:`FRAME_KEYS` entry) refuses, in its own words, and whether it takes null: the
    checker is probed with values of the wrong type, sign and size, and its messages collected."""
    bad = sidecar_module()._Bad
    messages: list[str] = []
    for probe in _PROBES:
        try:
            check(probe)
        except bad as exc:
            text = str(exc.args[0])
            if text not in messages:
                messages.append(text)
        except Exception:  # noqa: BLE001 - a probe a check cannot take at all says nothing about it
            continue
    try:
        check(None)
        nullable = True
    except Exception:  # noqa: BLE001
        nullable = False
    return messages, nullable


def text_allows_null(messages: list[str]) -> bool:
    return any(m.startswith("null") for m in messages)


def sidecar_key_nodes() -> list[nodes.Node]:
    """The sidecar's keys: the frame's own (:data:`FRAME_KEYS`) and the sensor's (its declared parameters)."""
    schema = sidecar_module()
    sensor = sensor_module()
    required = set(schema.REQUIRED)
    out: list[nodes.Node] = []

    sec = section("Required keys", "sidecar-required")
    sec += para("A sidecar without one of these is not a camsim frame's: ")
    sec += _key_list(schema.REQUIRED)
    out.append(sec)

    sec = section("The frame's keys", "sidecar-frame-keys")
    sec += para("Checked when present (older sidecars lack some). The requirement is what the checker "
                "accepts: a value it refuses is an error naming the key.")
    rows = []
    for key, check in schema.FRAME_KEYS.items():
        messages, nullable = sidecar_requirements(check)
        text = "; ".join(messages) + ("; or null" if nullable and not text_allows_null(messages) else "")
        rows.append([[literal(key)], "yes" if key in required else "", text])
    sec += table(["Key", "Required", "Must be"], rows, [3, 1, 8])
    out.append(sec)

    sec = section("The sensor's keys", "sidecar-sensor-keys")
    sec += para("The sensor's parameters, checked against their declaration (the same as in a scene file's ",
                literal("[sensor]"), " table); a stage switch is under ", literal("stages"), ".")
    skipped = {p.name for p in sensor.SENSOR_PARAMS if p.stage or (p.sidecar is not None and p.name != "bits")}
    params = [p for p in sensor.SENSOR_PARAMS if p.name not in skipped]
    sec += param_table(params, defaults=False)
    stages = [p.name for p in sensor.SENSOR_PARAMS if p.stage]
    sec += para(literal("stages"), " holds the stage switches ", *_joined(stages, "{}", " and "),
                ", each true or false.")
    out.append(sec)

    # keys a sensor parameter writes under names of its own (cfa → sensor_layout, cfa_pattern), not in FRAME_KEYS
    default = sensor.SensorParams()
    shown = set(schema.FRAME_KEYS) | {p.name for p in params}
    rows = []
    for p in sensor.SENSOR_PARAMS:
        if p.stage or p.sidecar is None:
            continue
        for key in p.record(default):
            if key not in shown:
                rows.append([[literal(key)], [literal(p.name)], type_text(p), bounds_text(p), _description(p)])
    if rows:
        sec += para("Keys that a sensor parameter writes under a name of its own (null where it does not apply):")
        sec += table(["Key", "Parameter", "Type", "Bounds", "Description"], rows, [3, 3, 2, 1, 8])
    others = [k for k in schema.REQUIRED if k not in schema.FRAME_KEYS
              and k not in {p.name for p in sensor.SENSOR_PARAMS}]
    if others:
        sec = section("Checked on their own", "sidecar-other-keys")
        sec += para("Required keys with checks of their own (their shape depends on other keys): ",
                    *_joined(others, "{}", " and "), ".")
        out.append(sec)
    return out


# -------------------------------------------------------------------------------------------------------------------
# Sphinx
# -------------------------------------------------------------------------------------------------------------------


class _Generated(Directive):
    has_content = False
    required_arguments = 0
    optional_arguments = 0
    make = staticmethod(lambda: [])

    def run(self):
        try:
            return list(type(self).make())
        except Exception as exc:  # noqa: BLE001 - a generator that fails is a build error, not a traceback
            raise self.error(f"{self.name}: cannot generate the reference: {type(exc).__name__}: {exc}") from exc


class CliDirective(_Generated):
    make = staticmethod(cli_nodes)


class SceneKeysDirective(_Generated):
    make = staticmethod(scene_key_nodes)


class DatasetKeysDirective(_Generated):
    make = staticmethod(dataset_key_nodes)


class SidecarKeysDirective(_Generated):
    make = staticmethod(sidecar_key_nodes)


def _exported_data_doc(app, what, name, obj, options, lines):
    """The doc-comment (``#:``) of a public data name (``camsim.PRESETS``), from the module that defines it.

    autodoc looks for it in ``camsim/__init__.py``, which only re-exports the name, finds none and falls back on
    the docstring of the value's type (``dict``'s)."""
    package, _, attr = name.rpartition(".")
    if what != "data" or package != "camsim":
        return
    from sphinx.pycode import ModuleAnalyzer

    import camsim

    module = getattr(camsim, "_EXPORTS", {}).get(attr)
    if module is None:
        return
    try:
        docs = ModuleAnalyzer.for_module(module).find_attr_docs()
    except Exception:  # noqa: BLE001 - no source to read: the name keeps autodoc's description
        return
    if ("", attr) in docs:
        lines[:] = list(docs[("", attr)])


#: The pages that use the directives: re-read on every build (their content is the code's, which Sphinx does not
#: watch), so that an incremental build never shows a stale reference.
GENERATED_PAGES = ("reference/cli", "reference/scene-keys", "reference/dataset-keys", "reference/sidecar-keys")


def _always_outdated(app, env, added, changed, removed):
    return [doc for doc in GENERATED_PAGES if doc in env.found_docs and doc not in added | changed]


def _numpydoc_warnings_are_sphinx_warnings() -> None:
    """numpydoc reports a malformed docstring (an unknown section, a bad parameter list) with Python's
    ``warnings.warn``, which Sphinx's ``-W`` does not see: route those to Sphinx's log as warnings, so that they
    fail the build like any other."""
    from sphinx.util import logging

    logger = logging.getLogger("camsim_reference")
    shown = warnings.showwarning
    if getattr(shown, "camsim_numpydoc", False):
        return

    def show(message, category, filename, lineno, file=None, line=None):
        if "numpydoc" in str(filename).replace("\\", "/").split("/"):
            logger.warning("numpydoc: %s", message, type="numpydoc")
        else:
            shown(message, category, filename, lineno, file, line)

    show.camsim_numpydoc = True
    warnings.showwarning = show


def setup(app):
    _numpydoc_warnings_are_sphinx_warnings()
    app.add_directive("camsim-cli", CliDirective)
    app.add_directive("camsim-scene-keys", SceneKeysDirective)
    app.add_directive("camsim-dataset-keys", DatasetKeysDirective)
    app.add_directive("camsim-sidecar-keys", SidecarKeysDirective)
    app.connect("env-get-outdated", _always_outdated)
    app.connect("autodoc-process-docstring", _exported_data_doc)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
