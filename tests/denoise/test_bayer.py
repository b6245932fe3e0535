"""``camsim denoise-eval`` on Bayer frames (issue 26, point 1): a small ``sony-a7s2`` ISO 12800 dataset is scored
frame by frame; the identity denoiser's raw PSNR is recomputed here from the files alone (OpenEXR and tifffile, this
file's own normalisation and PSNR formula); what a denoiser receives (packed planes or the mosaic) is checked against
the files; a denoiser returning the wrong shape is one line."""

import csv
import json
import math
import sys
import textwrap

import numpy as np
import pytest

from camsim.cli import main
from tests.support.helpers import ROOT

pytestmark = pytest.mark.slow  # CLI runs on a rendered dataset (about 7 s in all)

N_FRAMES = 3
WIDTH, HEIGHT = 128, 96

SPEC = """\
name = "bayer_small"
scene = "macbeth_26"
seed = 7
repeats = 1
[images]
folder = "{images}"
crop = [{width}, {height}]
[fixed]
preset = "sony-a7s2"
iso = 12800
method = "poisson"
statistics = "pixel"
[grid]
illuminants = ["D65"]
[random]
count = {count}
intensity_factor = {{ log_uniform = [1e-3, 0.1] }}
"""

# A user's denoisers: they record what they were given, and filter each plane with the same 3 × 3 box, so that
# the packed and the mosaic routes must give the same result; ``wrong_shape`` drops a row.
USER_MODULE = '''\
import numpy as np

SEEN = []


def _box(plane):
    padded = np.pad(plane, 1, mode="edge")
    h, w = plane.shape
    return sum(padded[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)) / 9.0


def packed(image, sigma_dn):
    SEEN.append(("packed", image.copy(), np.asarray(sigma_dn).copy()))
    return np.stack([_box(image[..., i]) for i in range(image.shape[-1])], axis=-1)


def mosaic(image, sigma_dn):
    SEEN.append(("mosaic", image.copy(), np.asarray(sigma_dn).copy()))
    out = np.empty_like(image)
    for dy in (0, 1):  # an RGGB mosaic's four sites, this module's own packing
        for dx in (0, 1):
            out[dy::2, dx::2] = _box(image[dy::2, dx::2])
    return out


def wrong_shape(image):
    return image[:-1]
'''


def _cli(argv):
    return main(["denoise-eval", *argv])


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("bayer")
    spec = out / "spec.toml"
    spec.write_text(SPEC.format(images=(ROOT / "scenes" / "images").as_posix(), width=WIDTH, height=HEIGHT,
                                count=N_FRAMES))
    assert main(["dataset", str(spec), "--out", str(out / "ds"), "--workers", "1", "-q"]) == 0
    return out / "ds"


@pytest.fixture(scope="module")
def identity(dataset, tmp_path_factory):
    """The identity denoiser scored with the default settings (``--isp-gain white``): the scores' test and the
    ``--isp-gain`` test read this one run."""
    out = tmp_path_factory.mktemp("identity") / "eval"
    assert _cli([str(dataset), "-d", "identity", "--out", str(out), "-q"]) == 0
    return out


@pytest.fixture(scope="module")
def user_module(tmp_path_factory):
    folder = tmp_path_factory.mktemp("user")
    (folder / "bayer_user_denoisers.py").write_text(USER_MODULE)
    sys.path.insert(0, str(folder))
    import bayer_user_denoisers

    yield bayer_user_denoisers
    sys.path.remove(str(folder))
    sys.modules.pop("bayer_user_denoisers", None)


def _frames_csv(out):
    with open(out / "frames.csv", newline="") as file:
        return list(csv.DictReader(file))


def _exr_frame(path):
    """The noisy mosaic, the clean layer and the sidecar of a camsim EXR, read with OpenEXR alone."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as exr:
        channels = {k: np.array(v.pixels, dtype=np.float64) for k, v in exr.channels().items()}
        meta = json.loads(exr.header()["camsim:metadata"])
    clean = np.stack([channels[f"clean.{c}"] for c in "RGB"])
    return channels["noisy.CFA"], clean, meta


def _normalised(noisy, clean, meta):
    """This test's own normalisation: each site's colour from the pattern string, (x − black) / (white − black),
    black the EXR's level before the ADC (``dark_level_dn``) and white the DNG's white level moved into the EXR's
    units: less the offset between the DNG's black level and the EXR's (the pedestal the ADC adds)."""
    pattern = meta["cfa_pattern"]
    black = np.asarray(meta["dark_level_dn"], dtype=np.float64)
    offset = np.mean(np.asarray(meta["black_level_dn"], dtype=np.float64) - black)
    white = float(meta["white_level_dn"]) - offset
    noisy_n, clean_n = np.empty_like(noisy), np.empty_like(noisy)
    colour_of = {}
    for i, letter in enumerate(pattern):
        dy, dx = divmod(i, 2)
        c = "RGB".index(letter)
        colour_of[(dy, dx)] = letter
        noisy_n[dy::2, dx::2] = (noisy[dy::2, dx::2] - black[c]) / (white - black[c])
        clean_n[dy::2, dx::2] = (clean[c, dy::2, dx::2] - black[c]) / (white - black[c])
    return noisy_n, clean_n, colour_of


def test_every_bayer_frame_is_scored_and_identity_raw_psnr_matches_the_files(dataset, identity):
    out = identity
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames_scored"] == N_FRAMES and summary["frames_scored_bayer"] == N_FRAMES
    assert summary["skipped"] == []
    rows = _frames_csv(out)
    assert len(rows) == N_FRAMES
    exrs = sorted((dataset / "frames").glob("*.exr"))
    assert len(exrs) == N_FRAMES
    for exr in exrs:
        (row,) = [r for r in rows if r["file"].endswith(exr.name)]
        assert row["frame_kind"] == "Bayer RGGB" and row["scored_as"] == "developed sRGB"
        noisy, clean, meta = _exr_frame(exr)
        assert noisy.shape == (HEIGHT, WIDTH)
        # The EXR's mosaic is the DNG's before quantisation: the DNG (tifffile) is floor(x + ½) + pedestal, clipped.
        import tifffile

        dng = tifffile.imread(exr.with_suffix(".dng")).astype(np.float64)
        expected = np.clip(np.floor(noisy + 0.5) + meta["pedestal_dn"], 0, meta["white_level_dn"])
        assert np.mean(dng == expected) > 0.999  # (float32 ties at .5 may round either way)
        noisy_n, clean_n, colour_of = _normalised(noisy, clean, meta)
        # ... and normalised as raw converters normalise the DNG, (DN − BlackLevel) / (WhiteLevel − BlackLevel),
        # it gives the same values but for the rounding: within ½ DN (and ties)
        dng_black = np.asarray(meta["black_level_dn"], dtype=np.float64)
        for i, letter in enumerate(meta["cfa_pattern"]):
            dy, dx = divmod(i, 2)
            b = dng_black["RGB".index(letter)]
            dng_n = (dng[dy::2, dx::2] - b) / (meta["white_level_dn"] - b)
            assert np.quantile(np.abs(dng_n - noisy_n[dy::2, dx::2]), 0.999) <= 0.5 / (meta["white_level_dn"] - b)
        mse = np.mean((noisy_n - clean_n) ** 2)
        psnr = 10 * math.log10(1.0 / mse)  # data range 1: the white level
        assert float(row["raw_psnr_noisy_db"]) == pytest.approx(psnr, abs=1e-4)
        assert float(row["raw_psnr_denoised_db"]) == pytest.approx(psnr, abs=1e-4)
        assert float(row["raw_psnr_gain_db"]) == 0.0
        # per plane: R is the site whose colour is R; G1 the green on R's row
        (r_site,) = [s for s, c in colour_of.items() if c == "R"]
        (g1_site,) = [s for s, c in colour_of.items() if c == "G" and s[0] == r_site[0]]
        for name, (dy, dx) in (("R", r_site), ("G1", g1_site)):
            plane_mse = np.mean((noisy_n[dy::2, dx::2] - clean_n[dy::2, dx::2]) ** 2)
            assert float(row[f"raw_psnr_{name}_noisy_db"]) == pytest.approx(10 * math.log10(1 / plane_mse), abs=1e-4)
        # the true noise σ per plane, normalised
        assert float(row["raw_noise_std_R"]) == pytest.approx(
            np.std(noisy_n[r_site[0]::2, r_site[1]::2] - clean_n[r_site[0]::2, r_site[1]::2]), rel=1e-4)
        for key in ("srgb_psnr_denoised_db", "srgb_ssim_denoised", "srgb_delta_e00_denoised"):
            assert row[key] == row[key.replace("denoised", "noisy")] != ""  # identity: the noisy baseline
        assert row["psnr_denoised_db"] == row["srgb_psnr_denoised_db"]  # the generic columns: after the ISP
        assert row["data_range_dn"] == "" and row["sigma_est_R_dn"] == ""  # three-chip columns stay empty
    report = (out / "report.md").read_text()
    assert "## Bayer frames: raw and after the ISP" in report and "(H/2, W/2, 4)" in report
    assert (out / "crops_by_band.png").is_file() and (out / "examples.png").is_file()


def test_packed_and_mosaic_inputs_match_the_files_and_each_other(dataset, user_module, tmp_path):
    outs = {}
    for option, function in (("packed", "packed"), ("mosaic", "mosaic")):
        out = tmp_path / option
        user_module.SEEN.clear()
        assert _cli([str(dataset), "-d", f"bayer_user_denoisers:{function}", "-d", "wavelet", "--bayer-input", option,
                     "--out", str(out), "-q"]) == 0
        assert len(user_module.SEEN) == N_FRAMES and all(kind == option for kind, _, _ in user_module.SEEN)
        outs[option] = (_frames_csv(out), list(user_module.SEEN))
    exr = sorted((dataset / "frames").glob("*.exr"))
    noisy_n = {}
    for path in exr:
        noisy, clean, meta = _exr_frame(path)
        noisy_n[path.name] = _normalised(noisy, clean, meta)[0]
    packed_seen = [image for _, image, _ in outs["packed"][1]]
    mosaic_seen = [image for _, image, _ in outs["mosaic"][1]]
    for image in packed_seen:
        assert image.shape == (HEIGHT // 2, WIDTH // 2, 4) and image.dtype == np.float32
    for image in mosaic_seen:
        assert image.shape == (HEIGHT, WIDTH) and image.dtype == np.float32
    # each mosaic given is one of the frames, normalised as this test does; its packing (RGGB) is the packed input
    for packed_image, mosaic_image in zip(packed_seen, mosaic_seen):
        (match,) = [n for n, m in noisy_n.items() if np.allclose(mosaic_image, m, rtol=0, atol=1e-6)]
        mine = np.stack([mosaic_image[0::2, 0::2], mosaic_image[0::2, 1::2], mosaic_image[1::2, 0::2],
                         mosaic_image[1::2, 1::2]], axis=-1)
        assert np.array_equal(mine, packed_image)
    for (_, _, sigma_p), (_, _, sigma_m) in zip(outs["packed"][1], outs["mosaic"][1]):
        assert sigma_p.shape == (4,) and np.array_equal(sigma_p, sigma_m)
    # pack → denoise → unpack: the same scores by either route, for the user's function and for the built-in
    rows_p, rows_m = outs["packed"][0], outs["mosaic"][0]
    for rp, rm in zip(rows_p, rows_m):
        assert rp["file"] == rm["file"]
        for key in ("raw_psnr_denoised_db", "raw_ssim_denoised", "raw_psnr_G2_denoised_db", "srgb_psnr_denoised_db",
                    "srgb_delta_e00_denoised"):
            assert float(rp[key]) == pytest.approx(float(rm[key]), rel=1e-6), key
        assert rp["bayer_input"] == "packed" and rm["bayer_input"] == "mosaic"
    # the built-in wavelet shrinkage on the packed planes removes noise at these light levels (F ≤ 0.1): a higher
    # raw PSNR and a lower ΔE00 after the ISP on every frame (measured 2026-11-25: +0.8 … +1.1 dB)
    wavelet_rows = [r for r in rows_p if r["denoiser"] == "wavelet"]
    assert len(wavelet_rows) == N_FRAMES
    for r in wavelet_rows:
        assert float(r["raw_psnr_gain_db"]) > 0
        assert float(r["srgb_delta_e00_denoised"]) < float(r["srgb_delta_e00_noisy"])


def test_a_denoiser_returning_the_wrong_shape_is_one_line(dataset, user_module, tmp_path, capsys):
    out = tmp_path / "bad"
    assert _cli([str(dataset), "-d", "bayer_user_denoisers:wrong_shape", "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("camsim: error: ")
    assert f"({HEIGHT // 2 - 1}, {WIDTH // 2}, 4)" in err and "(H/2, W/2, 4): packed planes R, G1, G2, B" in err
    assert not (out / "report.md").exists()


@pytest.mark.parametrize("option, channels, shape", [("packed", ["B", "G1", "G2", "R"], (HEIGHT // 2, WIDTH // 2)),
                                                     ("mosaic", ["CFA"], (HEIGHT, WIDTH))])
def test_a_command_denoiser_gets_the_planes_or_the_mosaic(dataset, tmp_path, option, channels, shape):
    """A ``cmd:`` denoiser reads an EXR of channels R, G1, G2, B at half resolution (or CFA at full resolution) and
    writes the same: copying them gives the identity's scores."""
    program = tmp_path / "copy_planes.py"
    program.write_text(textwrap.dedent(f"""\
        import sys
        import OpenEXR
        with OpenEXR.File(sys.argv[1], separate_channels=True) as exr:
            channels = {{k: v.pixels for k, v in exr.channels().items()}}
        assert sorted(channels) == {channels!r}, sorted(channels)
        assert all(v.shape == {shape!r} for v in channels.values())
        OpenEXR.File({{"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage}},
                     channels).write(sys.argv[2])
        """))
    out = tmp_path / "cmd"
    assert _cli([str(dataset), "-d", "identity", "-d", f"cmd:{sys.executable} {program} {{input}} {{output}}",
                 "--bayer-input", option, "--out", str(out), "-q"]) == 0
    rows = _frames_csv(out)
    by_file = {}
    for r in rows:
        by_file.setdefault(r["file"], {})[r["denoiser"]] = r
    assert len(by_file) == N_FRAMES
    for pair in by_file.values():
        ident = pair["identity"]
        (cmd,) = [row for name, row in pair.items() if name.startswith("cmd-")]
        assert cmd["raw_psnr_denoised_db"] == ident["raw_psnr_denoised_db"]
        assert cmd["srgb_delta_e00_denoised"] == ident["srgb_delta_e00_denoised"]



def test_a_command_denoiser_runs_from_the_command_line_on_a_three_chip_frame(tmp_path):
    """The ``cmd:`` denoiser's input EXR lies in a temporary folder, outside the output folder the run holds (where
    camsim's own writes are confined): it is written there all the same, and copying R, G, B gives the identity's
    scores (this failed from the command line before issue 26: "refusing to write …/noisy.exr")."""
    assert main(["render", "macbeth_26", "--size", "96x64", "--intensity", "1", "--illuminant", "D65",
                 "--out", str(tmp_path / "frames"), "-q"]) == 0
    program = tmp_path / "copy_rgb.py"
    program.write_text(textwrap.dedent("""\
        import sys
        import OpenEXR
        with OpenEXR.File(sys.argv[1], separate_channels=True) as exr:
            channels = {k: v.pixels for k, v in exr.channels().items()}
        assert sorted(channels) == ["B", "G", "R"], sorted(channels)
        OpenEXR.File({"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage},
                     channels).write(sys.argv[2])
        """))
    out = tmp_path / "eval"
    command = f"cmd:{sys.executable} {program} {{input}} {{output}}"
    assert _cli([str(tmp_path / "frames"), "-d", "identity", "-d", command, "--out", str(out), "-q"]) == 0
    rows = _frames_csv(out)
    (ident,) = [r for r in rows if r["denoiser"] == "identity"]
    (cmd,) = [r for r in rows if r["denoiser"].startswith("cmd-")]
    assert ident["frame_kind"] == "three-chip" and ident["raw_psnr_noisy_db"] == ""
    assert cmd["psnr_denoised_db"] == ident["psnr_denoised_db"] != ""
    assert cmd["delta_e00_denoised"] == ident["delta_e00_denoised"]


def test_isp_gain_option(dataset, identity, tmp_path, capsys):
    """--isp-gain auto develops as at F = 1 (recorded per frame; the raw scores do not change); a bad value is one
    line."""
    outs = {"white": identity, "auto": tmp_path / "auto"}  # white: the default, which argparse parses as if given
    assert _cli([str(dataset), "-d", "identity", "--isp-gain", "auto", "--out", str(outs["auto"]), "-q"]) == 0
    runs = {}
    for gain, out in outs.items():
        runs[gain] = {r["file"]: r for r in _frames_csv(out)}
        assert {r["isp_gain"] for r in runs[gain].values()} == {gain}
        assert json.loads((out / "summary.json").read_text())["bayer"]["isp_gain"] == gain
    for name, white in runs["white"].items():
        auto = runs["auto"][name]
        assert auto["raw_psnr_noisy_db"] == white["raw_psnr_noisy_db"]
        assert auto["srgb_psnr_noisy_db"] != white["srgb_psnr_noisy_db"]
    capsys.readouterr()
    assert _cli([str(dataset), "-d", "identity", "--isp-gain", "bright", "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--isp-gain: expected white, auto or a positive number" in err
    assert not (tmp_path / "bad").exists()
