"""camsim dataset's sRGB outputs (spec key ``srgb``, ``--srgb``): developed noisy and clean PNGs per frame, listed and
hashed by the manifest, that decode (OpenImageIO, not camsim's writer) to the ISP's development of the EXR's layers;
the clean target developed with the noisy frame's gains and matrix (checked against an independent float64
development of a three-chip frame from the record); the Zarr arrays ``srgb_noisy`` and ``srgb_clean`` with their
shapes and dtypes, holding the PNGs' codes; the same seed giving the same bytes; a re-run adding sRGB outputs to
frames written without them; bad values refused on one line."""

import json

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.dataset import load_spec, read_manifest, run_dataset
from tests.support.helpers import ROOT, file_tree, write_text_file

SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()


def spec_text(name="srgb", cfa='["none", "RGGB"]', srgb='"png"', preset='"emva-12bit"') -> str:
    """2 illuminants × the ``cfa`` list × 1 draw of F: frames of 64 × 48."""
    return f"""
name = "{name}"
scene = "{SCENE}"
seed = 5
{"" if srgb is None else f"srgb = {srgb}"}

[frame]
width = 64
height = 48

[fixed]
preset = {preset}

[grid]
illuminants = ["D65", "A"]
cfa = {cfa}

[random]
count = 1
intensity_factor = {{ log_uniform = [0.01, 0.5] }}
"""


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    folder = tmp_path_factory.mktemp("srgb")
    spec = write_text_file(folder, "srgb.toml", spec_text())
    out = folder / "out"
    summary = run_dataset(spec, out, workers=1, progress=False, echo=None)
    return spec, out, summary


def decode_png(path):
    """A PNG's codes as stored, (3, H, W) uint8 or uint16, decoded by OpenImageIO (libpng), not camsim."""
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(str(path))
    try:
        spec = image.spec()
        kind = {oiio.UINT8: "uint8", oiio.UINT16: "uint16"}[spec.format.basetype]
        pixels = image.read_image(0, 0, 0, spec.nchannels, kind)
    finally:
        image.close()
    assert spec.nchannels == 3
    return np.asarray(pixels).transpose(2, 0, 1)


def _srgb_encode(linear):
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _layers(out, record):
    """The EXR's noisy and clean layers and the sidecar of a frame (camsim's EXR reader)."""
    from camsim.io.exr import read_exr

    noisy, clean, _ = read_exr(out / record["files"]["exr"]["name"])
    meta = json.loads((out / record["files"]["json"]["name"]).read_text())
    return noisy.astype(np.float64), clean.astype(np.float64), meta


def test_the_pngs_are_listed_hashed_and_recorded(written):
    import hashlib

    from camsim.isp import read_png_record

    _, out, summary = written
    assert summary["srgb"] == "png" and summary["rendered"] == 4
    records = read_manifest(out)
    assert len(records) == 4
    for record in records:
        files = record["files"]
        assert files["srgb_noisy"]["name"] == f"frames/{record['id']}_srgb_noisy.png"
        assert files["srgb_clean"]["name"] == f"frames/{record['id']}_srgb_clean.png"
        for layer in ("srgb_noisy", "srgb_clean"):
            path = out / files[layer]["name"]
            assert hashlib.sha256(path.read_bytes()).hexdigest() == files[layer]["sha256"]
            assert path.stat().st_size == files[layer]["bytes"]
            png = read_png_record(path)
            assert png["layer"] == layer and png["isp"] == record["srgb"]["isp"]
        assert record["srgb"]["output"] == "png" and record["srgb"]["bits"] == 8
        stages = record["srgb"]["isp"]["stages"]
        assert stages["gain"]["value"] == pytest.approx(1 / record["intensity_factor"], rel=1e-12)
        if record["cfa"] is None:
            assert stages["demosaic"] is None
        else:
            assert stages["demosaic"]["method"] == "malvar2004"


def test_a_three_chip_frames_pngs_against_an_independent_development(written):
    """Decoded PNG codes / 255 = tone(1/F · M · wb · (layer − dark) / (white − dark)) from the EXR's layers and
    the record's gains and matrix, within one code: the clean target through the same ISP as the noisy frame."""
    _, out, _ = written
    record = next(r for r in read_manifest(out) if r["cfa"] is None)
    noisy, clean, meta = _layers(out, record)
    stages = record["srgb"]["isp"]["stages"]
    gains = np.asarray(stages["white_balance"]["gains"])[:, None, None]
    matrix, gain = np.asarray(stages["matrix"]["matrix"]), stages["gain"]["value"]
    black = np.asarray(meta["dark_level_dn"])[:, None, None]
    # the white of the values before the ADC: 2^nb − 1 less the offset of the quantised black level (the ISP's rule)
    white = float(meta["white_level_dn"]) - np.mean(np.subtract(meta["black_level_dn"], meta["dark_level_dn"]))
    assert np.allclose(stages["black"]["black_dn"], meta["dark_level_dn"])
    for layer, values in (("srgb_noisy", noisy), ("srgb_clean", clean)):
        linear = np.einsum("cj,jhw->chw", matrix, gains * (values - black) / (white - black)) * gain
        expected = _srgb_encode(linear) * 255
        decoded = decode_png(out / record["files"][layer]["name"]).astype(np.float64)
        assert decoded.shape == (3, 48, 64)
        assert np.max(np.abs(decoded - expected)) <= 0.5 + 1e-3  # round to nearest, float32 on the way
    assert record["srgb"]["isp"]["facts"]["intensity_factor"] == record["intensity_factor"]


def test_a_bayer_frames_pngs_decode_to_the_isp_development_of_its_layers(written):
    """The PNGs of a Bayer frame are the ISP's development of the EXR's noisy mosaic and of its clean layer taken at
    the mosaic's sites, with the same facts and settings (decoded by imageio, codes compared exactly)."""
    from camsim.isp import IspSettings, develop_pair, facts_from_meta
    from camsim.isp.writers import encode_image

    _, out, _ = written
    record = next(r for r in read_manifest(out) if r["cfa"] == "RGGB")
    noisy, clean, meta = _layers(out, record)
    mosaic = np.empty(noisy.shape[1:], np.float32)
    for dy, dx, c in ((0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 2)):
        mosaic[dy::2, dx::2] = clean[c, dy::2, dx::2]
    facts = facts_from_meta(meta, quantised=False)
    a, b = develop_pair(noisy[0].astype(np.float32), mosaic, facts, IspSettings(gain="auto"))
    for layer, developed in (("srgb_noisy", a), ("srgb_clean", b)):
        decoded = decode_png(out / record["files"][layer]["name"])
        assert decoded.dtype == np.uint8
        assert np.array_equal(decoded, encode_image(developed.image, 8).transpose(2, 0, 1))
    # the same record, but for the matrix's last bits (the sidecar's QE is a JSON round trip of the frame's)
    got, held = json.loads(json.dumps(a.record)), json.loads(json.dumps(record["srgb"]["isp"]))
    np.testing.assert_allclose(got["stages"]["matrix"].pop("matrix"), held["stages"]["matrix"].pop("matrix"),
                               rtol=1e-12)
    assert got == held


def test_same_seed_same_bytes_and_a_rerun_adds_srgb(written, tmp_path):
    spec, out, _ = written
    again = tmp_path / "again"
    run_dataset(spec, again, workers=1, progress=False, echo=None)
    first, second = file_tree(out / "frames"), file_tree(again / "frames")
    assert sorted(first) == sorted(second)
    assert all(first[name] == second[name] for name in first)  # frame by frame, PNGs included
    # a dataset written without sRGB: a re-run with --srgb renders every frame again and adds the PNGs
    bare = tmp_path / "bare"
    plain = write_text_file(tmp_path, "plain.toml", spec_text(srgb=None))
    assert run_dataset(plain, bare, workers=1, progress=False, echo=None)["srgb"] == "none"
    assert not list((bare / "frames").glob("*.png"))
    summary = run_dataset(plain, bare, workers=1, progress=False, echo=None, srgb="png")
    assert summary["rendered"] == 4 and len(list((bare / "frames").glob("*_srgb_*.png"))) == 8
    assert run_dataset(plain, bare, workers=1, progress=False, echo=None, srgb="png")["rendered"] == 0
    assert run_dataset(plain, bare, workers=1, progress=False, echo=None)["rendered"] == 0  # kept without --srgb


def test_zarr_arrays_hold_the_pngs_codes(tmp_path):
    """A store with ``--srgb png16``: arrays srgb_noisy and srgb_clean, (frame, 3, y, x) uint16, equal to the file
    layout's 16-bit PNGs of the same spec, frame by frame."""
    import zarr

    spec = write_text_file(tmp_path, "bayer.toml", spec_text("bayer", cfa='["RGGB"]', srgb=None))
    files, store = tmp_path / "files", tmp_path / "store"
    run_dataset(spec, files, workers=1, progress=False, echo=None, srgb="png16")
    run_dataset(spec, store, workers=1, progress=False, echo=None, output="zarr", srgb="png16")
    group = zarr.open_group(store / "dataset.zarr", mode="r")
    for name in ("srgb_noisy", "srgb_clean"):
        array = group[name]
        assert array.shape == (2, 3, 48, 64) and array.dtype == np.uint16
        assert array.metadata.dimension_names == ("frame", "channel", "y", "x")
    for record in read_manifest(files):
        for name in ("srgb_noisy", "srgb_clean"):
            decoded = decode_png(files / record["files"][name]["name"])
            assert decoded.dtype == np.uint16
            assert np.array_equal(group[name][record["index"]], decoded)
    stored = read_manifest(store)
    assert [r["srgb"] for r in stored] == [r["srgb"] for r in read_manifest(files)]
    assert all(r["arrays"]["srgb_noisy"]["chunk"].startswith("srgb_noisy/") for r in stored)
    # a re-run that does not name the output keeps the store's; another output is refused
    assert run_dataset(spec, store, workers=1, progress=False, echo=None, output="zarr")["srgb"] == "png16"
    with pytest.raises(CamsimError, match="another layout \\(srgb png16 there, png here\\)"):
        run_dataset(spec, store, workers=1, progress=False, echo=None, output="zarr", srgb="png")


def test_bad_srgb_values_are_refused(tmp_path):
    spec = write_text_file(tmp_path, "bad.toml", spec_text(srgb='"jpeg"'))
    with pytest.raises(CamsimError, match="srgb: sRGB output must be one of none, png, png16, got 'jpeg'"):
        load_spec(spec)
    good = write_text_file(tmp_path, "good.toml", spec_text())
    assert load_spec(good).srgb == "png"
    with pytest.raises(CamsimError, match="sRGB output must be one of"):
        run_dataset(good, tmp_path / "out", workers=1, progress=False, echo=None, srgb="tiff")


def test_the_command_line_option(tmp_path, capsys):
    from camsim.cli import main

    spec = write_text_file(tmp_path, "cli.toml", spec_text("cli", cfa='["RGGB"]', srgb=None))
    assert main(["dataset", str(spec), "--out", str(tmp_path / "o"), "--workers", "1", "-q", "--srgb", "png"]) == 0
    assert len(list((tmp_path / "o" / "frames").glob("*_srgb_clean.png"))) == 2
    capsys.readouterr()
    assert main(["dataset", str(spec), "--srgb", "gif"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: argument --srgb: invalid choice: 'gif'") and err.count("\n") == 1


def test_processes_give_the_serial_runs_bytes(written, tmp_path):
    """Two local processes write the same PNGs (and every other file) as the serial run."""
    spec, out, _ = written
    pooled = tmp_path / "pooled"
    run_dataset(spec, pooled, workers=2, progress=False, echo=None)
    first, second = file_tree(out / "frames"), file_tree(pooled / "frames")
    assert sorted(first) == sorted(second) and all(first[name] == second[name] for name in first)


def test_frames_with_auto_exposure_are_developed_with_a_gain_of_one(tmp_path):
    text = spec_text("auto", cfa='["RGGB"]').replace('preset = "emva-12bit"',
                                                     'preset = "emva-12bit"\nexposure = "auto"')
    spec = write_text_file(tmp_path, "auto.toml", text)
    run_dataset(spec, tmp_path / "out", workers=1, progress=False, echo=None)
    records = read_manifest(tmp_path / "out")
    assert [r["exposure"] for r in records] == ["auto", "auto"]
    assert [r["srgb"]["isp"]["stages"]["gain"]["value"] for r in records] == [1.0, 1.0]


@pytest.mark.slow
def test_a_dask_cluster_sends_the_pngs_back(written, tmp_path):
    """Dask workers render into their own temporary folders and send the files back, PNGs included: the same bytes
    as the serial run."""
    distributed = pytest.importorskip("distributed")
    spec, out, _ = written
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        summary = run_dataset(spec, tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False,
                              echo=None)
    assert summary["rendered"] == 4 and summary["srgb"] == "png"
    first, second = file_tree(out / "frames"), file_tree(tmp_path / "dask" / "frames")
    assert sorted(first) == sorted(second) and all(first[name] == second[name] for name in first)
