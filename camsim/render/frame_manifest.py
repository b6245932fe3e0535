"""A render folder's ``manifest.json``: at every moment, the frames committed in the folder.

``camsim render`` (and the experiments) update it as each frame commits (:func:`camsim.render.frame_files.write_frame`
renames a frame's sidecar into place last), so a run stopped at any point leaves a manifest that lists exactly
the complete frames. Runs into one folder add to it: it starts from the earlier manifest's entries whose frames
are still committed, adds every committed frame on disk it does not list (a run killed between a frame's commit
and the manifest's update), and a re-rendered frame replaces its entry in place.

Format::

    {"scene": NAME,                 # the scene of the last run into the folder
     "frames": [{"scene", "illuminant", "intensity_factor", "seed", "photon_statistics", "method",
                 "files": {"dng", "exr", "json"[, "xmp"][, "png"]}}, ...]}      # file names relative to the folder
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from pathlib import Path

from camsim.core.errors import CamsimError
from camsim.core.input_files import read_input
from camsim.io.atomic import write_json_atomic
from camsim.render.frame_files import SIDECAR_SUFFIX, FrameInfo
from camsim.render.sidecar_schema import MAX_SIDECAR_BYTES

__all__ = ["MANIFEST_NAME", "MAX_MANIFEST_BYTES", "FrameManifest", "manifest_entry"]

MANIFEST_NAME = "manifest.json"
#: The most bytes of one frame's entry: six keys, its scene's and illuminant's names and up to five file names of
#: up to 200-byte stems (measured: 0.4 kB). Unit: bytes.
_ENTRY_BYTES = 2_000
#: The most frames an earlier manifest is read for: a ``[sequence]`` of its most frames (10 000) and its reference,
#: twice over. Unit: frames.
_LISTED_FRAMES = 20_000
#: The largest earlier manifest read (40 MB); a larger one (or a FIFO, a device in its place) is passed over as an
#: unreadable one is, and the manifest is made again from the committed frames' sidecars. Unit: bytes.
MAX_MANIFEST_BYTES = _ENTRY_BYTES * _LISTED_FRAMES
_ENTRY_KEYS = ("scene", "illuminant", "intensity_factor", "seed", "photon_statistics", "method")


#: A sequence's keys (camsim.render.sequence), in an entry only where its sidecar has them.
_SEQUENCE_ENTRY_KEYS = ("frame_index", "time_s", "sequence_reference")


def manifest_entry(meta: dict) -> dict:
    """A frame's manifest entry, from its sidecar: the keys that tell frames apart (a sequence's frame: also its
    ``frame_index`` and ``time_s``; its reference: ``sequence_reference``), and its files."""
    return {**{key: meta.get(key) for key in _ENTRY_KEYS},
            **{key: meta[key] for key in _SEQUENCE_ENTRY_KEYS if key in meta}, "files": meta["files"]}


def _read_json(path: Path, what: str, max_bytes: int):
    """The JSON value in ``path``, or None where it is not a regular file of at most ``max_bytes`` holding JSON."""
    try:
        return json.loads(read_input(path, what, max_bytes).decode("utf-8"))
    except (CamsimError, OSError, ValueError, RecursionError):  # ValueError: UnicodeDecodeError, JSONDecodeError
        return None


def _committed_sidecar(path: Path) -> dict | None:
    """The sidecar at ``path`` if it is a camsim frame's commit record naming itself, else None."""
    meta = _read_json(path, "sidecar", MAX_SIDECAR_BYTES)
    if not isinstance(meta, dict) or "camsim_version" not in meta or not isinstance(meta.get("files"), dict):
        return None
    return meta if meta["files"].get("json") == path.name else None


class FrameManifest:
    """The manifest of the render folder ``out_dir``, kept on disk as frames commit.

    Parameters
    ----------
    out_dir : path
        The render folder (held by this run: :func:`camsim.io.output_folder.output_folder`).
    scene : str
        The name of the scene being rendered (the manifest's ``scene``).
    """

    def __init__(self, out_dir: str | Path, scene: str):
        self.out_dir = Path(out_dir)
        self.scene = scene
        self.entries: dict[str, dict | None] = {}  # sidecar name → entry (None: being re-written), in order
        self._unwritten = False  # whether the entries changed since the manifest was last written in full
        earlier = _read_json(self.out_dir / MANIFEST_NAME, "manifest", MAX_MANIFEST_BYTES)
        listed = earlier.get("frames") if isinstance(earlier, dict) else None
        for entry in listed if isinstance(listed, list) else ():
            name = entry.get("files", {}).get("json") if isinstance(entry, dict) else None
            if isinstance(name, str) and (self.out_dir / name).is_file():
                self.entries[name] = entry
        self._add_unlisted()

    def _add_unlisted(self) -> bool:
        """Add the committed frames on disk that no entry lists (in name order); returns whether there were any."""
        added = False
        for path in sorted(self.out_dir.glob(f"*{SIDECAR_SUFFIX}")):
            if self.entries.get(path.name) is None and path.name != MANIFEST_NAME:
                meta = _committed_sidecar(path)
                if meta is not None:
                    self.entries[path.name] = manifest_entry(meta)
                    added = True
        return added

    @contextlib.contextmanager
    def kept_on_failure(self) -> Iterator[FrameManifest]:
        """Render into the folder in the block; if the block fails or is interrupted, add to the manifest (and
        write, as far as the disk allows) a frame that committed but was not recorded yet: a signal can land
        between a frame's commit and :meth:`commit`, or inside the manifest's own write (the entry made, the file
        not yet renamed into place)."""
        try:
            yield self
        except BaseException:
            if self._add_unlisted() or self._unwritten:
                with contextlib.suppress(CamsimError):
                    self.write()
            raise

    @property
    def frames(self) -> list[dict]:
        return [entry for entry in self.entries.values() if entry is not None]

    def as_dict(self) -> dict:
        return {"scene": self.scene, "frames": self.frames}

    def write(self) -> Path:
        """Write the manifest (atomically); returns its path."""
        path = self.out_dir / MANIFEST_NAME
        self._unwritten = True
        write_json_atomic(path, self.as_dict())
        self._unwritten = False
        return path

    def withdraw(self, stem: str) -> None:
        """Drop frame ``stem`` before it is re-written (its sidecar is about to go), so the manifest never lists
        a frame that is not committed."""
        name = f"{stem}{SIDECAR_SUFFIX}"
        if self.entries.get(name) is not None:
            self._unwritten = True
            self.entries[name] = None  # keeps its place for the new entry
            self.write()

    def commit(self, info: FrameInfo, files: dict) -> None:
        """Add (or replace in place) the frame ``info`` that has just committed with ``files``, and write the
        manifest."""
        self.commit_entry(manifest_entry({**{key: getattr(info, key) for key in _ENTRY_KEYS}, **(info.sequence or {}),
                                          "files": files}))

    def commit_entry(self, entry: dict) -> None:
        """Add (or replace in place) a frame's entry (:func:`manifest_entry` of its sidecar) that has just
        committed, and write the manifest."""
        self._unwritten = True  # before the entry: a signal may land between any two lines
        self.entries[entry["files"]["json"]] = entry
        self.write()
