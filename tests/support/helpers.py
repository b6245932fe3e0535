"""Helpers the test modules import (``from tests.support.helpers import ...``): the repository root, scene builders,
patch pixels, a one-frame render and an EXR writer that meets a full disk. Fixtures live in ``conftest.py``;
closed forms in ``tests.support.theory``."""

from pathlib import Path

from camsim.light.spectra import WavelengthGrid
from camsim.render.pipeline import light_scene, make_frame
from camsim.scene.chart import ChartGeometry
from camsim.scene.scene_file import Scene
from camsim.scene.sources import ChartSource
from camsim.sensor.camera import load_camera

ROOT = Path(__file__).resolve().parents[2]
WHITE = 18  # "white 9.5 (.05 D)" in ColorChecker order


def write_text_file(folder: Path, name: str, text: str) -> Path:
    """``folder/name`` with ``text`` (UTF-8), the folder made if need be (a dataset spec, a scene file)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def preset_toml(name: str = '"p"', extra: str = "") -> str:
    """The text of a small camera preset file (12 bits, pedestal 64, one ISO point at 100); ``name`` is a TOML
    literal, written as it is, and ``extra`` lines go into its ``[preset]`` table (the hostile-input tests)."""
    return f"""
[preset]
name = {name}
source = "test"
bits = 12
pedestal_dn = 64
{extra}
[[iso]]
iso = 100
k_dn_per_e = 1.0
tukey_lambda = 0.14
tukey_scale_dn = 1.0
gaussian_sigma_dn = 2.0
"""


def flat_scene_toml(name: str = '"flat"', preset: str = '"emva-12bit"') -> str:
    """The text of a small scene file (a 32 × 24 flat field on a 400–700 nm grid, one frame under D65 at F = 0.5);
    ``name`` and ``preset`` are TOML literals, written as they are (the hostile-input tests)."""
    return f"""
name = {name}
[spectral]
start_nm = 400
end_nm = 700
step_nm = 10
[target]
kind = "flat"
reflectance = 0.5
[light]
illuminants = ["D65"]
intensity_factors = [0.5]
luminance_cd_m2 = 100
[frame]
width = 32
height = 24
[sensor]
preset = {preset}
"""


def libraw_black_levels(path: Path) -> list[int]:
    """What LibRaw reports as black level for each BlackLevel value stored in the DNG at ``path``, in file order.

    LibRaw reads each RATIONAL n/d as a double and keeps an integer: it truncates a CFA file's levels
    (``floor(n/d)``) and rounds a LinearRaw file's with halves up (``floor(n/d + 1/2)``). The model works on the
    rational the file stores, in integer arithmetic, not on the float it was made from: a level of
    803.9999999999999 DN is stored as 804/1 (within the writer's 1e-6 DN) and read as 804.
    """
    import tifffile

    with tifffile.TiffFile(path) as tif:
        page = tif.pages.first
        pairs = page.tags[50714].value
        cfa = page.photometric == 32803
    nums, dens = pairs[0::2], pairs[1::2]
    return [n // d if cfa else (2 * n + d) // (2 * d) for n, d in zip(nums, dens)]


def file_tree(out: Path) -> dict:
    """Every file under ``out`` by relative path: its bytes (an output folder, compared whole)."""
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def small_scene(**changes) -> Scene:
    """A ColorChecker scene with large patches, so that each patch gives thousands of samples."""
    base = Scene(
        name="test",
        grid=WavelengthGrid(),
        illuminants=("D65",),
        source=ChartSource(geometry=ChartGeometry(gap_fraction=0.1, margin_fraction=0.02)),
        width=720,
        height=480,
    )
    return base.replace(**changes)


def patch_pixels(image, rect, border=2):
    """Pixels of a patch rectangle (minus a border), shape (C, n) for (C, H, W) input."""
    x, y, w, h = rect
    return image[..., y + border : y + h - border, x + border : x + w - border].reshape(image.shape[0], -1)


def render(scene, sensor=None, factor=1.0, statistics="pixel", method="poisson", seed=1, illuminant="D65"):
    """Render one frame of ``scene``; returns (frame, radiance)."""
    sensor = sensor if sensor is not None else scene.sensor
    lit = light_scene(scene, illuminant, load_camera(scene.camera, scene.grid))
    frame = make_frame(lit, sensor, factor, statistics=statistics, method=method, rng=seed)
    return frame, lit.radiance


def full_disk(monkeypatch, only_suffix: str | None = None):
    """Every atomic write (all of camsim's writers go through one) fails with ENOSPC when it flushes its file,
    as a full disk does; with ``only_suffix``, only files of that suffix."""
    import errno
    import os

    import camsim.io.atomic as atomic

    real = atomic.fsync_path

    def fsync(path, *, directory=False):
        if not directory and (only_suffix is None or path.name.split(".")[-3] == only_suffix):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(path, directory=directory)

    monkeypatch.setattr(atomic, "fsync_path", fsync)


class FullDiskExrFile:
    """A stand-in for ``OpenEXR.File`` whose ``write`` meets a full disk as OpenEXR's does: it leaves part of the
    file and raises ``RuntimeError`` naming the reason. Patch it over ``camsim.io.exr.OpenEXR.File``."""

    def __init__(self, header, channels):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def write(self, path):
        Path(path).write_bytes(b"v/1\x01partial")
        raise RuntimeError(f"Cannot write image file {path}. No space left on device")


def cupy_or_skip():
    """CuPy, where it sees a GPU; else the calling test is skipped (one reason line)."""
    import pytest

    from camsim.core.errors import CamsimError
    from camsim.render.backends import cuda_module

    try:
        return cuda_module()
    except CamsimError as exc:
        pytest.skip(f"no GPU: {exc}")


def chi2_p_counts(observed, expected) -> float:
    """Pearson's χ² p of counts ``observed`` against ``expected`` over the same bins, in order: the bins pooled from
    the first until each pooled bin expects at least 5 (what is left joins the last); 1 where fewer than two pooled
    bins remain (no degree of freedom)."""
    import numpy as np
    from scipy import stats

    obs, exp, o_acc, e_acc = [], [], 0.0, 0.0
    for o, e in zip(observed, expected):
        o_acc, e_acc = o_acc + o, e_acc + e
        if e_acc >= 5:
            obs.append(o_acc)
            exp.append(e_acc)
            o_acc = e_acc = 0.0
    if obs:
        obs[-1] += o_acc
        exp[-1] += e_acc
    if len(obs) < 2:
        return 1.0
    obs, exp = np.array(obs), np.array(exp)
    return float(stats.chi2.sf(float(np.sum((obs - exp) ** 2 / exp)), obs.size - 1))
