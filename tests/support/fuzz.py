"""Hostile-input fuzzing of the ``camsim`` command line (issue 24): seed files, Hypothesis mutators, a case runner.

The suite (``tests/cli/test_fuzz.py``) and the long run (``tools/fuzz_cli.py``) share this module.

Seeds
    :func:`build_seeds` renders tiny frames once (a 48 × 32 ColorChecker: DNG, EXR, sidecar JSON) and prepares the
    other seed inputs: the built-in scene files and the built-in dataset spec ``denoise_small`` shrunk to one tiny
    frame, a camera preset file, a 48 × 32 PNG (written here, chunk by chunk, so that header edits keep valid CRCs)
    and a ``.npy`` reflectance cube.
Mutators
    Hypothesis strategies (:func:`case_strategy`) edit a seed structurally: TOML and JSON trees (delete a key,
    replace a value by another type or an extreme number, add a key, nest 3 000 deep, path-like names), binary
    files (byte flips, truncations, DNG tag entries, PNG IHDR fields, EXR header attributes, the ``.npy`` header's
    shape and dtype), so that a failure shrinks to a small edit. A :class:`Case` is the files of one run and its
    ``argv``; ``{IN}``, ``{OUT}`` and ``{ROOT}`` in them stand for the case's input folder, output folder and
    scratch folder.
Runner
    :func:`run_case` runs ``camsim.cli.main(argv)`` in a forked copy of the calling process (camsim already
    imported and warmed up: a case costs milliseconds more than an in-process call, not a new interpreter) in its
    own process group, with ``RLIMIT_AS`` (address space) and ``RLIMIT_CPU`` (CPU time: a case that computes too
    long is killed by the kernel, however busy the machine), and its file descriptors 1 and 2 sent to files, so that
    what C libraries print (``libpng error: ...``) is seen too. A case that makes no progress at all (no CPU time,
    nothing runnable) for as long as its CPU limit is blocked: a hang too. Wall-clock time only backstops: a case
    still working after :data:`BACKSTOP_FACTOR` times its CPU limit is ``busy`` (the machine was too busy to judge
    it), not a finding.
    It classifies the run (:data:`OUTCOMES`): every file under the case's scratch folder outside ``{OUT}`` is
    compared before and after (and in its parent folder), and no ``*.partial`` may remain anywhere in it.

Outside the scratch folder nothing is generated: the absolute paths the mutators write are ``{ROOT}/...`` and the
relative ones climb at most 4 folders from ``{OUT}`` (which is ``{ROOT}/a/b/c/out``), so an escape lands inside
``{ROOT}``, where it is seen (and harms nothing, even run as root).
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
import os
import resource
import shutil
import signal
import struct
import sys
import time
import tomllib
import traceback
import zlib
from pathlib import Path

from hypothesis import strategies as st

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "camsim" / "scenes"

#: What a case can come to, worst first (a case gets the first that applies; :func:`classify`).
#: ``busy`` is no finding: the case was still working at the wall-clock backstop (the machine was too busy to judge).
OUTCOMES = ("hang", "crash", "memory", "traceback", "outside", "partial", "multiline", "bad_exit", "refused", "ok",
            "busy")
#: The outcomes that meet the issue's standard: exit 0, or exit 2 with one ``camsim: error:`` line.
GOOD = ("ok", "refused")
#: A case's wall-clock backstop is this many times its CPU-time limit. Unit: 1.
BACKSTOP_FACTOR = 20
#: Every kind of case, in the order the totals list them.
KINDS = ("scene", "spec", "sidecar", "preset", "dng", "exr", "png", "cube", "raw")

#: Size of the seed frames (pixels) and of the frames the mutated scenes render.
SEED_SIZE = (48, 32)
TINY = [24, 22]


# --------------------------------------------------------------------------------------------------------------
# Serialising mutated trees: TOML (inline tables, which tomllib reads as tables) and JSON (NaN/Infinity allowed)
# --------------------------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Raw:
    """Text written verbatim into a TOML or JSON file where a value goes (a 5 000-digit integer, 3 000 brackets)."""

    text: str

    def __repr__(self):
        return f"Raw({self.text[:24]!r}{'...' if len(self.text) > 24 else ''} len={len(self.text)})"


def nested(depth: int, brackets: str = "[]") -> Raw:
    """``depth`` nested empty lists (or ``{"a": {...}}`` objects with ``brackets="{}"``), as text."""
    if brackets == "{}":
        return Raw('{"a": ' * depth + "{}" + "}" * depth)
    return Raw("[" * depth + "]" * depth)


def _toml_key(key: str) -> str:
    return json.dumps(key, ensure_ascii=True)


def toml_value(value) -> str:
    """``value`` as an inline TOML value (strings JSON-escaped, which TOML's basic strings share)."""
    if isinstance(value, Raw):
        return value.text
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return repr(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=True)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_key(str(k))} = {toml_value(v)}" for k, v in value.items()) + "}"
    if value is None:  # TOML has no null: the closest hostile thing is an empty string
        return '""'
    raise TypeError(type(value))


def to_toml(doc: dict) -> str:
    """A TOML document: one ``key = inline value`` line per top-level key."""
    return "".join(f"{_toml_key(str(k))} = {toml_value(v)}\n" for k, v in doc.items())


def to_json(doc) -> str:
    """A JSON document, with :class:`Raw` values spliced in verbatim and NaN/Infinity as Python writes them."""
    raws: list[str] = []

    def swap(value):
        if isinstance(value, Raw):
            raws.append(value.text)
            return f"\x00RAW{len(raws) - 1}\x00"
        if isinstance(value, dict):
            return {str(k): swap(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [swap(v) for v in value]
        return value

    text = json.dumps(swap(doc), indent=1)
    for i, raw in enumerate(raws):
        text = text.replace(json.dumps(f"\x00RAW{i}\x00"), raw)
    return text


# --------------------------------------------------------------------------------------------------------------
# Tree mutators
# --------------------------------------------------------------------------------------------------------------

#: Path-like names (issue 24, point 1). ``{ROOT}`` is the case's scratch folder; ``..`` climbs at most 4 levels.
PATH_NAMES = ("../x", "../../escaped", "../../../../deep", "{ROOT}/abs/victim", "..", ".", "a\nb", "a/b", "",
              " ", "-x", "x" * 300, "nul\x00byte", "é ü", "{ROOT}", "./../x")

#: Extreme numbers and other values of the wrong type (issue 24, points 2 and 5).
EXTREMES = (0, -1, 1, 0.0, -0.0, 1e308, -1e308, 1e-320, float("nan"), float("inf"), float("-inf"), 2**63, -2**63,
            2**64, 2**40, 9223372036854775807, Raw("1" + "0" * 5000), True, False, "", "1", "nan", [], [[]], {},
            [1, 2, 3], [0, 1e308], {"uniform": [0, 1e308]}, None)

_SAFE_TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="/\\"), max_size=12)

#: Any hostile value: an extreme, a path-like name, a small random number or text, or deep nesting.
hostile_values = st.one_of(
    st.sampled_from(EXTREMES),
    st.sampled_from(PATH_NAMES),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    _SAFE_TEXT,
    st.lists(st.one_of(st.integers(-5, 5), st.floats(-1e3, 1e3)), max_size=4),
    st.sampled_from((nested(100), nested(3000), nested(3000, "{}"))),
)


def tree_paths(doc, prefix=()) -> list[tuple]:
    """Every path (keys and list indices) to a value inside ``doc``, parents before children."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for key, value in items:
        out.append((*prefix, key))
        out.extend(tree_paths(value, (*prefix, key)))
    return out


def _parent(doc, path):
    for key in path[:-1]:
        doc = doc[key]
    return doc


def apply_tree_ops(doc, ops):
    """A deep copy of ``doc`` with ``ops`` applied in turn (an op whose path no longer exists is skipped).

    Ops: ``("delete", path)``, ``("set", path, value)``, ``("add", path, key, value)`` (a new key in the table at
    ``path``, or the top level for ``()``).
    """
    doc = json.loads(json.dumps(doc, default=repr))  # a deep copy (seeds hold only JSON types)
    for op in ops:
        try:
            if op[0] == "delete":
                parent = _parent(doc, op[1])
                del parent[op[1][-1]]
            elif op[0] == "set":
                _parent(doc, op[1])[op[1][-1]] = op[2]
            elif op[0] == "add":
                table = doc
                for key in op[1]:
                    table = table[key]
                if isinstance(table, dict):
                    table[op[2]] = op[3]
                elif isinstance(table, list):
                    table.append(op[3])
        except (KeyError, IndexError, TypeError):
            continue
    return doc


def tree_ops(doc, values=hostile_values, keys=None, max_ops=3):
    """A strategy for 1 to ``max_ops`` edits of ``doc``; ``keys`` restricts the edited paths to those ending in one
    of them (e.g. the name keys), ``values`` the values written."""
    paths = [p for p in tree_paths(doc) if keys is None or p[-1] in keys]
    tables = [()] + [p for p in tree_paths(doc) if isinstance(_get(doc, p), (dict, list))]
    ops = [st.tuples(st.just("set"), st.sampled_from(paths), values)]
    if keys is None:
        ops += [st.tuples(st.just("delete"), st.sampled_from(paths)),
                st.tuples(st.just("add"), st.sampled_from(tables), st.sampled_from(("extra", "name", "path", "x")),
                          values)]
    return st.lists(st.one_of(*ops), min_size=1, max_size=max_ops)


def _get(doc, path):
    for key in path:
        doc = doc[key]
    return doc


# --------------------------------------------------------------------------------------------------------------
# Binary mutators
# --------------------------------------------------------------------------------------------------------------

U32_EXTREMES = (0, 1, 2, 3, 7, 255, 65535, 30000, 2**31 - 1, 2**31, 2**32 - 1)


def byte_ops(max_ops=3):
    """A strategy for byte flips, overwrites and truncations; offsets are fractions of the file's length."""
    where = st.floats(min_value=0.0, max_value=1.0, allow_nan=False)
    return st.lists(st.one_of(
        st.tuples(st.just("flip"), where, st.integers(1, 255)),
        st.tuples(st.just("u32"), where, st.sampled_from(U32_EXTREMES)),
        st.tuples(st.just("truncate"), where),
        st.tuples(st.just("zero"), where, st.integers(1, 4096)),
    ), min_size=1, max_size=max_ops)


def apply_byte_ops(data: bytes, ops) -> bytes:
    """``data`` with the byte ops of :func:`byte_ops` applied in turn."""
    buf = bytearray(data)
    for op in ops:
        if not buf:
            break
        at = min(int(op[1] * len(buf)), len(buf) - 1)
        if op[0] == "flip":
            buf[at] ^= op[2]
        elif op[0] == "u32":
            at = min(at, max(len(buf) - 4, 0))
            buf[at:at + 4] = struct.pack("<I", op[2])[: len(buf) - at]
        elif op[0] == "truncate":
            del buf[at:]
        elif op[0] == "zero":
            buf[at:at + op[2]] = bytes(len(buf[at:at + op[2]]))
    return bytes(buf)


def tiff_entries(data: bytes) -> list[tuple[int, int]]:
    """(file offset, tag) of every entry of a little-endian TIFF's first IFD and of its SubIFDs (tag 330)."""
    if data[:2] != b"II":
        return []
    entries, queue, seen = [], [struct.unpack_from("<I", data, 4)[0]], set()
    while queue:
        ifd = queue.pop()
        if ifd in seen or ifd + 2 > len(data):
            continue
        seen.add(ifd)
        count = struct.unpack_from("<H", data, ifd)[0]
        for i in range(count):
            at = ifd + 2 + 12 * i
            tag, kind, n = struct.unpack_from("<HHI", data, at)
            entries.append((at, tag))
            if tag == 330:  # SubIFDs: LONG offsets, inline when one
                offsets = [struct.unpack_from("<I", data, at + 8)[0]] if n == 1 else \
                    list(struct.unpack_from(f"<{n}I", data, struct.unpack_from("<I", data, at + 8)[0]))
                queue.extend(offsets)
    return entries


def dng_ops(entries):
    """A strategy for edits of DNG tag entries: its type, count or value field set to an extreme (Compression = 7,
    JPEG, over uncompressed data among them), then perhaps byte ops."""
    tag_edit = st.tuples(st.just("tag"), st.sampled_from(entries), st.sampled_from(("type", "count", "value")),
                         st.sampled_from(U32_EXTREMES + (6, 7, 8, 34892, 32803)))
    return st.lists(st.one_of(tag_edit, byte_ops(1).map(lambda ops: ops[0])), min_size=1, max_size=3)


def apply_dng_ops(data: bytes, ops) -> bytes:
    """``data`` with the ops of :func:`dng_ops` applied in turn."""
    buf = bytearray(data)
    for op in ops:
        if op[0] != "tag":
            buf = bytearray(apply_byte_ops(bytes(buf), [op]))
            continue
        (at, _), field, value = op[1], op[2], op[3]  # (offset of the entry, its tag code)
        if at + 12 > len(buf):
            continue
        kind = struct.unpack_from("<H", buf, at + 2)[0]
        if field == "type":
            struct.pack_into("<H", buf, at + 2, value & 0xFFFF)
        elif field == "count":
            struct.pack_into("<I", buf, at + 4, value)
        elif kind == 3:  # SHORT inline
            struct.pack_into("<H", buf, at + 8, value & 0xFFFF)
        else:
            struct.pack_into("<I", buf, at + 8, value)
    return bytes(buf)


def png_bytes(width: int, height: int, rows: bytes | None = None, *, bit_depth=8, colour_type=2,
              idat: bytes | None = None) -> bytes:
    """A PNG file, chunk by chunk (CRCs right): ``rows`` the filtered scanlines (default: a gradient)."""
    def chunk(name, body):
        return struct.pack(">I", len(body)) + name + body + struct.pack(">I", zlib.crc32(name + body))

    if idat is None:
        if rows is None:
            rows = b"".join(b"\0" + bytes((x * 5 + y * 7 + c * 60) & 255 for x in range(width) for c in range(3))
                            for y in range(height))
        idat = zlib.compress(rows, 9)
    ihdr = struct.pack(">IIBBBBB", width, height, bit_depth, colour_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def png_bomb(width: int = 15000, height: int = 15000) -> bytes:
    """A decompression bomb: a valid RGB PNG of ``width`` × ``height`` black pixels (225 MP, 675 MB decoded, about
    0.7 MB on disk), compressed row by row."""
    packer = zlib.compressobj(9)
    row = bytes(1 + 3 * width)
    idat = b"".join(packer.compress(row) for _ in range(height)) + packer.flush()
    return png_bytes(width, height, idat=idat)


def png_ops():
    """A strategy for PNG edits: IHDR fields (CRC kept right, so the decoder believes them), the bomb, byte ops."""
    size = st.sampled_from((0, 1, 24, 2**15, 30000, 2**31 - 1, 2**32 - 1))
    ihdr = st.tuples(st.just("ihdr"), size, size, st.sampled_from((1, 8, 16, 3, 0)),
                     st.sampled_from((0, 2, 3, 4, 6, 7)))
    return st.lists(st.one_of(ihdr, st.just(("bomb",)), byte_ops(1).map(lambda ops: ops[0])), min_size=1, max_size=2)


def apply_png_ops(data: bytes, ops, bomb: bytes) -> bytes:
    """``data`` with the ops of :func:`png_ops` applied in turn (``bomb``: the bytes a ``("bomb",)`` op puts)."""
    for op in ops:
        if op[0] == "bomb":
            data = bomb
        elif op[0] == "ihdr" and len(data) >= 33:
            body = struct.pack(">IIBBBBB", op[1], op[2], op[3], op[4], 0, 0, 0)
            data = data[:16] + body + struct.pack(">I", zlib.crc32(b"IHDR" + body)) + data[33:]
        else:
            data = apply_byte_ops(data, [op])
    return data


def exr_attributes(data: bytes) -> dict[str, tuple[int, int]]:
    """Name → (offset, size) of the value of each attribute of a single-part EXR header."""
    out, at = {}, 8
    while at < len(data) and data[at] != 0:
        name_end = data.index(b"\0", at)
        type_end = data.index(b"\0", name_end + 1)
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        out[data[at:name_end].decode("latin-1")] = (type_end + 5, size)
        at = type_end + 5 + size
    out["__offsets__"] = (at + 1, 8)  # the first line-offset table entry
    return out


def exr_ops(attributes):
    """A strategy for EXR edits: an int32 inside an attribute's value (dataWindow, displayWindow, channels,
    compression, the line-offset table) set to an extreme, then perhaps byte ops."""
    names = sorted(attributes)
    edit = st.tuples(st.just("attr"), st.sampled_from(names), st.integers(0, 3),
                     st.sampled_from((0, -1, 1, 2**31 - 1, -(2**31), 30000, 9, 255)))
    return st.lists(st.one_of(edit, byte_ops(1).map(lambda ops: ops[0])), min_size=1, max_size=3)


def apply_exr_ops(data: bytes, ops, attributes) -> bytes:
    """``data`` with the ops of :func:`exr_ops` applied in turn (``attributes``: :func:`exr_attributes` of it)."""
    buf = bytearray(data)
    for op in ops:
        if op[0] != "attr":
            buf = bytearray(apply_byte_ops(bytes(buf), [op]))
            continue
        at, size = attributes[op[1]]
        at += 4 * op[2] if 4 * op[2] + 4 <= size else 0
        if at + 4 <= len(buf):
            if size == 1:
                buf[at] = op[3] & 255
            else:
                struct.pack_into("<i", buf, at, op[3])
    return bytes(buf)


def npy_bytes(header: dict, body: bytes) -> bytes:
    """A ``.npy`` file (format 1.0) with the header dict written as numpy does (``repr``) and ``body`` after it."""
    text = repr(header).encode("latin-1")
    pad = 64 - (10 + len(text) + 1) % 64
    text += b" " * pad + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text + body


def npy_ops():
    """A strategy for ``.npy`` edits: the header's shape and dtype (an object dtype: a pickle), then byte ops."""
    dim = st.sampled_from((0, 1, 22, 24, 101, 2**20, 2**31, 2**40, -1))
    header = st.tuples(st.just("header"), st.tuples(dim, dim, dim) | st.sampled_from(((), (22, 24), (1, 1, 1, 1))),
                       st.sampled_from(("<f8", ">f8", "<f4", "|O", "<c16", "|u1", "<U4", "|V8", "<f8")),
                       st.booleans())
    return st.lists(st.one_of(header, byte_ops(1).map(lambda ops: ops[0])), min_size=1, max_size=2)


def apply_npy_ops(body: bytes, ops) -> bytes:
    """The seed cube's ``.npy`` file with the ``.npy`` ops of :func:`npy_ops` applied (header edits, then bytes)."""
    header = {"descr": "<f8", "fortran_order": False, "shape": (TINY[1], TINY[0], 101)}
    edits = []
    for op in ops:
        if op[0] == "header":
            header = {"descr": op[2], "fortran_order": op[3], "shape": op[1]}
        else:
            edits.append(op)
    data = npy_bytes(header, body)
    return apply_byte_ops(data, edits) if edits else data


# --------------------------------------------------------------------------------------------------------------
# Seeds
# --------------------------------------------------------------------------------------------------------------

PRESET_FILE = {
    "preset": {"name": "fuzz-camera", "source": "camsim fuzz seed", "bits": 12, "pedestal_dn": 256, "cfa": "GRBG",
               "read_noise_model": "gaussian", "full_well_e": 9000.0, "conversion_gain_v_per_e": 0.0001},
    "iso": [{"iso": 200, "k_dn_per_e": 0.2, "tukey_lambda": 0.05, "tukey_scale_dn": 0.9, "gaussian_sigma_dn": 1.2,
             "row_sigma_dn": 0.1},
            {"iso": 800, "k_dn_per_e": 0.8, "tukey_lambda": -0.05, "tukey_scale_dn": 1.5, "gaussian_sigma_dn": 2.4,
             "row_sigma_dn": 0.3, "dsnu_dn": 0.4, "prnu_percent": 0.5}],
}


def shrink_scene(doc: dict) -> dict:
    """A built-in scene cut to one tiny frame: first illuminant, first intensity factor, 24 × 22 pixels."""
    doc = json.loads(json.dumps(doc))
    light = doc.setdefault("light", {})
    light["illuminants"] = light.get("illuminants", ["D65"])[:1]
    light["intensity_factors"] = light.get("intensity_factors", [1.0])[:1]
    if "image" in doc:
        doc["image"]["size"] = list(TINY)
    else:
        doc["frame"] = {"width": TINY[0], "height": TINY[1]}
    return doc


@dataclasses.dataclass
class Seeds:
    """The seed inputs the mutators edit, built once per process by :func:`build_seeds`."""

    folder: Path
    scenes: dict  # name → shrunk scene document
    spec: dict
    preset: dict
    frame: dict  # "dng", "exr", "json" → bytes of one 48 × 32 frame; "stem"
    sidecar: dict
    png: bytes
    cube_body: bytes
    dng_entries: list = dataclasses.field(default_factory=list)
    raw_dng: bytes = b""  # a Bayer DNG of a camera preset (Sony ILCE-7SM2): a [raw] scene's file
    raw_entries: list = dataclasses.field(default_factory=list)
    exr_attributes: dict = dataclasses.field(default_factory=dict)
    _bomb: bytes | None = None

    @property
    def bomb(self) -> bytes:
        """The PNG bomb, made on first use (about a second)."""
        if self._bomb is None:
            path = self.folder / "bomb.png"
            if not path.exists():
                path.write_bytes(png_bomb())
            self._bomb = path.read_bytes()
        return self._bomb


def _quiet_main(argv) -> int:
    from contextlib import redirect_stderr, redirect_stdout

    from camsim.cli import main

    with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()) as err:
        rc = main(argv)
    if rc != 0:
        raise RuntimeError(f"seed run {argv} failed: {err.getvalue()}")
    return rc


def build_seeds(folder: Path) -> Seeds:
    """Render the seed frame and read the seed files into ``folder``; also imports and warms camsim (each command a
    case runs is run once here), so that forked cases start warm."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    frames = folder / "frames"
    if not (frames / "manifest.json").exists():
        _quiet_main(["render", "macbeth_26", "--size", "x".join(map(str, SEED_SIZE)), "--illuminant", "D65",
                     "--intensity", "1", "-q", "--workers", "1", "--out", str(frames)])
    (dng,) = frames.glob("*.dng")
    frame = {"stem": dng.stem, "dng": dng.read_bytes(), "exr": dng.with_suffix(".exr").read_bytes(),
             "json": dng.with_suffix(".json").read_bytes()}
    raws = folder / "raws"
    if not (raws / "manifest.json").exists():
        _quiet_main(["render", "macbeth_26", "--size", "x".join(map(str, SEED_SIZE)), "--illuminant", "D65",
                     "--intensity", "1", "--preset", "sony-a7s2", "--iso", "100", "-q", "--workers", "1",
                     "--out", str(raws)])
    (raw_dng,) = raws.glob("*.dng")
    scenes = {}
    for path in sorted(SCENES.glob("*.toml")):
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
        if "scene" in doc:  # a dataset spec
            continue
        scenes[path.stem] = shrink_scene(doc)
    # a scene with a [sequence] (issue 29): shake, pan, a rolling shutter and a flickering light, 3 frames
    scenes["dead_leaves_sequence"] = {**scenes["dead_leaves"], "sequence": {
        "frames": 3, "frame_interval_s": 0.05, "shake_px": 0.5, "shake_deg": 0.1, "pan_px_per_s": [20.0, -5.0],
        "rolling_shutter_row_s": 0.0005, "flicker_hz": 100.0, "flicker_depth": 0.3}}
    scenes["dead_leaves_sequence"]["sensor"] = {**scenes["dead_leaves"].get("sensor", {}), "exposure_s": 0.01}
    spec = tomllib.loads((SCENES / "denoise_small.toml").read_text(encoding="utf-8"))
    spec.update(repeats=1, scene="macbeth_26.toml")
    spec["images"].update(folder="images", crop=list(TINY))
    spec["grid"] = {"illuminants": ["D65"], "read_noise_model": ["gaussian"]}
    spec["random"]["count"] = 1
    import numpy as np

    cube = np.linspace(0.05, 0.9, TINY[1] * TINY[0] * 101).reshape(TINY[1], TINY[0], 101)
    seeds = Seeds(folder=folder, scenes=scenes, spec=spec, preset=PRESET_FILE, frame=frame,
                  sidecar=json.loads(frame["json"]), png=png_bytes(*SEED_SIZE), cube_body=cube.tobytes())
    seeds.dng_entries = tiff_entries(frame["dng"])
    seeds.raw_dng = raw_dng.read_bytes()
    seeds.raw_entries = tiff_entries(seeds.raw_dng)
    seeds.exr_attributes = exr_attributes(frame["exr"])
    _warm_up(seeds)
    return seeds


def _warm_up(seeds: Seeds) -> None:
    """Run each kind's seed case once in this process (imports, colour-science caches), so forks start warm."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="camsim-fuzz-warm-") as tmp:
        for kind, choice in ((kind, choice) for kind in KINDS for choice in (0, 1)):
            case = make_case(seeds, kind, [], choice)
            root = Path(tmp) / f"{kind}{choice}"
            inp, out = prepare(case, root)
            _quiet_main([a.replace("{IN}", str(inp)).replace("{OUT}", str(out)).replace("{ROOT}", str(root))
                         for a in case.argv])
    quiesce()


def quiesce() -> None:
    """Stop the thread pools this process started (OpenEXR's process-wide pool), so that a fork of it does not wait
    on threads that only the parent has; a case's camsim then runs OpenEXR in its calling thread."""
    import OpenEXR

    if hasattr(OpenEXR, "set_global_thread_count"):
        OpenEXR.set_global_thread_count(0)


# --------------------------------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------------------------------


@dataclasses.dataclass
class Case:
    """One run: the files written into ``{IN}`` (name → bytes or text) and the command line."""

    kind: str
    files: dict
    argv: list
    label: str = ""
    ops: list = dataclasses.field(default_factory=list)

    def __repr__(self):
        sizes = {name: len(body) for name, body in self.files.items()}
        ops = repr(self.ops)
        ops = ops if len(ops) < 400 else ops[:400] + "..."
        return f"Case({self.kind}, {self.label}, ops={ops}, argv={self.argv}, files={sizes})"

    def _repr_pretty_(self, printer, cycle):  # Hypothesis prints a failing case with this
        printer.text(repr(self))


def _frame_files(seeds: Seeds, **replace) -> dict:
    stem = seeds.frame["stem"]
    files = {f"frames/{stem}.{ext}": seeds.frame[ext] for ext in ("dng", "exr", "json")}
    files.update({f"frames/{stem}.{ext}": body for ext, body in replace.items()})
    return files


ANALYZE = ["analyze", "{IN}/frames", "--out", "{OUT}", "-q", "--no-figures", "--border", "1"]
RENDER = ["--out", "{OUT}", "-q", "--workers", "1"]


def scene_argv(name="scene.toml"):
    return ["render", "{IN}/" + name, *RENDER]


def seed_case(seeds: Seeds, kind: str) -> Case:
    """The unmutated case of ``kind`` (it must exit 0)."""
    return make_case(seeds, kind, ops=[], choice=0)


def make_case(seeds: Seeds, kind: str, ops, choice=0, label="") -> Case:
    """The case of ``kind`` with the mutation ``ops`` (as the strategies draw them); ``choice`` picks the seed scene
    (scene) or the command variant (sidecar, exr)."""
    if kind == "scene":
        name = sorted(seeds.scenes)[choice % len(seeds.scenes)]
        doc = apply_tree_ops(seeds.scenes[name], ops)
        return Case(kind, {"scene.toml": to_toml(doc)}, scene_argv(), label or name)
    if kind == "spec":
        doc = apply_tree_ops(seeds.spec, ops)
        files = {"spec.toml": to_toml(doc), "macbeth_26.toml": to_toml(seeds.scenes["macbeth_26"]),
                 "images/tiny.png": seeds.png}
        return Case(kind, files, ["dataset", "{IN}/spec.toml", "--out", "{OUT}", "-q", "--workers", "1"], label)
    if kind == "sidecar":
        doc = apply_tree_ops(seeds.sidecar, ops)
        source = ["--source", "exr"] if choice % 2 else []
        return Case(kind, _frame_files(seeds, json=to_json(doc)), ANALYZE + source, label)
    if kind == "preset":
        doc = apply_tree_ops(seeds.preset, ops)
        iso = ["--iso", "400"] if choice % 2 else []
        argv = ["render", "macbeth_26", "--preset", "{IN}/preset.toml", *iso, "--size", "24x22", "--illuminant",
                "D65", "--intensity", "1", *RENDER]
        return Case(kind, {"preset.toml": to_toml(doc)}, argv, label)
    if kind == "dng":
        body = apply_dng_ops(seeds.frame["dng"], ops)
        if choice % 2:  # camsim develop on the DNG alone: no sidecar, so its own tags are read (tifffile)
            dng = f"frames/{seeds.frame['stem']}.dng"
            return Case(kind, {dng: body}, ["develop", "{IN}/" + dng, "--out", "{OUT}", "-q"], label)
        return Case(kind, _frame_files(seeds, dng=body), ANALYZE, label)
    if kind == "exr":
        body = apply_exr_ops(seeds.frame["exr"], ops, seeds.exr_attributes)
        argv = ANALYZE + ["--source", "exr"] if choice % 2 == 0 else \
            ["denoise-eval", "{IN}/frames", "-d", "identity", "--out", "{OUT}", "-q", "--border", "1"]
        return Case(kind, _frame_files(seeds, exr=body), argv, label)
    if kind == "png":
        bomb = seeds.bomb if any(op[0] == "bomb" for op in ops) else b""
        scene = json.loads(json.dumps(seeds.scenes["astronaut"]))
        scene["image"].update(path="img.png", size=list(TINY))
        return Case(kind, {"img.png": apply_png_ops(seeds.png, ops, bomb), "scene.toml": to_toml(scene)},
                    scene_argv(), label)
    if kind == "cube":
        scene = {"name": "cube", "cube": {"path": "c.npy"}, "light": {"illuminants": ["D65"]}}
        return Case(kind, {"c.npy": apply_npy_ops(seeds.cube_body, ops), "scene.toml": to_toml(scene)},
                    scene_argv(), label)
    if kind == "raw":  # a [raw] scene: its file's bytes mutated, or its table's values
        if choice % 2 == 0:
            return Case(kind, {"src.dng": apply_dng_ops(seeds.raw_dng, ops), "scene.toml": to_toml(RAW_SCENE)},
                        scene_argv(), label)
        return Case(kind, {"src.dng": seeds.raw_dng, "scene.toml": to_toml(apply_tree_ops(RAW_SCENE, ops))},
                    scene_argv(), label)
    raise ValueError(kind)


#: The seed scene of the ``raw`` kind: a crop of the seed camera DNG, two frames darker than it.
RAW_SCENE = {"name": "raw", "raw": {"path": "src.dng", "crop": [2, 2, 44, 28], "photon_law": "thin"},
             "light": {"intensity_factors": [0.1, 0.01]}, "sensor": {"iso": 3200}}


#: Keys whose value becomes part of a file name (issue 24, point 1).
NAME_KEYS = ("name", "illuminants", "preset", "id")
#: Keys of sizes, counts and ranges (issue 24, points 3 and 5).
SIZE_KEYS = ("width", "height", "size", "crop", "count", "radius_max_px", "radius_min_px", "intensity_factors",
             "start_nm", "end_nm", "step_nm", "pixel_pitch_um", "levels", "repeats", "bits")

#: Named families of mutations per kind: (kind, family) → what they edit. The suite has one test per family.
FAMILIES = {
    "scene": ("names", "sizes", "values", "nesting"),
    "spec": ("names", "values"),
    "sidecar": ("values", "nesting"),
    "preset": ("values",),
    "dng": ("bytes",),
    "exr": ("bytes",),
    "png": ("bytes",),
    "cube": ("bytes",),
    "raw": ("bytes", "values"),
}


def _ops_for(seeds: Seeds, kind: str, family: str, doc=None):
    if kind == "dng":
        return dng_ops(seeds.dng_entries)
    if kind == "raw" and family == "bytes":
        return dng_ops(seeds.raw_entries)
    if kind == "exr":
        return exr_ops(seeds.exr_attributes)
    if kind == "png":
        return png_ops()
    if kind == "cube":
        return npy_ops()
    if family == "names":
        return tree_ops(doc, st.sampled_from(PATH_NAMES) | st.lists(st.sampled_from(PATH_NAMES), min_size=1,
                                                                         max_size=2), keys=NAME_KEYS, max_ops=1)
    if family == "sizes":
        return tree_ops(doc, st.sampled_from(EXTREMES) | st.sampled_from((2**40, 100000, -(2**63), 30000)),
                        keys=SIZE_KEYS, max_ops=2)
    if family == "nesting":
        return tree_ops(doc, st.sampled_from((nested(3000), nested(100000), nested(3000, "{}"))), max_ops=1)
    return tree_ops(doc)


@st.composite
def case_strategy(draw, seeds: Seeds, kind: str, family: str | None = None) -> Case:
    """A strategy for one mutated :class:`Case` of ``kind`` (and of one of :data:`FAMILIES`, else any)."""
    family = family or draw(st.sampled_from(FAMILIES[kind]))
    if kind == "scene":
        choice = draw(st.integers(0, len(seeds.scenes) - 1))
        doc = seeds.scenes[sorted(seeds.scenes)[choice]]
    elif kind == "raw":  # choice 0 mutates the file's bytes, 1 the [raw] scene's values
        choice, doc = (0, None) if family == "bytes" else (1, RAW_SCENE)
    else:
        choice = draw(st.integers(0, 1))
        doc = {"spec": seeds.spec, "sidecar": seeds.sidecar, "preset": seeds.preset}.get(kind)
    if kind == "spec" and family == "names":  # a spec's names are its own and its scene's illuminants
        doc = {k: v for k, v in doc.items() if k in ("name", "grid", "fixed")}
    if family == "names" and not [p for p in tree_paths(doc) if p[-1] in NAME_KEYS]:
        family = "values"
    if family == "sizes" and not [p for p in tree_paths(doc) if p[-1] in SIZE_KEYS]:
        family = "values"
    ops = draw(_ops_for(seeds, kind, family, doc))
    case = make_case(seeds, kind, ops, choice, label=family)
    case.ops = ops
    return case


# --------------------------------------------------------------------------------------------------------------
# Running a case
# --------------------------------------------------------------------------------------------------------------


@dataclasses.dataclass
class Result:
    """What one case came to (:func:`classify`) and what was seen."""

    outcome: str
    rc: int | None
    seconds: float  # wall-clock time
    cpu_s: float  # CPU time of the case and the processes it reaped
    peak_mb: float  # the case's resident memory above the forking process's (MB)
    stderr: list
    traceback: str | None
    outside: list  # files made, changed or removed outside {OUT}, relative to the scratch folder's parent
    partial: list  # temporary files left

    def summary(self) -> str:
        """One line: outcome, exit status, seconds, MB and the first lines of what went wrong."""
        parts = [f"{self.outcome} rc={self.rc} {self.seconds:.2f}s ({self.cpu_s:.2f}s CPU) {self.peak_mb:.0f}MB"]
        if self.traceback:
            parts.append(self.traceback.strip().splitlines()[-1][:200])
        parts += [repr(line[:200]) for line in self.stderr[:3]]
        parts += [f"outside: {self.outside[:3]}"] if self.outside else []
        parts += [f"partial: {self.partial[:3]}"] if self.partial else []
        return " | ".join(parts)


def prepare(case: Case, root: Path) -> tuple[Path, Path]:
    """Write ``case``'s files into ``root/in`` (``{ROOT}`` and ``{IN}`` replaced); returns (input, output) folders.
    The output folder, ``root/a/b/c/out``, is not made: the command makes it."""
    inp = root / "in"
    out = root / "a" / "b" / "c" / "out"
    out.parent.mkdir(parents=True, exist_ok=True)
    for name, body in case.files.items():
        path = inp / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(body, str):
            body = body.replace("{ROOT}", str(root)).replace("{IN}", str(inp)).encode("utf-8", "surrogatepass")
        path.write_bytes(body)
    return inp, out


def snapshot(top: Path, skip: tuple[Path, ...]) -> dict:
    """(size, mtime) of every file and folder under ``top``, except ``skip`` and what is under them, by path."""
    state = {}
    for folder, dirs, files in os.walk(top):
        here = Path(folder)
        dirs[:] = [name for name in dirs if here / name not in skip]
        for name in dirs + files:
            path = here / name
            if path in skip:
                continue
            try:
                info = path.lstat()
            except OSError:
                continue
            state[str(path.relative_to(top))] = (info.st_size, 0 if path.is_dir() else info.st_mtime_ns)
    return state


def _vm_bytes(field: str) -> int:
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    return 0


def _group_progress(pgid: int) -> tuple[float, bool]:
    """(CPU time, any thread runnable) of the case's processes: the living members of process group ``pgid`` and
    the descendants of its leader ``pgid`` (a ``cmd:`` denoiser runs in a group of its own), the CPU time including
    what they reaped of their children. Unit: s. Read from ``/proc``; a process that exits meanwhile is skipped."""
    tick = os.sysconf("SC_CLK_TCK")
    stats, children = {}, {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/stat", "rb") as handle:
                fields = handle.read().rsplit(b")", 1)[1].split()
            pid, ppid, group = int(entry.name), int(fields[1]), int(fields[2])
        except (OSError, ValueError, IndexError):
            continue
        stats[pid] = (group, sum(int(f) for f in fields[11:15]) / tick)  # utime, stime, cutime, cstime
        children.setdefault(ppid, []).append(pid)
    members = {pid for pid, (group, _) in stats.items() if group == pgid}
    seen, todo = {pgid}, [pgid]
    while todo:  # the leader's descendants, whatever their group
        for child in children.get(todo.pop(), ()):
            if child not in seen:
                seen.add(child)
                todo.append(child)
    members |= seen
    cpu, runnable = 0.0, False
    for pid in members & stats.keys():
        cpu += stats[pid][1]
        try:
            for task in os.scandir(f"/proc/{pid}/task"):
                with open(f"{task.path}/stat", "rb") as handle:
                    runnable = runnable or handle.read().rsplit(b")", 1)[1].split()[0] == b"R"
        except OSError:
            continue
    return cpu, runnable


def run_case(case: Case, root: Path, *, time_limit: float = 10.0, memory_limit_mb: float = 1536,
             backstop_s: float | None = None, main=None) -> Result:
    """Run ``case`` in a forked child (its own process group) under ``root`` (made; removed by the caller) and
    classify it.

    Parameters
    ----------
    case : Case
        The files and the command line.
    root : Path
        The case's scratch folder (must not exist): input ``root/in``, output ``root/a/b/c/out``. Its parent
        must hold nothing that changes while the case runs: it is compared before and after too (a scene named
        ``{ROOT}`` writes ``{ROOT}_D65_F1.dng`` beside ``root``).
    time_limit : float
        Seconds of CPU time each process of the case may use (``RLIMIT_CPU``, whole seconds, at least 1) before the
        kernel kills it (the outcome is then ``hang``); also how long the case may go without any progress (no CPU
        time gained, nothing runnable) before it counts as blocked (``hang`` too).
    memory_limit_mb : float
        MB of address space the case may add to the forking process's (``RLIMIT_AS``); a case that needs more
        fails its allocation (outcome ``memory``).
    backstop_s : float, optional
        Seconds of wall-clock time after which a case still making progress is stopped as ``busy``
        (default :data:`BACKSTOP_FACTOR` × ``time_limit``).
    main : callable, optional
        What the child runs on the case's ``argv`` (default :func:`camsim.cli.main`; the runner's own tests pass
        functions that compute or block forever).
    """
    root = Path(root)
    root.mkdir(parents=True)
    inp, out = prepare(case, root)
    argv = [a.replace("{IN}", str(inp)).replace("{OUT}", str(out)).replace("{ROOT}", str(root)) for a in case.argv]
    side = root.parent / f".{root.name}"
    side.mkdir()
    before = snapshot(root.parent, (out, side))
    err_path, result_path = side / "stderr", side / "result.json"
    limit = _vm_bytes("VmSize") + int(memory_limit_mb * 2**20)
    cpu_limit = max(1, math.ceil(time_limit))
    backstop = BACKSTOP_FACTOR * time_limit if backstop_s is None else backstop_s
    base_rss = _vm_bytes("VmRSS")
    quiesce()  # another test in this process may have started OpenEXR's pool since
    sys.stdout.flush()
    sys.stderr.flush()
    start = time.monotonic()
    pid = os.fork()
    if pid == 0:  # the case
        _child(argv, root, err_path, result_path, limit, cpu_limit, main)
    killed = busy = False
    last_cpu, last_progress, next_look = -1.0, start, start
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            break
        now = time.monotonic()
        if now >= next_look:  # a /proc walk: a few times a second
            next_look = now + 0.1
            cpu, runnable = _group_progress(pid)
            if cpu > last_cpu or runnable:
                last_cpu, last_progress = max(cpu, last_cpu), now
            blocked = now - last_progress > time_limit
            if blocked or now - start > backstop:
                busy = not blocked
                killed = blocked
                with _suppress():
                    os.killpg(pid, signal.SIGKILL)
                _, status, usage = os.wait4(pid, 0)
                break
        time.sleep(0.002 if now - start < 0.5 else 0.02)
    seconds = time.monotonic() - start
    with _suppress():  # whatever the case started in its group
        os.killpg(pid, signal.SIGKILL)
    cpu_s = usage.ru_utime + usage.ru_stime
    # SIGXCPU comes from the kernel only; a SIGKILL not ours (busy, blocked) at the limit is its hard limit's
    # (the accounting lags the limit by a clock tick or so)
    signalled_by = os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
    over_cpu = signalled_by == signal.SIGXCPU or (signalled_by == signal.SIGKILL and not (busy or killed)
                                                  and cpu_s >= 0.9 * cpu_limit)
    killed = killed or over_cpu
    stderr = [line for line in err_path.read_text("utf-8", "replace").splitlines() if line.strip()]
    try:
        reported = json.loads(result_path.read_text())
    except (OSError, ValueError):
        reported = None
    after = snapshot(root.parent, (out, side))
    outside = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    partial = sorted(str(p.relative_to(root.parent)) for p in root.parent.rglob("*.partial") if side not in p.parents)
    result = Result(outcome="", rc=reported["rc"] if reported else None, seconds=seconds, cpu_s=cpu_s,
                    peak_mb=max(usage.ru_maxrss * 1024 - base_rss, 0) / 2**20, stderr=stderr,
                    traceback=reported["traceback"] if reported else None, outside=outside, partial=partial)
    result.outcome = "busy" if busy else classify(
        result, killed=killed, signalled=os.WIFSIGNALED(status) and not killed, memory_limit_mb=memory_limit_mb)
    shutil.rmtree(side, ignore_errors=True)
    return result


class _suppress:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return exc[0] is not None and issubclass(exc[0], OSError)


def _child(argv, root, err_path, result_path, limit, cpu_limit, main):  # pragma: no cover - runs in the fork
    code = 0
    try:
        os.setpgid(0, 0)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        resource.setrlimit(resource.RLIMIT_CPU, (cpu_limit, cpu_limit + 1))  # SIGXCPU, then SIGKILL a second later
        fd = os.open(err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.dup2(fd, 2)
        sys.stdout = open(1, "w", encoding="utf-8", errors="replace", closefd=False, buffering=1)
        sys.stderr = open(2, "w", encoding="utf-8", errors="backslashreplace", closefd=False, buffering=1)
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_DFL if sig == signal.SIGTERM else signal.default_int_handler)
        os.chdir(root)
        fresh_reporting()
        if main is None:
            from camsim.cli import main

        rc, tb = None, None
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:  # noqa: BLE001 - anything else escaping main is the finding
            tb = traceback.format_exc()
        sys.stdout.flush()
        sys.stderr.flush()
        with open(result_path, "w") as handle:
            json.dump({"rc": rc, "traceback": tb}, handle)
    except BaseException:  # noqa: BLE001
        code = 70
    finally:
        os._exit(code)


def fresh_reporting() -> None:
    """Warnings and log records reach stderr as in a fresh ``camsim`` process, whatever the forking process set up.

    Under pytest the forking process records warnings (``catch_warnings(record=True)``) and captures log records
    (handlers on the root logger): a case would hide the lines a user sees (numpy's ``RuntimeWarning``, tifffile's
    log messages). This restores Python's default warning filters and printing, and the root logger's defaults
    (no handler: records of WARNING and above go to stderr through ``logging.lastResort``). The filters libraries
    add on import are dropped with pytest's (numpy's: ignore "numpy.ndarray size changed", always RankWarning);
    none concerns what camsim prints.
    """
    import logging
    import warnings

    warnings.resetwarnings()  # also forgets which warnings were shown already
    for category in (ResourceWarning, ImportWarning, PendingDeprecationWarning, DeprecationWarning):
        warnings.filterwarnings("ignore", category=category)
    warnings.filterwarnings("default", category=DeprecationWarning, module="__main__")

    def show(message, category, filename, lineno, file=None, line=None):
        (file or sys.stderr).write(warnings.formatwarning(message, category, filename, lineno, line))

    warnings.showwarning = show
    root = logging.getLogger()
    for handler in list(root.handlers):
        root.removeHandler(handler)
    root.setLevel(logging.WARNING)
    logging.disable(logging.NOTSET)


def classify(result: Result, *, killed: bool, signalled: bool, memory_limit_mb: float) -> str:
    """The first of :data:`OUTCOMES` that applies to ``result``."""
    text = "\n".join(result.stderr) + (result.traceback or "")
    if killed:
        return "hang"
    if signalled or (result.rc is None and result.traceback is None):
        return "crash"
    if "MemoryError" in text or "out of memory" in text or result.peak_mb > memory_limit_mb:
        return "memory"
    if result.traceback or "Traceback (most recent call last)" in text:
        return "traceback"
    if result.outside:
        return "outside"
    if result.partial:
        return "partial"
    if result.rc != 0 and len(result.stderr) > 1:
        return "multiline"
    if result.rc == 0:
        return "ok"
    if result.rc == 2 and len(result.stderr) == 1 and result.stderr[0].startswith("camsim: error: "):
        return "refused"
    return "bad_exit"


def noisy_success(result: Result) -> bool:
    """Exit 0 with stderr lines that are not camsim's own (``camsim: warning: ...``): a library's warning."""
    return result.rc == 0 and any(not line.startswith("camsim:") for line in result.stderr)
