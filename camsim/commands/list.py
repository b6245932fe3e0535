"""``camsim list``: the illuminants, cameras, reflectance sets and sensor presets camsim knows."""

from __future__ import annotations

import argparse

from camsim.sensor import PRESETS


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``list`` to ``subparsers``; returns its parser."""
    return subparsers.add_parser("list", help="list the illuminants, cameras, reflectance sets and presets camsim knows")


def run(args) -> int:
    """Carry out ``camsim list``; returns the exit status (0)."""
    from camsim.spectra import camera_names, illuminant_names, reflectance_set_names

    print("illuminants:", ", ".join(illuminant_names()))
    print("cameras:", ", ".join(camera_names()))
    print("reflectance sets:", ", ".join(reflectance_set_names()))
    print("presets:", ", ".join(PRESETS))
    return 0
