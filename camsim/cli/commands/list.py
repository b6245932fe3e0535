"""``camsim list``: the built-in scenes, illuminants, cameras, reflectance sets, sensor presets and methods."""

from __future__ import annotations

import argparse

from camsim.sensor.params import PRESETS


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``list`` to ``subparsers``; returns its parser."""
    return subparsers.add_parser("list", help="list the built-in scenes and dataset specs, illuminants, cameras, "
                                 "reflectance sets, sensor presets and sampling methods camsim knows")


def run(args) -> int:
    """Carry out ``camsim list``; returns the exit status (0). Imports neither scipy nor colour-science."""
    from camsim.colour.colour_names import (  # colour-science's, without importing it
        CAMERAS,
        ILLUMINANTS,
        REFLECTANCE_SETS,
    )
    from camsim.methods import METHOD_NAMES
    from camsim.scene.builtin_scenes import builtin_scene_names, builtin_spec_names

    print("built-in scenes:", ", ".join(builtin_scene_names()))
    print("built-in dataset specs (camsim dataset NAME):", ", ".join(builtin_spec_names()))
    print("illuminants:", ", ".join(ILLUMINANTS))
    print("cameras:", ", ".join(CAMERAS))
    print("reflectance sets:", ", ".join(REFLECTANCE_SETS))
    print("presets:", ", ".join(PRESETS))
    from camsim.sensor.presets import CAMERA_PRESETS

    print("camera presets (--preset NAME --iso N; figures in DN of the raw, converted to electrons; then what each "
          "source publishes for the sensor effects of low-light raws):")
    for camera in CAMERA_PRESETS.values():
        print("  " + camera.describe())
        for line in camera.describe_effects(compact=True):
            print("    " + line)
    print("sampling methods:", ", ".join(METHOD_NAMES))
    return 0
