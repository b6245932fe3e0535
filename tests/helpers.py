"""Helpers the test modules import (``from tests.helpers import ...``): the repository root, scene builders,
patch pixels, a one-frame render and an EXR writer that meets a full disk. Fixtures live in ``conftest.py``;
closed forms in ``tests.theory``."""

from pathlib import Path

from camsim.camera import load_camera
from camsim.chart import ChartGeometry
from camsim.pipeline import light_scene, make_frame
from camsim.scene import Scene
from camsim.sources import ChartSource
from camsim.spectra import WavelengthGrid

ROOT = Path(__file__).resolve().parents[1]
WHITE = 18  # "white 9.5 (.05 D)" in ColorChecker order


def write_text_file(folder: Path, name: str, text: str) -> Path:
    """``folder/name`` with ``text`` (UTF-8), the folder made if need be (a dataset spec, a scene file)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


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
