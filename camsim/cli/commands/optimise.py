"""``camsim optimise``: for each light level, the exposure time and ISO that maximise SNR or minimise ΔE."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from camsim.cli.commands import DEFAULT_OUT, preset_argument, writing_to
from camsim.cli.types import positive_float, sensor_setting
from camsim.core.errors import CamsimError

DEFAULT_FACTORS = (1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``optimise`` and its options to ``subparsers``; returns its parser."""
    parser = subparsers.add_parser(
        "optimise",
        help="the exposure time and ISO that measure a scene's colours best at each light level",
        description=(
            "For each light level F, search exposure time T (up to --max-exposure) and ISO (the camera preset's "
            "published points within --iso-range) for the setting that maximises the mean SNR of the scene's "
            "patches (Eqs. 13–14) or minimises their expected ΔE_ab, from the model's closed-form moments; "
            "settings that would saturate a patch are not allowed. Then render frames at each choice and its grid "
            "neighbours to check it. Writes OUT/choices.csv, verification.csv, objective_maps.png and report.md."
        ),
    )
    parser.add_argument("scene", metavar="SCENE.toml", help="a scene with patches (a chart), e.g. macbeth_26")
    parser.add_argument("--preset", metavar="NAME|PATH.toml", required=True,
                        help="camera preset (camsim list), e.g. sony-a7s2, or a preset file")
    parser.add_argument("--intensity", "-F", metavar="F", type=positive_float, nargs="+", action="extend",
                        help="light levels F (default: 1 down to 0.001, ten values)")
    parser.add_argument("--max-exposure", metavar="S", type=float, default=1.0,
                        help="the longest exposure allowed (motion), in s (default 1)")
    parser.add_argument("--iso-range", metavar=("A", "B"), type=float, nargs=2,
                        help="search the preset's ISO points from A to B (default: all)")
    parser.add_argument("--objective", choices=("snr", "delta-e", "both"), default="snr",
                        help="maximise the mean SNR, minimise the mean E[ΔE], or both (a Pareto front)")
    parser.add_argument("--sensor", metavar="NAME=VALUE", type=sensor_setting, action="append", default=[],
                        help="set a sensor parameter on top of the preset (repeatable), e.g. "
                             "dark_current_e_per_s=500")
    parser.add_argument("--illuminant", metavar="NAME", help="the light (default: the scene's first)")
    parser.add_argument("--no-verify", action="store_true", help="skip the rendered check")
    parser.add_argument("--verify-size", metavar="WxH", default="240x160",
                        help="frame size of the rendered check (default 240x160)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the rendered check")
    parser.add_argument("--out", metavar="DIR", type=Path, help="output folder (default outputs/optimise)")
    parser.add_argument("--quiet", "-q", action="store_true",
                        help="no table on the terminal, no colour-science warnings")
    return parser


def run(args) -> int:
    """Carry out ``camsim optimise``; returns the exit status (0)."""
    import dataclasses

    from camsim.optimise.model import SensorAtIso
    from camsim.optimise.report import write_report
    from camsim.optimise.search import exposure_axis, iso_axis, optimise, patch_rates
    from camsim.optimise.verify import three_chip, verify_choice
    from camsim.render.pipeline import light_scene
    from camsim.scene.chart import parse_size
    from camsim.scene.scene_file import load_scene
    from camsim.sensor.presets import camera_preset, sensor_preset

    if not args.max_exposure > 0:
        raise CamsimError(f"--max-exposure must be a positive number of seconds, got {args.max_exposure:g}")
    preset = preset_argument(args.preset)
    camera = camera_preset(preset)
    isos = iso_axis(camera, None if args.iso_range is None else tuple(args.iso_range))
    exposures = exposure_axis(args.max_exposure)
    overrides = dict(args.sensor)
    factors = tuple(args.intensity) if args.intensity else DEFAULT_FACTORS
    scene = load_scene(args.scene)
    illuminant = args.illuminant or scene.illuminants[0]
    width, height = parse_size(args.verify_size)
    scene = scene.replace(width=width, height=height, preset_name=preset, illuminants=(illuminant,))

    def sensor_at(iso, exposure_s=1.0):
        sensor = sensor_preset(preset, None if camera is None else iso, **overrides)
        return three_chip(dataclasses.replace(sensor, exposure_s=exposure_s))

    sensors = [SensorAtIso.of(sensor_at(iso), iso) for iso in isos]
    rates = patch_rates(scene, illuminant, sensor_at(isos[0]))
    result = optimise(rates, sensors, exposures, factors, args.objective, preset=args.preset)
    out = args.out if args.out is not None else DEFAULT_OUT / "optimise"
    command = "camsim optimise " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["optimise"] else "camsim optimise"
    with writing_to(out):
        verification = []
        if not args.no_verify:
            lit = light_scene(scene, illuminant)
            for k, choice in enumerate(result.choices):
                verification += verify_choice(choice, result, lit, rates, sensor_at, seed=args.seed + k)
        paths = write_report(result, verification, out, scene.name,
                             None if camera is None else camera.dual_gain_iso, command)
    if not args.quiet:
        print(f"{'F':>8} {'objective':>9} {'T (s)':>10} {'ISO':>7} {'SNR dB':>7} {'ΔE':>7}  dominant / limited by")
        for c in result.choices:
            de = "—" if c.delta_e is None else f"{c.delta_e:.3f}"
            iso = "—" if c.iso is None else f"{c.iso:g}"
            print(f"{c.intensity_factor:>8g} {c.objective:>9} {c.exposure_s:>10.4g} {iso:>7} {c.snr_db:>7.2f} "
                  f"{de:>7}  {c.dominant_noise} / {c.limited_by}")
        print(f"search: {result.search_s:.3f} s for {len(exposures)} exposures × {len(isos)} ISO × {len(factors)} F")
    print(f"optimised {scene.name} with {args.preset}: {paths['report']}")
    return 0
