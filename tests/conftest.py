"""Shared fixtures and the Hypothesis profile (:mod:`tests.support.profiles`). Helpers are in
:mod:`tests.support.helpers` and the closed forms in :mod:`tests.support.theory`."""

import pytest

from camsim.scene.radiance import scene_radiance
from camsim.sensor.camera import AnchorScale, load_camera
from tests.support import profiles
from tests.support.helpers import small_scene

profiles.load()  # HYPOTHESIS_PROFILE=ci (default) or dev


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
