"""Hostile sidecars (issue 24, point 2): a real rendered frame's sidecar, each key in turn set to null, a string,
NaN, ±Infinity, 1e308 or a 5000-digit integer, or deleted, and JSON nested 100 000 deep; beside a good frame,
through ``main(["analyze", ...])`` in process. Each case: exit 0 with the good frame analysed and the bad frame
either measured or skipped on one warning line (or with --strict exit 2 on one error line), no traceback,
``analysis.json`` strict JSON (no NaN), in well under two seconds of CPU time. The same edits in an EXR header's
embedded sidecar (``camsim:metadata``)."""

import contextlib
import io
import json
import re
import shutil
import signal
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from camsim.analysis.analyze import non_finite
from camsim.cli import main
from camsim.io.exr import read_exr, write_exr
from camsim.render.run import render_scene
from tests.support.helpers import small_scene

GOOD = "test_D65_F1"
#: CPU time per case (:func:`time.process_time`, which a busy machine does not stretch): well under it in practice
#: (measured: about 0.02–0.1 s). Unit: s.
LIMIT_S = 2.0
SENTINEL = "@@hostile@@"
#: Single-value edits: name → the JSON text that replaces the value (None: the key is deleted).
EDITS = {
    "null": "null",
    "string": '"x"',
    "nan": "NaN",
    "infinity": "Infinity",
    "-infinity": "-Infinity",
    "1e308": "1e308",
    "5000-digit": "9" * 5000,
    "deleted": None,
}
DEEP = "[" * 100_000 + "]" * 100_000


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    root = tmp_path_factory.mktemp("hostile")
    render_scene(small_scene(width=64, height=48, intensity_factors=(1.0,)), root, progress=False)
    return root


def key_paths(meta: dict) -> list[tuple]:
    """Every key of the sidecar: the top level's, and inside objects and the first element of lists of objects
    (``("patches", 0, "signal_e")``, ``("stages", "read_noise")``)."""
    paths = []

    def walk(value, prefix):
        if isinstance(value, dict):
            for key, item in value.items():
                paths.append((*prefix, key))
                walk(item, (*prefix, key))
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            walk(value[0], (*prefix, 0))

    walk(meta, ())
    return paths


def edited_text(meta: dict, path: tuple, replacement: str | None) -> str:
    """The sidecar's JSON text with the value at ``path`` replaced by the raw JSON ``replacement`` (or deleted)."""
    meta = json.loads(json.dumps(meta))
    parent = meta
    for key in path[:-1]:
        parent = parent[key]
    if replacement is None:
        del parent[path[-1]]
        return json.dumps(meta)
    parent[path[-1]] = SENTINEL
    return json.dumps(meta).replace(json.dumps(SENTINEL), replacement)


def _reject_constant(name):
    raise ValueError(f"analysis.json holds {name}")


@contextmanager
def _deadline(seconds):
    """Fail a case that runs away (e.g. ``2**int(1e308)``) instead of hanging the suite: after ``seconds`` of this
    process's CPU time (``ITIMER_PROF``), not of wall time."""
    def stop(signum, frame):
        raise TimeoutError(f"ran past {seconds} s of CPU time")

    previous = signal.signal(signal.SIGPROF, stop)
    signal.setitimer(signal.ITIMER_PROF, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, previous)


def _frame_folder(rendered, folder, kinds=(".dng", ".json", ".exr")):
    """``folder`` with the good frame as ``a_good`` and a copy as ``b_bad`` (sidecars claiming their names)."""
    folder.mkdir()
    for stem in ("a_good", "b_bad"):
        for kind in kinds:
            shutil.copy(rendered / f"{GOOD}{kind}", folder / f"{stem}{kind}")
        meta = json.loads((folder / f"{stem}.json").read_text())
        meta["files"] = {"dng": f"{stem}.dng", "exr": f"{stem}.exr", "json": f"{stem}.json"}
        (folder / f"{stem}.json").write_text(json.dumps(meta))
    return json.loads((folder / "b_bad.json").read_text())


def analyse(folder, out, capsys, source="dng", strict=False, deadline_s=20):
    """``camsim analyze`` on ``folder``; returns (exit status, stderr lines, CPU seconds, analysis.json or None),
    after checking that nothing printed a traceback."""
    argv = ["analyze", str(folder), "--out", str(out), "--source", source, "-q", "--no-figures"]
    start = time.process_time()
    with _deadline(deadline_s):
        status = main(argv + (["--strict"] if strict else []))
    seconds = time.process_time() - start
    captured = capsys.readouterr()
    err = [line for line in captured.err.splitlines() if line]
    assert "Traceback" not in captured.err + captured.out
    summary = None
    if status == 0:
        summary = json.loads((out / "analysis.json").read_text(), parse_constant=_reject_constant)
    return status, err, seconds, summary


def check_bad_frame(summary, err, bad, source="dng"):
    """The bad frame ``bad`` (its path), beside the good one, either measured with nothing said about it, ignored
    as uncommitted on one line naming it (its sidecar no longer claims it: ``files``), or skipped on one line naming
    it; ``err`` are the lines about it. Returns which: ``measured``, ``ignored`` or ``skipped``."""
    files = {f["frame_file"] for f in summary["frames"]}
    if str(bad) in files:  # measured: the edit was harmless (e.g. a string scene name)
        assert err == [], err
        return "measured"
    assert len(err) == 1, err
    if err[0].startswith("camsim: warning: ignored "):
        assert bad.name in err[0] and str(bad.parent) in err[0], err
        assert str(bad) in summary["uncommitted"]
        return "ignored"
    # the frame file or its sidecar, named
    assert err[0].startswith("camsim: warning: skipped "), err
    named = Path(err[0].split()[3].rstrip(":"))
    assert named.parent == bad.parent and named.stem == bad.stem, err
    assert str(named) in [s["file"] for s in summary["skipped"]]
    return "skipped"


def run_case(folder, out, capsys, source="dng", strict=False):
    """Analyse ``folder`` (``a_good`` and ``b_bad``); returns (exit status, stderr lines, CPU seconds), after
    checking the common properties."""
    status, err, seconds, summary = analyse(folder, out, capsys, source, strict)
    if strict:
        assert status in (0, 2), status
        if status == 2:
            assert len(err) == 1 and err[0].startswith("camsim: error: ") and "b_bad" in err[0], err
            assert not out.exists()
    else:
        assert status == 0, err
        assert str(folder / f"a_good.{source}") in {f["frame_file"] for f in summary["frames"]}
        check_bad_frame(summary, err, folder / f"b_bad.{source}", source)
    return status, err, seconds


def _edits(meta) -> list[tuple[str, tuple | None, str | None]]:
    """Every case: (name, the key's path or None for the whole file, the raw JSON that replaces its value)."""
    edits = [(f"{'.'.join(map(str, path))}={edit}", path, text) for path in key_paths(meta)
             for edit, text in EDITS.items()]
    edits.append(("whole-file=deep", None, DEEP))
    edits.append(("patches=deep", ("patches",), DEEP))
    edits.append(("scale=deep", ("scale",), DEEP))
    edits.append(("scale=900-deep", ("scale",), "[" * 900 + "]" * 900))
    return edits


def _case_text(meta, path, replacement) -> str:
    return replacement if path is None else edited_text(meta, path, replacement)


def _cases(meta):
    """Every case as (name, the bad frame's sidecar text)."""
    return [(name, _case_text(meta, path, replacement)) for name, path, replacement in _edits(meta)]


def _write_cases(rendered, folder, edits) -> list[Path]:
    """Each case in a folder of its own under ``folder`` (``caseNNNN/b_bad.dng`` and its edited sidecar), beside
    the good frame (``folder/a_good``); returns the bad frames' paths. Each case's sidecar names a scene and a
    sensor seed of its own before its edit (an edit changes one key at most), so that no two frames are ever one
    sequence to the temporal analysis: each is analysed as it would be beside the good frame alone."""
    meta = _frame_folder(rendered, folder, kinds=(".dng", ".json"))
    (folder / "b_bad.dng").unlink()
    (folder / "b_bad.json").unlink()
    bad = []
    for index, (_, path, replacement) in enumerate(edits):
        case = folder / f"case{index:04d}"
        case.mkdir()
        shutil.copy(folder / "a_good.dng", case / "b_bad.dng")
        own = {**meta, "scene": f"{meta['scene']}-case{index:04d}", "sensor_seed": 10_000 + index}
        (case / "b_bad.json").write_text(_case_text(own, path, replacement))
        bad.append(case / "b_bad.dng")
    return bad


@pytest.fixture(scope="module")
def every_edit(rendered, tmp_path_factory):
    """Every case at once, each its own bad frame in a folder of its own beside the good frame, analysed in one run
    (without --strict): the cases, their frames, and the run's exit status, stderr lines, CPU time and summary."""
    root = tmp_path_factory.mktemp("every-edit")
    cases = _edits(_frame_folder(rendered, root / "first", kinds=(".dng", ".json")))
    bad = _write_cases(rendered, root / "frames", cases)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as stderr:
        start = time.process_time()
        with _deadline(LIMIT_S * len(cases)):
            status = main(["analyze", str(root / "frames"), "--out", str(root / "out"), "-q", "--no-figures"])
        seconds = time.process_time() - start
    err = [line for line in stderr.getvalue().splitlines() if line]
    summary = json.loads((root / "out" / "analysis.json").read_text(), parse_constant=_reject_constant) \
        if status == 0 else None
    about, other = {path: [] for path in bad}, []  # the lines that name the folder of exactly one case, by case
    for line in err:
        named = {m.group(1) for m in re.finditer(r"/frames/(case\d{4})\b", line)}
        (about[root / "frames" / named.pop() / "b_bad.dng"] if len(named) == 1 else other).append(line)
    return {"root": root, "cases": cases, "bad": bad, "status": status, "err": err, "seconds": seconds,
            "summary": summary, "about": about, "other": other}


@pytest.mark.slow
def test_every_single_field_edit_of_a_sidecar_is_measured_or_skipped_cleanly(every_edit):
    """Exit 0, no traceback, the good frame analysed, every bad frame measured or told about on exactly one line of
    its own."""
    cases, bad, err, summary = every_edit["cases"], every_edit["bad"], every_edit["err"], every_edit["summary"]
    assert len(cases) > 400  # every key of a real sidecar, 8 edits each
    assert every_edit["status"] == 0, err[:5]
    assert not any("Traceback" in line for line in err)
    frames = every_edit["root"] / "frames"
    assert str(frames / "a_good.dng") in {f["frame_file"] for f in summary["frames"]}
    assert every_edit["other"] == []  # each line names the folder of exactly one case
    outcomes = []
    for (name, _, _), path in zip(cases, bad):
        try:
            outcomes.append(check_bad_frame(summary, every_edit["about"][path], path))
        except AssertionError as exc:
            raise AssertionError(f"case {name}: {exc}") from None
    assert outcomes.count("measured") < len(cases) // 2  # most edits make a bad frame
    # measured: about 0.02 s a case; each case's own time is judged with --strict
    assert every_edit["seconds"] < LIMIT_S * len(cases) / 10


@pytest.mark.slow
def test_every_single_field_edit_of_a_sidecar_is_refused_or_measured_with_strict(every_edit, rendered, tmp_path,
                                                                                capsys):
    """--strict ends the analysis at the first bad frame. Each case whose frame the analysis skips or ignores, on
    its own beside the good frame: a skipped one exits 2 on one error line naming it, an ignored one 0 or that
    line; within LIMIT_S of CPU time each. The cases whose frame is measured, all in one --strict run: exit 0,
    nothing said, every frame measured (a harmless edit is not fatal)."""
    outcome = {path: check_bad_frame(every_edit["summary"], every_edit["about"][path], path)
               for path in every_edit["bad"]}
    harmless = [case for case, path in zip(every_edit["cases"], every_edit["bad"]) if outcome[path] == "measured"]
    frames = _write_cases(rendered, tmp_path / "harmless", harmless)
    status, lines, seconds, measured = analyse(tmp_path / "harmless", tmp_path / "harmless_out", capsys, strict=True,
                                               deadline_s=LIMIT_S * len(harmless))
    assert status == 0 and lines == [], lines[:5]
    assert {f["frame_file"] for f in measured["frames"]} == {str(p) for p in frames} | {
        str(tmp_path / "harmless" / "a_good.dng")}
    assert seconds < LIMIT_S * len(harmless) / 10
    slow = []
    for index, ((name, path, replacement), frame) in enumerate(zip(every_edit["cases"], every_edit["bad"])):
        if outcome[frame] == "measured":
            continue
        folder = tmp_path / f"case{index}"
        meta = _frame_folder(rendered, folder, kinds=(".dng", ".json"))
        (folder / "b_bad.json").write_text(_case_text(meta, path, replacement))
        try:
            status, _, seconds = run_case(folder, tmp_path / f"out{index}", capsys, strict=True)
            assert status == 2 or outcome[frame] == "ignored", status  # skipped without --strict: fatal with it
        except AssertionError as exc:
            raise AssertionError(f"case {name}: {exc}") from None
        if seconds > LIMIT_S:
            slow.append((name, seconds))
    assert slow == []


#: Edits the issue names, each of which must make the frame bad (skipped with a warning, or --strict's error).
BAD_EDITS = [
    (("bits",), "1e308"),
    (("patches",), "null"),
    (("patches", 0, "signal_e"), None),
    (("stages",), "null"),
    (("read_noise_e",), "null"),
    (("read_noise_e",), '"4"'),
    (("dn_per_electron",), "9" * 5000),
    (("patches", 0, "signal_e"), "[NaN, 1, 2]"),
    (("intensity_factor",), "Infinity"),
    (("black_level_dn",), "[NaN, 0, 0]"),
    (("patches", 0, "rect_xywh"), "[60, 40, 9, 10]"),  # outside the 64 x 48 frame
    (("width_px",), "64.0"),
    (("qe_e_m2_sr_per_photon",), "[[1, 2], [3, 4], [5, 6]]"),
]


@pytest.mark.parametrize("source", ["dng", "exr"])
@pytest.mark.parametrize("path, replacement", BAD_EDITS,
                         ids=[f"{'.'.join(map(str, p))}={'long' if r and len(r) > 20 else r}" for p, r in BAD_EDITS])
def test_the_issues_sidecar_edits_skip_the_frame_on_one_line(rendered, tmp_path, capsys, path, replacement, source):
    meta = _frame_folder(rendered, tmp_path / "frames")
    text = edited_text(meta, path, replacement)
    if source == "dng":
        (tmp_path / "frames" / "b_bad.json").write_text(text)
    else:  # the EXR header's copy of the sidecar (an EXR is read on its own)
        noisy, clean, header = read_exr(tmp_path / "frames" / "b_bad.exr")
        (tmp_path / "frames" / "b_bad.exr").unlink()
        write_exr(tmp_path / "frames" / "b_bad.exr", noisy, clean, {**header, "camsim:metadata": text})
    status, err, seconds = run_case(tmp_path / "frames", tmp_path / "out", capsys, source=source)
    assert status == 0 and len(err) == 1 and "b_bad" in err[0], err
    assert seconds < LIMIT_S
    status, err, _ = run_case(tmp_path / "frames", tmp_path / "out_strict", capsys, source=source, strict=True)
    assert status == 2 and len(err) == 1, err


def test_nesting_100000_deep_is_one_warning_line(rendered, tmp_path, capsys):
    _frame_folder(rendered, tmp_path / "frames")
    (tmp_path / "frames" / "b_bad.json").write_text('{"files": {"dng": "b_bad.dng"}, "x": ' + DEEP + "}")
    status, err, seconds = run_case(tmp_path / "frames", tmp_path / "out", capsys)
    assert status == 0 and len(err) == 1 and "nested too deeply" in err[0], err
    assert seconds < LIMIT_S


@pytest.mark.parametrize("value, refused", [("1e300", True), ("1e-300", True), ("1e60", False), ("1e-60", False)])
def test_gains_at_the_sidecars_bounds_give_finite_results_and_beyond_them_a_skip(rendered, tmp_path, capsys, value,
                                                                                refused):
    """Finite values whose products overflow float64 (a gain of 1e300 DN/e⁻, squared; 1 / 1e-300²) are refused
    by the sidecar's bounds (±1e60, positive ≥ 1e-60); at the bounds, in every gain and noise at once, the
    measurement stays finite: analysis.json is strict JSON either way, on at most one warning line. The sensor's
    keys have the schema's own ranges (a full well of at most 10⁸ e⁻, an exposure of at most 10⁶ s): at 1e60 they
    take their largest instead."""
    from camsim.sensor.params import SENSOR_PARAMS

    highest = {p.name: p.high for p in SENSOR_PARAMS}
    meta = _frame_folder(rendered, tmp_path / "frames")
    for key in ("dn_per_electron", "read_noise_e", "row_noise_e", "full_well_e", "exposure_s"):
        meta[key] = highest[key] if value == "1e60" and key in highest else SENTINEL
    (tmp_path / "frames" / "b_bad.json").write_text(json.dumps(meta).replace(json.dumps(SENTINEL), value))
    status, err, _ = run_case(tmp_path / "frames", tmp_path / "out", capsys)
    assert status == 0 and len(err) == int(refused), err
    if refused:
        assert "sidecar key dn_per_electron must be" in err[0]


def test_non_finite_names_the_first_place_of_a_nan_or_infinity():
    assert non_finite({"a": [1.0, {"b": 2}], "c": None}) is None
    assert non_finite({"a": [1.0, {"b": float("nan")}], "c": float("inf")}) == "a[1].b"
    assert non_finite([0, np.float32("-inf")]) == "[1]"


@pytest.mark.parametrize("edit", ["iso=Infinity", "iso=huge", "exposure_s=NaN", "exposure_s=string", "deep"])
def test_calibrate_reads_a_raw_file_beside_a_hostile_sidecar_by_its_own_tags(rendered, tmp_path, edit):
    """``camsim calibrate``'s raw reader takes ISO and exposure from a camsim sidecar beside the file where the
    file has none: a sidecar value that is no finite number says nothing, and unparsable JSON is no sidecar."""
    from camsim.calibration.rawfiles import read_raw

    meta = _frame_folder(rendered, tmp_path / "frames", kinds=(".dng", ".json"))
    key, _, value = edit.partition("=")
    text = {"Infinity": "Infinity", "huge": "9" * 400, "NaN": "NaN", "string": '"1"'}.get(value)
    sidecar = tmp_path / "frames" / "b_bad.json"
    sidecar.write_text(DEEP if edit == "deep" else edited_text(meta, (key,), text) if key in meta
                       else edited_text({**meta, key: None}, (key,), text))
    own = read_raw(tmp_path / "frames" / "a_good.dng")
    raw = read_raw(tmp_path / "frames" / "b_bad.dng")
    assert (raw.iso, raw.exposure_s) == (own.iso, own.exposure_s)


def _lists(meta, prefix=()):
    """The path of every list in ``meta`` (lists inside lists excepted: a row of a matrix is the matrix's)."""
    for key, value in meta.items():
        if isinstance(value, list):
            yield (*prefix, key)
        elif isinstance(value, dict):
            yield from _lists(value, (*prefix, key))


@pytest.mark.slow
def test_every_list_of_a_sidecar_repeated_is_skipped_in_moments(rendered, tmp_path, capsys):
    """A crafted sidecar whose list is its own items 10³ times over (24 000 patches in a 64 × 48 frame; each other
    list of the frame's sidecar likewise, past every bound; ``tools/fuzz_cli.py`` repeats them 10⁵ times, where the
    patches' 914 MB meet the size limit first: :func:`test_a_sidecar_over_the_limit_is_refused_before_it_is_read`):
    bounded by the frame it describes before any item is looked at, so the frame is skipped on one line within the
    case's CPU budget, not analysed for minutes. A list the readers do not use (``channels``, a record's) costs only its
    parse, and the frame is measured as it was. Every case is a frame of one folder, analysed once."""
    meta = _frame_folder(rendered, tmp_path / "frames")
    paths = list(_lists(meta))
    bad = {}
    for index, path in enumerate(paths):
        stem = f"c{index:02d}"
        edited = json.loads(json.dumps(meta))
        edited["files"] = {kind: f"{stem}.{kind}" for kind in ("dng", "exr", "json")}
        target = edited
        for key in path[:-1]:
            target = target[key]
        items = json.dumps(target[path[-1]])[1:-1]  # the list's text repeated, not the list: a second, not twenty
        target[path[-1]] = SENTINEL
        repeated = "[" + ", ".join([items] * 1000) + "]"
        for kind in ("dng", "exr"):
            shutil.copy(rendered / f"{GOOD}.{kind}", tmp_path / "frames" / f"{stem}.{kind}")
        (tmp_path / "frames" / f"{stem}.json").write_text(json.dumps(edited).replace(json.dumps(SENTINEL), repeated))
        bad[path] = tmp_path / "frames" / f"{stem}.dng"
    status, err, seconds, summary = analyse(tmp_path / "frames", tmp_path / "out", capsys)
    assert status == 0, err
    outcomes = {"measured": [], "skipped": [], "ignored": []}
    for path, frame in bad.items():
        said = [line for line in err if f"{frame.stem}." in line]
        outcomes[check_bad_frame(summary, said, frame)].append(path)
    assert ("patches",) in outcomes["skipped"] and ("wavelengths_nm",) in outcomes["skipped"], outcomes
    assert seconds < len(paths) * LIMIT_S, seconds


def test_a_patch_list_longer_than_the_frame_has_pixels_is_named(rendered, tmp_path, capsys):
    meta = _frame_folder(rendered, tmp_path / "frames")
    meta["patches"] = meta["patches"] * (64 * 48 // len(meta["patches"]) + 1)
    (tmp_path / "frames" / "b_bad.json").write_text(json.dumps(meta))
    status, err, _, _ = analyse(tmp_path / "frames", tmp_path / "out", capsys)
    assert status == 0 and len(err) == 1, err
    assert f"sidecar key patches must be at most one patch per pixel of the 64x48 frame (3072), got a list of " \
           f"{len(meta['patches'])}" in err[0], err


def test_a_sidecar_over_the_limit_is_refused_before_it_is_read(rendered, tmp_path, capsys):
    """A sidecar of 64 MB and one byte (a sparse file: its size is what is judged, from the file system, before
    a byte is read) is skipped on one line; in its EXR header's copy the same limit holds for the text."""
    from camsim.core.errors import CamsimError
    from camsim.render.sidecar_schema import MAX_SIDECAR_BYTES, parse_sidecar

    _frame_folder(rendered, tmp_path / "frames")
    bad = tmp_path / "frames" / "b_bad.json"
    with open(bad, "r+b") as handle:
        handle.truncate(MAX_SIDECAR_BYTES + 1)
    start = time.process_time()
    status, err, seconds, summary = analyse(tmp_path / "frames", tmp_path / "out", capsys)
    assert status == 0 and len(err) == 1 and "over the limit of 64 MB" in err[0], err
    assert time.process_time() - start < LIMIT_S
    with pytest.raises(CamsimError, match="over the limit of 64 MB"):
        parse_sidecar(" " * (MAX_SIDECAR_BYTES + 1), "x.exr")


@pytest.mark.parametrize("kind", ["fifo", "directory", "device"])
def test_a_sidecar_that_is_not_a_regular_file_is_refused_not_read(rendered, tmp_path, capsys, kind):
    """A FIFO by a frame's sidecar's name would block the reader forever (no writer ever comes), a device never
    ends: the frame is not taken (its files are uncommitted: no sidecar claims them), on one line."""
    import os

    _frame_folder(rendered, tmp_path / "frames")
    bad = tmp_path / "frames" / "b_bad.json"
    bad.unlink()
    {"fifo": lambda: os.mkfifo(bad), "directory": bad.mkdir, "device": lambda: bad.symlink_to("/dev/zero")}[kind]()
    status, err, seconds, summary = analyse(tmp_path / "frames", tmp_path / "out", capsys, deadline_s=10)
    assert status == 0 and len(err) == 1 and "b_bad" in err[0], err
    assert str(tmp_path / "frames" / "a_good.dng") in {f["frame_file"] for f in summary["frames"]}


def test_a_sidecar_of_millions_of_values_is_refused_before_it_is_parsed(rendered, tmp_path, capsys):
    """A list the readers do not use, filled with 2.4 × 10⁶ empty lists (7 MB, under the byte limit): refused by
    its count of values before any parse (``analyze`` parses a sidecar up to 7 times), on one line."""
    from camsim.render.sidecar_schema import MAX_SIDECAR_VALUES

    meta = _frame_folder(rendered, tmp_path / "frames")
    meta["channels"] = SENTINEL
    text = json.dumps(meta).replace(json.dumps(SENTINEL), "[" + ", ".join(["[]"] * 2_400_000) + "]")
    (tmp_path / "frames" / "b_bad.json").write_text(text)
    status, err, seconds, summary = analyse(tmp_path / "frames", tmp_path / "out", capsys)
    assert status == 0 and len(err) == 1, err
    assert f"holds about {text.count(',') + 1} values, over the limit of {MAX_SIDECAR_VALUES}" in err[0], err
    assert seconds < LIMIT_S


def test_the_depth_of_a_sidecar_is_judged_as_its_walk_would():
    """The depth judged on the JSON text against a walk of the object (the reference): every nesting of lists and
    objects up to 20 deep, strings holding brackets, and a list of 10⁶ empty lists in well under a second."""
    from camsim.render.sidecar_schema import _too_deep

    def depth(value):
        if isinstance(value, dict):
            return 1 + max(map(depth, value.values()), default=0)
        if isinstance(value, list):
            return 1 + max(map(depth, value), default=0)
        return 0

    rng = np.random.default_rng(3)
    for _ in range(300):
        value = "x[{\"]"
        for _ in range(int(rng.integers(0, 20))):
            value = {"k": value, "s": "]]}"} if rng.random() < 0.5 else [value, 1, "[["]
        for limit in (1, 4, 16):
            assert _too_deep(value, limit) == (depth(value) > limit), (value, limit)
    start = time.process_time()
    assert not _too_deep({"a": [[]] * 1_000_000})
    assert time.process_time() - start < 1.0
