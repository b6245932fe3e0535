"""Hostile-input fuzzing of the ``camsim`` command line (issue 24): seed files, Hypothesis mutators, a case runner.

The suite (``tests/cli/test_fuzz.py``) and the long run (``tools/fuzz_cli.py``) share this module.

Seeds
    :func:`build_seeds` renders tiny frames once (a 48 × 32 ColorChecker: DNG, EXR, sidecar JSON) and prepares the
    other seed inputs: the built-in scene files and the built-in dataset spec ``denoise_small`` shrunk to one tiny
    frame, a camera preset file, a 48 × 32 PNG (written here, chunk by chunk, so that header edits keep valid CRCs)
    and a ``.npy`` reflectance cube; a dark frame, and (made per case) a TIFF, the cube as ENVI and MATLAB v5
    files and ``.npy`` pixel maps, also written here byte by byte, so that their headers can say anything.
Mutators
    Hypothesis strategies (:func:`case_strategy`) edit a seed structurally: TOML and JSON trees (delete a key,
    replace a value by another type or an extreme number, add a key, nest 3 000 deep, path-like names), binary
    files (byte flips, truncations, DNG tag entries, PNG IHDR fields, EXR header attributes, the ``.npy`` header's
    shape and dtype), so that a failure shrinks to a small edit. The second round's families
    (:data:`SECOND_ROUND`) put a special file at each path camsim reads (a FIFO, ``/dev/zero``, a socket, ...),
    control characters into each string that becomes a path, float64's extremes into every number, 10⁵ copies into
    a sidecar's lists, a sidecar over its size limit, and headers that declare 10⁸ to 10¹⁰ pixels (TIFF, DNG, PNG,
    EXR, ``.npy``, ENVI, ``.mat``) into tiny files. A :class:`Case` is the files of one run, its special files and
    its ``argv``; ``{IN}``, ``{OUT}`` and ``{ROOT}`` in them stand for the case's input folder, output folder and
    scratch folder.
Runner
    :func:`run_case` runs ``camsim.cli.main(argv)`` in a forked copy of the calling process (camsim already
    imported and warmed up: a case costs milliseconds more than an in-process call, not a new interpreter) in its
    own process group, with ``RLIMIT_AS`` (address space) and ``RLIMIT_CPU`` (CPU time: a case that computes too
    long is killed by the kernel, however busy the machine), and its file descriptors 1 and 2 sent to files, so that
    what C libraries print (``libpng error: ...``) is seen too. A case that makes no progress at all (no CPU time,
    nothing runnable) for as long as its CPU limit is blocked: a hang too (a case waiting in ``open()`` on a FIFO;
    the runner itself never opens a case's files, so no special file can block it). Wall-clock time only
    backstops: a case still working after :data:`BACKSTOP_FACTOR` times its CPU limit is ``busy`` (the machine was
    too busy to judge it), not a finding.
    It classifies the run (:data:`OUTCOMES`): every file under the case's scratch folder outside ``{OUT}`` is
    compared before and after (and in its parent folder), and no ``*.partial`` may remain anywhere in it.

Outside the scratch folder nothing is generated: the absolute paths the mutators write are ``{ROOT}/...`` and the
relative ones climb at most 4 folders from ``{OUT}`` (which is ``{ROOT}/a/b/c/out``), so an escape lands inside
``{ROOT}``, where it is seen (and harms nothing, even run as root).
"""

from __future__ import annotations

import dataclasses
import functools
import io
import itertools
import json
import math
import os
import resource
import shutil
import signal
import socket
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


@dataclasses.dataclass(frozen=True)
class Repeat:
    """Text written verbatim like :class:`Raw`, made only when written: ``unit`` ``count`` times joined by ``sep``,
    between ``prefix`` and ``suffix`` (a list of 2.4 million entries, 65 MB of blanks), so that a drawn case holds
    a few numbers, not the megabytes."""

    unit: str
    count: int
    sep: str = ","
    prefix: str = "["
    suffix: str = "]"

    @property
    def text(self) -> str:
        return self.prefix + self.sep.join(itertools.repeat(self.unit, self.count)) + self.suffix

    def __repr__(self):
        return f"Repeat({self.unit[:24]!r} x {self.count})"


#: What is spliced into a TOML or JSON document as text.
VERBATIM = (Raw, Repeat)


def nested(depth: int, brackets: str = "[]") -> Raw:
    """``depth`` nested empty lists (or ``{"a": {...}}`` objects with ``brackets="{}"``), as text."""
    if brackets == "{}":
        return Raw('{"a": ' * depth + "{}" + "}" * depth)
    return Raw("[" * depth + "]" * depth)


def _toml_key(key: str) -> str:
    return json.dumps(key, ensure_ascii=True)


def toml_value(value) -> str:
    """``value`` as an inline TOML value (strings JSON-escaped, which TOML's basic strings share)."""
    if isinstance(value, VERBATIM):
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
        if isinstance(value, VERBATIM):
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
    ``path``, or the top level for ``()``); ``("every_number", value)`` (every number in ``doc`` set to ``value``);
    ``("repeat", path, k)`` (the list at ``path`` repeated ``k`` times), ``("fill", path, n, element)`` (the list at
    ``path`` replaced by ``n`` copies of the JSON text ``element``), ``("repeat_every", k)`` (every list that is a
    table's value repeated ``k`` times): a list's text is kept under :data:`LIST_TEXT_BUDGET` characters.
    """
    doc = json.loads(json.dumps(doc, default=repr))  # a deep copy (seeds hold only JSON types)
    for op in ops:
        try:
            if op[0] == "every_number":
                for path in number_paths(doc):
                    _parent(doc, path)[path[-1]] = op[1]
            elif op[0] == "repeat":
                _parent(doc, op[1])[op[1][-1]] = repeated(_get(doc, op[1]), op[2])
            elif op[0] == "fill":
                _parent(doc, op[1])[op[1][-1]] = Repeat(op[3], op[2])
            elif op[0] == "repeat_every":
                paths = list_paths(doc)
                for path in reversed(paths):  # children first: a repeated list's own lists are repeated inside it
                    _parent(doc, path)[path[-1]] = repeated(_get(doc, path), op[1], share=len(paths))
            elif op[0] == "delete":
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


#: The most characters a repeated list is written with (the sidecar's limit is 64 MB: a list under it reaches the
#: code that reads the list, not the size check), and so the most a case's file holds. Unit: characters.
LIST_TEXT_BUDGET = 48 * 2**20


def number_paths(doc) -> list[tuple]:
    """Every path to a number (not a bool) inside ``doc``."""
    return [p for p in tree_paths(doc) if isinstance(_get(doc, p), (int, float)) and not isinstance(_get(doc, p), bool)]


def list_paths(doc) -> list[tuple]:
    """Every path to a non-empty list that is a table's value (not an element of another list) inside ``doc``."""
    return [p for p in tree_paths(doc) if isinstance(_get(doc, p), list) and _get(doc, p)
            and isinstance(_get(doc, p[:-1]), dict)]


def repeated(items, k: int, share: int = 1):
    """The list ``items`` × ``k`` as :class:`Repeat` text, ``k`` cut so that it stays within its ``1 / share`` of
    :data:`LIST_TEXT_BUDGET`; anything but a non-empty list is returned as it is."""
    if not isinstance(items, list) or not items:
        return items
    unit = ",".join(_compact(item) for item in items)
    return Repeat(unit, max(1, min(k, LIST_TEXT_BUDGET // share // max(len(unit), 1))))


def _compact(value) -> str:
    if isinstance(value, VERBATIM):
        return value.text
    if isinstance(value, dict):
        return "{" + ",".join(f"{json.dumps(str(k))}:{_compact(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ",".join(_compact(v) for v in value) + "]"
    return json.dumps(value)


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
    dark: dict = dataclasses.field(default_factory=dict)  # "dng", "json" → bytes of a dark frame (analyze --dark)
    dataset_record: str = ""  # the seed spec's frame record's name (``<id>.done``), which a re-run reads
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
    darks = folder / "darks"  # a dark frame of the seed frame's sensor: what analyze --dark reads
    if not (darks / "manifest.json").exists():
        _quiet_main(["render", "dark", "--size", "x".join(map(str, SEED_SIZE)), "--intensity", "1", "-q",
                     "--workers", "1", "--out", str(darks)])
    (dark,) = darks.glob("*.dng")
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
    seeds.dark = {"dng": dark.read_bytes(), "json": dark.with_suffix(".json").read_bytes()}
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
            if kind == "spec" and choice == 0:
                seeds.dataset_record = next((out / "frames").glob("*.done")).name
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
    """One run: the files written into ``{IN}`` (name → bytes or text), the special files made there (name → one
    of :data:`SPECIAL_FILES`; a name ``{OUT}/...`` is made in the output folder, which then exists before the run)
    and the command line."""

    kind: str
    files: dict
    argv: list
    label: str = ""
    ops: list = dataclasses.field(default_factory=list)
    specials: dict = dataclasses.field(default_factory=dict)
    family: str = ""

    def __repr__(self):
        sizes = {name: len(body) for name, body in self.files.items()}
        ops = repr(self.ops)
        ops = ops if len(ops) < 400 else ops[:400] + "..."
        specials = f", specials={self.specials}" if self.specials else ""
        return f"Case({self.kind}, {self.label}, ops={ops}, argv={self.argv}, files={sizes}{specials})"

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


def make_case(seeds: Seeds, kind: str, ops, choice=0, label="", family="") -> Case:
    """The case of ``kind`` with the mutation ``ops`` (as the strategies draw them); ``choice`` picks the seed scene
    (scene) or the command variant (sidecar, exr); ``family`` says how ``ops`` are read (:data:`FAMILIES`; the
    first round's and ``numbers``, ``lists``, ``oversize`` are tree, byte or header edits as ``kind`` has them)."""
    if family in ("special", "controls", "headers"):
        case = _second_round_case(seeds, kind, family, ops, choice)
        case.label, case.family = label or family, family
        return case
    case = _make_case(seeds, kind, ops, choice, label)
    case.family = family
    return case


def _make_case(seeds: Seeds, kind: str, ops, choice, label) -> Case:
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
        # ("sparse_file", n): the sidecar's text, then holes up to n bytes
        specials = {f"frames/{seeds.frame['stem']}.json": f"sparse:{op[1]}" for op in ops if op[0] == "sparse_file"}
        return Case(kind, _frame_files(seeds, json=to_json(doc)), ANALYZE + source, label, specials=specials)
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
#: The second round's (:data:`SECOND_ROUND`): ``special`` (a FIFO, device, folder, socket, self-link or sparse file
#: where a file is read), ``controls`` (control characters in a string that becomes a path), ``numbers`` (±1e300,
#: ±1e-300, 5e-324, ±1.7976931348623157e308 in every number), ``lists`` (a sidecar's lists × 10⁵, or millions of
#: entries), ``oversize`` (a sidecar over 64 MB), ``headers`` (a header that declares 10⁸ to 10¹⁰ pixels).
FAMILIES = {
    "scene": ("names", "sizes", "values", "nesting", "special", "controls", "numbers"),
    "spec": ("names", "values", "special", "controls", "numbers"),
    "sidecar": ("values", "nesting", "special", "controls", "numbers", "lists", "oversize"),
    "preset": ("values", "special", "controls", "numbers"),
    "dng": ("bytes", "special", "headers"),
    "exr": ("bytes", "special", "headers"),
    "png": ("bytes", "special", "controls", "headers"),
    "cube": ("bytes", "special", "controls", "headers"),
    "raw": ("bytes", "values", "special", "controls", "numbers", "headers"),
}


def kinds_of(family: str) -> tuple:
    """The kinds that have ``family``, in :data:`KINDS` order."""
    return tuple(kind for kind in KINDS if family in FAMILIES[kind])


def _ops_for(seeds: Seeds, kind: str, family: str, doc=None):
    if family == "special":
        return special_ops(kind)
    if family == "controls":
        return control_ops(kind)
    if family == "headers":
        return header_ops(kind)
    if family == "numbers":
        return number_ops(doc)
    if family == "lists":
        return list_ops(doc)
    if family == "oversize":
        return oversize_ops()
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
    if family in ("special", "controls", "headers"):  # built from their ops alone
        ops = draw(_ops_for(seeds, kind, family))
        case = make_case(seeds, kind, ops, draw(st.integers(0, 5)), label=family, family=family)
        case.ops = ops
        return case
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
    case = make_case(seeds, kind, ops, choice, label=family, family=family)
    case.ops = ops
    return case


# --------------------------------------------------------------------------------------------------------------
# The second round of hostile inputs: special files at every input path, control characters in every string that
# becomes a path, extreme numbers everywhere, huge sidecar lists and files, headers that declare huge images
# --------------------------------------------------------------------------------------------------------------

#: The families of the second round, each of several kinds (:data:`FAMILIES`).
SECOND_ROUND = ("special", "controls", "numbers", "lists", "oversize", "headers")

#: Control characters put into the strings that become paths. NUL cannot be in a file name: such a path names a
#: file that cannot exist (and the operating system's calls raise ``ValueError`` on it, not ``OSError``); the
#: others can, and camsim must still say which file it means on one line.
CONTROL_CHARS = ("\x00", "\x01", "\n", "\r", "\x1b", "\x7f")
#: Where in the string the character goes (``middle``: in the stem, so that the extension still names the format).
CONTROL_PLACES = ("prefix", "middle", "suffix", "only")

#: Numbers at the ends of float64: huge, tiny, subnormal, the largest finite. Every number of a scene, spec,
#: preset or sidecar may be any of them (none is NaN or infinite: those are the first round's).
HUGE_NUMBERS = (1e300, -1e300, 1e-300, -1e-300, 5e-324, 1.7976931348623157e308, -1.7976931348623157e308)

#: How many times a sidecar list is repeated (the text kept under :data:`LIST_TEXT_BUDGET`). Unit: 1.
LIST_REPEAT = 10**5
#: Entries of a list replaced by copies of one small element (a list of millions of entries in a few MB). Unit: 1.
LIST_FILL = (10**5, 10**6, 24 * 10**5)
#: The elements it is filled with, as JSON text.
FILL_ELEMENTS = ("0", "[]", "{}", '""', "1e300", "null", "[0, 0, 0]")
#: Size of an oversized sidecar: over the 64 MB that camsim reads of one (written for the case, removed after it).
#: Unit: bytes.
OVERSIZE_BYTES = 65 * 2**20

#: (width, height) that headers declare: 10⁸ to 10¹⁰ pixels, and the largest sizes each field holds.
PIXEL_DIMS = ((10000, 10000), (100000, 1000), (31623, 31623), (100000, 100000), (65536, 65536), (2**31 - 1, 4),
              (4, 2**31 - 1))
#: Bands a cube header declares beside its huge size.
CUBE_BANDS = (101, 10**6)
#: The largest sparse file a header case makes to be the size its header declares (holes only). Unit: bytes.
SPARSE_LIMIT = 2**40

#: Where each kind's special file goes: the slot names the path camsim reads (:func:`special_case`).
SPECIAL_SLOTS = {
    "scene": ("scene file", "dark_shading_map", "hot_pixel_map", "render manifest", "earlier sidecar"),
    "spec": ("spec file", "spec's scene", "image", "images folder", "frame record"),
    "preset": ("preset file", "dark_shading_map", "hot_pixel_map"),
    "sidecar": ("sidecar", "frame folder"),
    "dng": ("dng", "dark frame"),
    "exr": ("exr",),
    "png": ("image",),
    "cube": ("npy", "ENVI header", "ENVI binary", "mat"),
    "raw": ("raw",),
}
#: Which string of each kind gets a control character (:func:`controls_case`).
CONTROL_SLOTS = {
    "scene": ("name", "illuminant", "preset name", "scene file", "map path", "out"),
    "spec": ("name", "illuminant", "preset name", "spec's scene", "images folder", "spec file", "out"),
    "preset": ("name", "map path", "preset file"),
    "sidecar": ("frame stem", "files entry", "frame folder"),
    "png": ("image path",),
    "cube": ("cube path",),
    "raw": ("raw path",),
}


def with_control(text: str, char: str, place: str) -> str:
    """``text`` with ``char`` put at ``place`` (one of :data:`CONTROL_PLACES`)."""
    if place == "only":
        return char
    if place == "prefix":
        return char + text
    if place == "suffix":
        return text + char
    stem, dot, ext = text.rpartition(".")
    stem, ext = (stem, dot + ext) if dot else (text, "")
    return stem[:len(stem) // 2] + char + stem[len(stem) // 2:] + ext


def map_npy(shape=(TINY[1], TINY[0])) -> bytes:
    """A ``.npy`` pixel map of zeros (e⁻, or e⁻/s), the tiny frames' shape: what a ``*_map`` key names."""
    return npy_bytes({"descr": "<f8", "fortran_order": False, "shape": shape}, bytes(8 * math.prod(shape)))


def envi_header(samples: int, lines: int, bands: int, data_type: int = 5) -> str:
    """An ENVI header of a band-interleaved-by-pixel cube (the ``.npy`` cube's layout), little-endian."""
    return (f"ENVI\nsamples = {samples}\nlines = {lines}\nbands = {bands}\nheader offset = 0\n"
            f"data type = {data_type}\ninterleave = bip\nbyte order = 0\n")


def mat_bytes(name: str, dims, data: bytes, declared: int | None = None) -> bytes:
    """A MATLAB v5 file (little-endian) of one double array ``name`` of ``dims`` whose real part is ``data``
    (column-major), its byte count written as ``declared`` if given (a header that claims more than is there)."""
    def element(kind, payload, size=None):
        return struct.pack("<II", kind, len(payload) if size is None else size) + payload + bytes(-len(payload) % 8)

    body = (element(6, struct.pack("<II", 6, 0))  # miUINT32 array flags: mxDOUBLE_CLASS
            + element(5, struct.pack(f"<{len(dims)}i", *dims))  # miINT32 dimensions
            + element(1, name.encode("ascii"))  # miINT8 name
            + element(9, data, declared))  # miDOUBLE real part
    header = b"MATLAB 5.0 MAT-file, written by the camsim fuzz seeds".ljust(116, b" ") + bytes(8)
    return header + struct.pack("<H", 0x0100) + b"IM" + struct.pack("<II", 14, len(body)) + body


def _pack_entries(entries: dict, at: int) -> bytes:
    """A TIFF IFD placed at file offset ``at``: ``entries`` tag → the 12 bytes of an entry kept as it was, or
    (type, values) for SHORT (3) or LONG (4) values, put after the IFD when they do not fit in it."""
    ifd, extra = bytearray(struct.pack("<H", len(entries))), bytearray()
    extra_at = at + 2 + 12 * len(entries) + 4
    for tag in sorted(entries):
        entry = entries[tag]
        if isinstance(entry, bytes):
            ifd += entry
            continue
        kind, values = entry
        packed = struct.pack(f"<{len(values)}{'H' if kind == 3 else 'I'}", *values)
        if len(packed) <= 4:
            ifd += struct.pack("<HHI", tag, kind, len(values)) + packed.ljust(4, b"\0")
        else:
            ifd += struct.pack("<HHII", tag, kind, len(values), extra_at + len(extra))
            extra += packed + bytes(len(packed) % 2)
    return bytes(ifd + struct.pack("<I", 0) + extra)


def tiff_with(data: bytes, edits: dict) -> bytes:
    """The little-endian TIFF ``data`` with its first IFD's entries edited (tag → (type, values), or None to
    remove it): a new IFD appended and the header pointed at it; the old bytes stay where their offsets point."""
    ifd = struct.unpack_from("<I", data, 4)[0]
    count = struct.unpack_from("<H", data, ifd)[0]
    entries = {struct.unpack_from("<H", data, ifd + 2 + 12 * i)[0]: data[ifd + 2 + 12 * i: ifd + 14 + 12 * i]
               for i in range(count)}
    for tag, edit in edits.items():
        if edit is None:
            entries.pop(tag, None)
        else:
            entries[tag] = edit
    out = bytearray(data + bytes(len(data) % 2))  # an IFD starts on a word boundary
    at = len(out)
    out += _pack_entries(entries, at)
    struct.pack_into("<I", out, 4, at)
    return bytes(out)


def tiff_bytes(width: int = SEED_SIZE[0], height: int = SEED_SIZE[1]) -> bytes:
    """An uncompressed 8-bit RGB TIFF, one strip (a gradient): the seed of the TIFF header cases."""
    pixels = bytes((x * 5 + y * 7 + c * 60) & 255 for y in range(height) for x in range(width) for c in range(3))
    data = b"II*\0" + struct.pack("<I", 8 + len(pixels)) + pixels
    tags = {256: (4, [width]), 257: (4, [height]), 258: (3, [8, 8, 8]), 259: (3, [1]), 262: (3, [2]),
            273: (4, [8]), 277: (3, [3]), 278: (4, [height]), 279: (4, [len(pixels)]), 284: (3, [1])}
    return data + _pack_entries(tags, len(data))


def _first_value(data: bytes, tag: int) -> int:
    ifd = struct.unpack_from("<I", data, 4)[0]
    for i in range(struct.unpack_from("<H", data, ifd)[0]):
        at = ifd + 2 + 12 * i
        if struct.unpack_from("<H", data, at)[0] == tag:
            kind = struct.unpack_from("<H", data, at + 2)[0]
            return struct.unpack_from("<H" if kind == 3 else "<I", data, at + 8)[0]
    raise KeyError(tag)


def dims_edits(data: bytes, width: int, height: int, layout: str) -> dict:
    """:func:`tiff_with` edits that make the TIFF/DNG ``data`` (one strip) declare ``width`` × ``height``:
    ``strips`` (ImageWidth, ImageLength, RowsPerStrip), ``tiles`` (one tile of the whole size: TileWidth,
    TileLength, TileOffsets, TileByteCounts for the strip's bytes), ``small tiles`` (16 × 16 tiles, one offset
    for all of them), ``crop`` (DefaultCropSize), ``active`` (ActiveArea)."""
    size = {256: (4, [width]), 257: (4, [height])}
    if layout == "strips":
        return {**size, 278: (4, [height])}
    if layout in ("tiles", "small tiles"):
        tile = [min(-(-width // 16) * 16, 2**32 - 16), min(-(-height // 16) * 16, 2**32 - 16)] \
            if layout == "tiles" else [16, 16]
        return {**size, 273: None, 278: None, 279: None, 322: (4, [tile[0]]), 323: (4, [tile[1]]),
                324: (4, [_first_value(data, 273)]), 325: (4, [_first_value(data, 279)])}
    if layout == "crop":
        return {50719: (4, [0, 0]), 50720: (4, [width, height])}
    return {50829: (4, [0, 0, height, width])}  # active: top, left, bottom, right


def _frame_base(seeds: Seeds, kind: str, choice: int) -> tuple[dict, list]:
    """(files, argv) of the frame-folder commands: analyze (DNG or EXR source) or denoise-eval."""
    files = _frame_files(seeds)
    if kind == "exr":
        argv = ANALYZE + ["--source", "exr"] if choice % 2 == 0 else \
            ["denoise-eval", "{IN}/frames", "-d", "identity", "--out", "{OUT}", "-q", "--border", "1"]
    elif kind == "sidecar" and choice % 2:
        argv = ["denoise-eval", "{IN}/frames", "-d", "identity", "--out", "{OUT}", "-q", "--border", "1"]
    else:
        argv = list(ANALYZE)
    return files, argv


def _preset_argv(iso: str | None) -> list:
    return ["render", "macbeth_26", "--preset", "{IN}/preset.toml", *(["--iso", iso] if iso else []), "--size",
            "24x22", "--illuminant", "D65", "--intensity", "1", *RENDER]


def _cube_base(seeds: Seeds, form: str) -> tuple[dict, str]:
    """(files, the cube's file name) of a cube scene whose cube is a ``.npy``, ENVI (``.hdr`` + ``.img``) or
    ``.mat`` file of the seed cube."""
    if form == "npy":
        files, name = {"c.npy": apply_npy_ops(seeds.cube_body, [])}, "c.npy"
    elif form == "envi":
        files, name = {"c.hdr": envi_header(TINY[0], TINY[1], 101), "c.img": seeds.cube_body}, "c.hdr"
    else:
        import numpy as np

        cube = np.frombuffer(seeds.cube_body).reshape(TINY[1], TINY[0], 101)
        files, name = {"c.mat": mat_bytes("cube", cube.shape, cube.tobytes(order="F"))}, "c.mat"
    scene = {"name": "cube", "cube": {"path": name}, "light": {"illuminants": ["D65"]}}
    return {**files, "scene.toml": to_toml(scene)}, name


def special_case(seeds: Seeds, kind: str, slot: str, special: str, choice: int = 0) -> Case:
    """The seed case of ``kind`` with the file at ``slot`` (one of :data:`SPECIAL_SLOTS`) made the special file
    ``special`` (one of :data:`SPECIAL_FILES`); ``choice`` picks the command where a kind has two."""
    argv = None
    if kind == "scene":
        doc = json.loads(json.dumps(seeds.scenes["macbeth_26"]))
        files = {}
        target = {"scene file": "scene.toml", "dark_shading_map": "map.npy", "hot_pixel_map": "map.npy",
                  "render manifest": "{OUT}/manifest.json", "earlier sidecar": "{OUT}/earlier.json"}[slot]
        if slot.endswith("_map"):
            doc.setdefault("sensor", {})[slot] = "map.npy"
            files["map.npy"] = map_npy()
        files["scene.toml"] = to_toml(doc)
        argv = scene_argv()
    elif kind == "spec":
        case = make_case(seeds, "spec", [])
        files, argv = dict(case.files), case.argv
        target = {"spec file": "spec.toml", "spec's scene": "macbeth_26.toml", "image": "images/tiny.png",
                  "images folder": "images", "frame record": f"{{OUT}}/frames/{seeds.dataset_record}"}[slot]
    elif kind == "preset":
        doc = json.loads(json.dumps(seeds.preset))
        files, target, argv = {}, "preset.toml", _preset_argv("400" if choice % 2 else None)
        if slot.endswith("_map"):
            doc["iso"][0][slot] = "map.npy"
            files["map.npy"] = map_npy()
            target, argv = "map.npy", _preset_argv("200")  # the ISO the map is stated at
        files["preset.toml"] = to_toml(doc)
    elif kind in ("sidecar", "dng", "exr"):
        files, argv = _frame_base(seeds, kind, choice)
        stem = seeds.frame["stem"]
        target = {"sidecar": f"frames/{stem}.json", "frame folder": "frames", "dng": f"frames/{stem}.dng",
                  "exr": f"frames/{stem}.exr", "dark frame": "dark.dng"}[slot]
        if slot == "dng" and choice % 2:  # develop on the DNG alone
            files, argv = {target: seeds.frame["dng"]}, ["develop", "{IN}/" + target, "--out", "{OUT}", "-q"]
        if slot == "dark frame":
            files.update({"dark.dng": seeds.dark["dng"], "dark.json": seeds.dark["json"]})
            argv = argv + ["--dark", "{IN}/dark.dng"]
    elif kind == "png":
        case = make_case(seeds, "png", [])
        files, argv, target = dict(case.files), case.argv, "img.png"
    elif kind == "cube":
        form = {"npy": "npy", "ENVI header": "envi", "ENVI binary": "envi", "mat": "mat"}[slot]
        files, target = _cube_base(seeds, form)
        target, argv = "c.img" if slot == "ENVI binary" else target, scene_argv()
    elif kind == "raw":
        case = make_case(seeds, "raw", [], 0)
        files, argv, target = dict(case.files), case.argv, "src.dng"
    else:
        raise ValueError(kind)
    files = {name: body for name, body in files.items() if not name.startswith(target + "/")}  # no folder there
    return Case(kind, files, argv, specials={target: special})


def controls_case(seeds: Seeds, kind: str, slot: str, char: str, place: str, choice: int = 0) -> Case:
    """The seed case of ``kind`` with ``char`` (one of :data:`CONTROL_CHARS`) put at ``place`` into the string at
    ``slot`` (one of :data:`CONTROL_SLOTS`): a name that becomes an output file's, or a path, in a file or on the
    command line. A file the path names is written under that name, where a file can have it (no NUL)."""
    mangle = functools.partial(with_control, char=char, place=place)

    def renamed(files, old, new):  # the file ``old`` now at ``new``, if a file can be named so
        return {(new if name == old and "\x00" not in new else name): body for name, body in files.items()}

    if kind == "scene":
        doc = json.loads(json.dumps(seeds.scenes["macbeth_26"]))
        files, name, argv = {}, "scene.toml", scene_argv()
        if slot == "name":
            doc["name"] = mangle("macbeth_26")
        elif slot == "illuminant":
            doc["light"]["illuminants"] = [mangle("D65")]
        elif slot == "preset name":
            doc.setdefault("sensor", {})["preset"] = mangle("paper-table1")
        elif slot == "map path":
            doc.setdefault("sensor", {})["dark_shading_map"] = mangle("map.npy")
            files = renamed({"map.npy": map_npy()}, "map.npy", mangle("map.npy"))
        elif slot == "scene file":
            name = mangle("scene.toml")
            argv = scene_argv(name)
        elif slot == "out":
            argv = [a if a != "{OUT}" else "{OUT}/" + mangle("sub") for a in argv]
        files = renamed({**files, "scene.toml": to_toml(doc)}, "scene.toml", name)
        return Case(kind, files, argv)
    if kind == "spec":
        doc = json.loads(json.dumps(seeds.spec))
        case = make_case(seeds, "spec", [])
        files, argv = dict(case.files), list(case.argv)
        if slot == "name":
            doc["name"] = mangle(doc["name"])
        elif slot == "illuminant":
            doc["grid"]["illuminants"] = [mangle("D65")]
        elif slot == "preset name":
            doc["fixed"]["preset"] = mangle(doc["fixed"]["preset"])
        elif slot == "spec's scene":
            doc["scene"] = mangle("macbeth_26.toml")
            files = renamed(files, "macbeth_26.toml", doc["scene"])
        elif slot == "images folder":
            doc["images"]["folder"] = mangle("images")
            files = renamed(files, "images/tiny.png", doc["images"]["folder"] + "/tiny.png")
        elif slot == "spec file":
            argv[1] = "{IN}/" + mangle("spec.toml")
        elif slot == "out":
            argv = [a if a != "{OUT}" else "{OUT}/" + mangle("sub") for a in argv]
        files["spec.toml"] = to_toml(doc)
        if slot == "spec file":
            files = renamed(files, "spec.toml", mangle("spec.toml"))
        return Case(kind, files, argv)
    if kind == "preset":
        doc = json.loads(json.dumps(seeds.preset))
        files, name, argv = {}, "preset.toml", _preset_argv(None)
        if slot == "name":
            doc["preset"]["name"] = mangle(doc["preset"]["name"])
        elif slot == "map path":
            doc["iso"][0]["dark_shading_map"] = mangle("map.npy")
            files, argv = renamed({"map.npy": map_npy()}, "map.npy", mangle("map.npy")), _preset_argv("200")
        elif slot == "preset file":
            name = mangle("preset.toml")
            argv = [a if a != "{IN}/preset.toml" else "{IN}/" + name for a in argv]
        files = renamed({**files, "preset.toml": to_toml(doc)}, "preset.toml", name)
        return Case(kind, files, argv)
    if kind == "sidecar":
        files, argv = _frame_base(seeds, kind, choice)
        sidecar = json.loads(json.dumps(seeds.sidecar))
        stem = seeds.frame["stem"]
        if slot == "frame stem" and char != "\x00":
            new = mangle(stem)
            files = {name.replace(stem, new): body for name, body in files.items()}
            sidecar["files"] = {k: v.replace(stem, new) for k, v in sidecar["files"].items()}
        elif slot == "frame folder" and char != "\x00":
            folder = mangle("frames")
            files = {name.replace("frames/", folder + "/", 1): body for name, body in files.items()}
            argv = [a.replace("{IN}/frames", "{IN}/" + folder) for a in argv]
        else:  # the files entries (a stem or folder with NUL can only be named, not made)
            key = ("dng", "exr", "json")[choice % 3] if slot == "files entry" else "json"
            sidecar["files"][key] = mangle(sidecar["files"][key])
        json_name = next(name for name in files if name.endswith(".json"))
        files[json_name] = to_json(sidecar)
        return Case(kind, files, argv)
    if kind == "png":
        case = make_case(seeds, "png", [])
        scene = json.loads(json.dumps(seeds.scenes["astronaut"]))
        scene["image"].update(path=mangle("img.png"), size=list(TINY))
        files = renamed({**case.files, "scene.toml": to_toml(scene)}, "img.png", scene["image"]["path"])
        return Case(kind, files, case.argv)
    if kind == "cube":
        files, name = _cube_base(seeds, ("npy", "envi", "mat")[choice % 3])
        scene = {"name": "cube", "cube": {"path": mangle(name)}, "light": {"illuminants": ["D65"]}}
        files = renamed({**files, "scene.toml": to_toml(scene)}, name, mangle(name))
        if name == "c.hdr" and "\x00" not in mangle(name):  # the binary beside its header, by the header's stem
            files = renamed(files, "c.img", mangle(name)[:-4] + ".img")
        return Case(kind, files, scene_argv())
    if kind == "raw":
        scene = json.loads(json.dumps(RAW_SCENE))
        scene["raw"]["path"] = mangle("src.dng")
        files = renamed({"src.dng": seeds.raw_dng, "scene.toml": to_toml(scene)}, "src.dng", scene["raw"]["path"])
        return Case(kind, files, scene_argv())
    raise ValueError(kind)


def headers_case(seeds: Seeds, kind: str, op: tuple) -> Case:
    """The seed case of ``kind`` whose file's header declares a huge image (``op``: :func:`header_ops`'s) in a
    tiny file, or in a sparse one of the declared size."""
    if kind in ("dng", "raw"):
        (width, height), layout = op[1], op[2]
        if kind == "raw":
            body = tiff_with(seeds.raw_dng, dims_edits(seeds.raw_dng, width, height, layout))
            return Case(kind, {"src.dng": body, "scene.toml": to_toml(RAW_SCENE)}, scene_argv())
        files, argv = _frame_base(seeds, kind, 0)
        dng = f"frames/{seeds.frame['stem']}.dng"
        files[dng] = tiff_with(seeds.frame["dng"], dims_edits(seeds.frame["dng"], width, height, layout))
        if op[3] % 2:  # develop on the DNG alone: its own tags are all there is
            files, argv = {dng: files[dng]}, ["develop", "{IN}/" + dng, "--out", "{OUT}", "-q"]
        return Case(kind, files, argv)
    if kind == "exr":
        (width, height), which = op[1], op[2]
        body = bytearray(seeds.frame["exr"])
        for name in (("dataWindow", "displayWindow") if which == "both" else (f"{which}Window",)):
            at, _ = seeds.exr_attributes[name]
            struct.pack_into("<4i", body, at, 0, 0, width - 1, height - 1)
        files, argv = _frame_base(seeds, kind, op[3])
        files[f"frames/{seeds.frame['stem']}.exr"] = bytes(body)
        return Case(kind, files, argv)
    if kind == "png":
        (width, height) = op[1]
        scene = json.loads(json.dumps(seeds.scenes["astronaut"]))
        if op[0] == "ihdr":
            body, name = apply_png_ops(seeds.png, [("ihdr", width, height, 8, 2)], b""), "img.png"
        else:
            seed = tiff_bytes()
            body, name = tiff_with(seed, dims_edits(seed, width, height, op[2])), "img.tif"
        scene["image"].update(path=name, size=list(TINY))
        return Case(kind, {name: body, "scene.toml": to_toml(scene)}, scene_argv())
    if kind == "cube":
        form, (width, height), bands, body = op
        files, name = _cube_base(seeds, form)
        specials = {}
        declared = width * height * bands * 8
        if form == "npy":
            files[name] = npy_bytes({"descr": "<f8", "fortran_order": False, "shape": (height, width, bands)},
                                    seeds.cube_body[:4096])
            if body == "sparse" and declared <= SPARSE_LIMIT:
                specials[name] = f"sparse:{len(files[name]) - 4096 + declared}"
        elif form == "envi":
            files[name] = envi_header(width, height, bands)
            files["c.img"] = seeds.cube_body[:4096]
            if body == "sparse" and declared <= SPARSE_LIMIT:
                specials["c.img"] = f"sparse:{declared}"
        else:
            files[name] = mat_bytes("cube", (height, width, bands), seeds.cube_body[:4096],
                                    declared=min(declared, 2**32 - 8) if body == "sparse" else None)
        return Case(kind, files, scene_argv(), specials=specials)
    raise ValueError(kind)


def special_ops(kind: str):
    """A strategy for one special-file edit of ``kind``: ``[("special", slot, special file)]``."""
    return st.tuples(st.just("special"), st.sampled_from(SPECIAL_SLOTS[kind]),
                     st.sampled_from(SPECIAL_FILES)).map(lambda op: [op])


def control_ops(kind: str):
    """A strategy for one control-character edit of ``kind``: ``[("control", slot, char, place)]``."""
    return st.tuples(st.just("control"), st.sampled_from(CONTROL_SLOTS[kind]), st.sampled_from(CONTROL_CHARS),
                     st.sampled_from(CONTROL_PLACES)).map(lambda op: [op])


def number_ops(doc):
    """A strategy for extreme numbers in ``doc``: every number set to one of :data:`HUGE_NUMBERS`, or 1 to 3 of
    them, each to one."""
    value = st.sampled_from(HUGE_NUMBERS)
    every = st.tuples(st.just("every_number"), value).map(lambda op: [op])
    some = st.lists(st.tuples(st.just("set"), st.sampled_from(number_paths(doc)), value), min_size=1, max_size=3)
    return every | some


def list_ops(doc):
    """A strategy for a huge list in ``doc``: one list (a table's: ``patches`` and the other top-level ones more
    often than a patch's own) × :data:`LIST_REPEAT`, or filled with millions of one small element, or every list
    × :data:`LIST_REPEAT` (all within :data:`LIST_TEXT_BUDGET`)."""
    top = [p for p in list_paths(doc) if len(p) == 1]
    where = st.sampled_from(top) | st.sampled_from(list_paths(doc))
    return st.one_of(
        st.tuples(st.just("repeat"), where, st.just(LIST_REPEAT)),
        st.tuples(st.just("fill"), where, st.sampled_from(LIST_FILL), st.sampled_from(FILL_ELEMENTS)),
        st.just(("repeat_every", LIST_REPEAT)),
    ).map(lambda op: [op])


def oversize_ops():
    """A strategy for a sidecar over 64 MB: valid JSON padded with blanks, a 65 MB string in it, or the sidecar's
    text followed by holes (a sparse file of 65 MB or :data:`SPARSE_BYTES`)."""
    return st.sampled_from((
        [("add", (), "padding", Repeat(" ", OVERSIZE_BYTES, "", "", "0"))],
        [("set", ("units", "signal_e"), Repeat("x", OVERSIZE_BYTES, "", '"', '"'))],
        [("sparse_file", OVERSIZE_BYTES)],
        [("sparse_file", SPARSE_BYTES)],
    ))


def header_ops(kind: str):
    """A strategy for a header that declares :data:`PIXEL_DIMS` pixels: DNG tags (``raw``: the [raw] file's),
    an EXR window, a PNG IHDR or TIFF tags, a ``.npy``, ENVI or ``.mat`` cube's dimensions. A cube's data is
    ``tiny`` (4 kB) or ``sparse``: holes up to the declared size (``.npy``, ENVI binary; up to
    :data:`SPARSE_LIMIT`), or for ``.mat`` a real part whose byte count claims it (the file stays tiny)."""
    dims = st.sampled_from(PIXEL_DIMS)
    if kind in ("dng", "raw"):
        return st.tuples(st.just("dims"), dims, st.sampled_from(("strips", "tiles", "small tiles", "crop", "active")),
                         st.integers(0, 1)).map(lambda op: [op])
    if kind == "exr":
        return st.tuples(st.just("window"), dims, st.sampled_from(("data", "display", "both")),
                         st.integers(0, 1)).map(lambda op: [op])
    if kind == "png":
        return (st.tuples(st.just("ihdr"), dims)
                | st.tuples(st.just("tiff"), dims, st.sampled_from(("strips", "tiles", "small tiles")))).map(
                    lambda op: [op])
    return st.tuples(st.sampled_from(("npy", "envi", "mat")), dims, st.sampled_from(CUBE_BANDS),
                     st.sampled_from(("tiny", "sparse"))).map(lambda op: [op])


def _second_round_case(seeds: Seeds, kind: str, family: str, ops, choice: int) -> Case:
    op = ops[0]
    if family == "special":
        return special_case(seeds, kind, op[1], op[2], choice)
    if family == "controls":
        return controls_case(seeds, kind, op[1], op[2], op[3], choice)
    return headers_case(seeds, kind, op)


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
    """Write ``case``'s files into ``root/in`` (``{ROOT}`` and ``{IN}`` replaced) and make its special files;
    returns (input, output) folders. The output folder, ``root/a/b/c/out``, is not made (the command makes it)
    unless a special file goes into it."""
    inp = root / "in"
    out = root / "a" / "b" / "c" / "out"
    out.parent.mkdir(parents=True, exist_ok=True)
    for name, body in case.files.items():
        special = case.specials.get(name)
        if special is not None and not special.startswith("sparse"):  # the special file takes the file's place
            continue
        path = inp / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(body, str):
            body = body.replace("{ROOT}", str(root)).replace("{IN}", str(inp)).encode("utf-8", "surrogatepass")
        path.write_bytes(body)
    for name, kind in case.specials.items():
        path = out / name.removeprefix("{OUT}/") if name.startswith("{OUT}/") else inp / name
        path.parent.mkdir(parents=True, exist_ok=True)
        make_special(path, kind)
    return inp, out


#: The special files a case can name where camsim reads a file (:func:`make_special`): each blocks, never ends,
#: cannot be read or is no file, and must be refused on one line before a byte is read.
SPECIAL_FILES = ("fifo", "/dev/zero", "/dev/null", "dir", "socket", "loop", "sparse")
#: Size of a ``sparse`` special file: holes, no disk blocks, 8 GiB to a reader that reads it. Unit: bytes.
SPARSE_BYTES = 2**33


def make_special(path: Path, kind: str) -> None:
    """Make the special file ``kind`` at ``path``: ``fifo`` (a named pipe: opening it to read waits for a writer),
    ``socket`` (a bound UNIX socket's file), ``dir`` (an empty folder), ``/dev/...`` (a symbolic link to that
    character device: ``/dev/zero`` never ends, ``/dev/null`` is empty), ``loop`` (a symbolic link to itself),
    ``sparse`` or ``sparse:N`` (the file, or an empty one, extended with holes to :data:`SPARSE_BYTES` or ``N``
    bytes: huge to a reader, free on disk)."""
    name, _, size = kind.partition(":")
    if name == "fifo":
        os.mkfifo(path)
    elif name == "dir":
        path.mkdir()
    elif name == "socket":  # bound by a relative name: a socket's path may hold at most 107 bytes
        here = os.getcwd()
        server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            os.chdir(path.parent)
            server.bind(path.name)
        finally:
            os.chdir(here)
            server.close()  # the file stays; connecting to it is refused
    elif name.startswith("/dev/"):
        path.symlink_to(name)
    elif name == "loop":
        path.symlink_to(path.name)
    elif name == "sparse":
        with open(path, "ab") as handle:
            handle.truncate(int(size) if size else SPARSE_BYTES)
    else:
        raise ValueError(kind)


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


def raw_controls(result: Result) -> bool:
    """Whether stderr holds a control character as it is (NUL, ESC, DEL, ...; a tab aside): a path printed without
    escaping, which a terminal may obey. Line ends split lines, so a ``\\n`` or ``\\r`` shows as ``multiline``."""
    return any(ord(ch) < 32 and ch != "\t" or ord(ch) == 127 for line in result.stderr for ch in line)


def noisy_success(result: Result) -> bool:
    """Exit 0 with stderr lines that are not camsim's own (``camsim: warning: ...``): a library's warning."""
    return result.rc == 0 and any(not line.startswith("camsim:") for line in result.stderr)
