import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from camsim.camera import AnchorScale, load_camera  # noqa: E402
from camsim.chart import ChartGeometry  # noqa: E402
from camsim.pipeline import light_scene, make_frame  # noqa: E402
from camsim.radiance import scene_radiance  # noqa: E402
from camsim.scene import Scene  # noqa: E402
from camsim.sources import ChartSource  # noqa: E402
from camsim.spectra import WavelengthGrid  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WHITE = 18  # "white 9.5 (.05 D)" in ColorChecker order


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


@pytest.fixture(scope="session")
def scene():
    return small_scene()


@pytest.fixture(scope="session")
def d65_radiance(scene):
    return scene_radiance(scene, "D65")


@pytest.fixture(scope="session")
def camera(scene):
    return load_camera(scene.camera, scene.grid)


@pytest.fixture
def anchor():
    return AnchorScale()


def rng(seed=0):
    return np.random.default_rng(seed)
