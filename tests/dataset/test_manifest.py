"""A dataset's records read back (camsim.dataset.manifest): the manifest line by line, within its limits; a
``.done`` record, a listed file or a Zarr store's metadata that is not a regular file (a FIFO, a device) counts as
no record, is never waited on; a render folder's manifest.json and sidecars likewise (camsim.render.frame_manifest).
"""

import json
from pathlib import Path

import pytest

from camsim.core.errors import CamsimError
from camsim.dataset import manifest as manifest_mod
from camsim.dataset.manifest import (
    MANIFEST_NAME,
    MAX_MANIFEST_BYTES,
    MAX_RECORD_BYTES,
    frame_record,
    read_manifest,
    sha256_file,
)
from tests.support.hostile_files import no_hang, not_regular, one_error_line

RECORD = {"id": "00000-abc", "seed": 7, "files": {"exr": {"name": "frames/00000-abc.exr", "bytes": 3}}}


def write_manifest_lines(folder: Path, *lines: str) -> Path:
    folder.mkdir(exist_ok=True)
    (folder / MANIFEST_NAME).write_text("".join(f"{line}\n" for line in lines), encoding="utf-8")
    return folder


def test_the_limits_are_in_proportion_to_what_they_hold():
    """A record: a frame's 64 kB and 2 kB per frame of the longest burst (10 000 frames); the manifest: 4 kB a line
    for the most frames a spec declares."""
    from camsim.dataset.spec_parts import MAX_FRAMES
    from camsim.scene.sequence import MAX_FRAMES as MAX_BURST_FRAMES

    assert MAX_RECORD_BYTES == 64_000 + 2_000 * MAX_BURST_FRAMES
    assert MAX_MANIFEST_BYTES == 4_000 * MAX_FRAMES


def test_records_read_back_line_by_line(tmp_path):
    folder = write_manifest_lines(tmp_path / "ds", json.dumps(RECORD), "", json.dumps({**RECORD, "seed": 8}))
    assert read_manifest(folder) == [RECORD, {**RECORD, "seed": 8}]


@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_a_manifest_that_is_no_regular_file_is_refused_not_waited_on(tmp_path, kind):
    folder = tmp_path / "ds"
    folder.mkdir()
    not_regular(folder / MANIFEST_NAME, kind)
    with no_hang(f"read_manifest of a {kind}"), pytest.raises(CamsimError, match="not a regular file"):
        read_manifest(folder)


def test_a_manifest_over_its_limit_is_refused_before_a_byte_is_read(tmp_path, monkeypatch):
    """Judged by its size from the file system (a sparse file here), before it is read."""
    folder = tmp_path / "ds"
    folder.mkdir()
    monkeypatch.setattr(manifest_mod, "MAX_MANIFEST_BYTES", 1000)
    with open(folder / MANIFEST_NAME, "wb") as handle:
        handle.truncate(1001)
    with pytest.raises(CamsimError, match="over the limit of 1 kB for a dataset manifest"):
        read_manifest(folder)


def test_a_line_over_the_record_limit_is_refused_without_reading_on(tmp_path, monkeypatch):
    monkeypatch.setattr(manifest_mod, "MAX_RECORD_BYTES", 100)
    folder = write_manifest_lines(tmp_path / "ds", json.dumps(RECORD), " " * 200)
    with pytest.raises(CamsimError, match=r"line 2 is over the limit of 100 bytes for a frame's record"):
        read_manifest(folder)


def test_more_lines_than_a_dataset_has_frames_are_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(manifest_mod, "MAX_FRAMES", 2)
    folder = write_manifest_lines(tmp_path / "ds", *[json.dumps(RECORD)] * 3)
    with pytest.raises(CamsimError, match="lists more than 2 frames"):
        read_manifest(folder)


@pytest.mark.parametrize("line, reason", [("{\"id\": ", "JSONDecodeError"), ("[1, 2]", "a JSON object"),
                                          ("\"\\ud800\" \xff", "JSONDecodeError"), ("[" * 100_000, "")])
def test_a_line_that_is_no_record_is_one_line_naming_it(tmp_path, line, reason):
    folder = write_manifest_lines(tmp_path / "ds", json.dumps(RECORD), line)
    with pytest.raises(CamsimError) as exc:
        read_manifest(folder)
    message = str(exc.value)
    assert "\n" not in message and "line 2 is not a frame's record" in message and reason in message, message


@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_a_done_record_that_is_no_regular_file_is_no_record(tmp_path, kind):
    """The frame is then rendered again (its record is written by an atomic rename, over whatever is there)."""
    path = not_regular(tmp_path / "x.done", kind)
    with no_hang(f"frame_record of a {kind}"):
        assert frame_record(path, None, ()) is None


def test_a_done_record_over_its_limit_is_no_record(tmp_path, monkeypatch):
    monkeypatch.setattr(manifest_mod, "MAX_RECORD_BYTES", 10)
    path = tmp_path / "x.done"
    path.write_text(json.dumps(RECORD), encoding="utf-8")
    assert frame_record(path, None, ()) is None


def test_a_listed_file_that_became_a_fifo_is_refused_not_hashed(tmp_path):
    path = not_regular(tmp_path / "x.exr", "fifo")
    with no_hang("sha256_file of a FIFO"), pytest.raises(CamsimError, match="FIFO"):
        sha256_file(path)


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_store_whose_metadata_is_no_regular_file_holds_no_srgb(tmp_path, kind):
    from camsim.dataset.zarr_store import STORE_NAME, held_srgb

    (tmp_path / STORE_NAME).mkdir()
    not_regular(tmp_path / STORE_NAME / "zarr.json", kind)
    with no_hang(f"held_srgb of a {kind}"):
        assert held_srgb(tmp_path) is None


@pytest.mark.parametrize("name", ["manifest.json", "stray.json"])
def test_a_render_into_a_folder_with_a_fifo_json_is_not_blocked(tmp_path, capfd, name):
    """A render reads the folder's earlier manifest.json and every *.json (the committed frames' sidecars) to make
    its manifest: a FIFO there is passed over as an unreadable file is, not waited on. The manifest's FIFO is
    replaced by the new manifest (an atomic rename); a stray FIFO stays."""
    from camsim.cli import main

    out = tmp_path / "out"
    out.mkdir()
    not_regular(out / name, "fifo")
    with no_hang(f"render into a folder with a FIFO {name}"):
        status = main(["render", "macbeth_26", "--size", "48x32", "--illuminant", "D65", "--intensity", "1", "-q",
                       "--workers", "1", "--out", str(out)])
    assert status == 0, capfd.readouterr().err
    listed = json.loads((out / "manifest.json").read_text(encoding="utf-8"))["frames"]
    assert [entry["files"]["json"] for entry in listed] == ["macbeth_26_D65_F1.json"]


def test_an_earlier_render_manifest_over_its_limit_is_made_again_from_the_sidecars(tmp_path, monkeypatch):
    from camsim.render import frame_manifest
    from camsim.render.frame_manifest import FrameManifest

    out = tmp_path / "out"
    out.mkdir()
    entry = {"scene": "s", "files": {"json": "a.json"}}
    (out / "a.json").write_text(json.dumps({"camsim_version": "x", "files": {"json": "a.json"}}), encoding="utf-8")
    (out / "manifest.json").write_text(json.dumps({"scene": "s", "frames": [entry]}), encoding="utf-8")
    assert FrameManifest(out, "s").frames == [entry]  # the earlier manifest's entry, as it was
    monkeypatch.setattr(frame_manifest, "MAX_MANIFEST_BYTES", 10)
    (rebuilt,) = FrameManifest(out, "s").frames  # passed over: the entry is made again from the sidecar
    assert rebuilt["files"] == {"json": "a.json"} and rebuilt["scene"] is None


def test_pairs_refuse_a_manifest_line_that_is_no_record_on_one_line(tmp_path, capfd):
    """The reader of written datasets (camsim.pairs.WrittenPairs) goes through read_manifest."""
    from camsim.pairs import WrittenPairs

    write_manifest_lines(tmp_path / "ds", "not json")
    with pytest.raises(CamsimError) as exc:
        WrittenPairs(tmp_path / "ds")
    assert "line 1 is not a frame's record" in one_error_line(f"camsim: error: {exc.value}\n")
