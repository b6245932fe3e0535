"""``camsim emva``: simulate the EMVA 1288 measurement of the camera and analyse it with the reference
implementation."""

from __future__ import annotations

import argparse
from pathlib import Path

from camsim.cli.commands import DEFAULT_OUT, preset_argument, writing_to
from camsim.cli.types import integer_between, non_negative_int, positive_float, sensor_setting

#: ``--size``: the range :class:`camsim.emva.EmvaSetup` accepts for the side of the region of interest.
ROI_SIDE_PX = integer_between(16, 4096, "the side of the EMVA region of interest in pixels")


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``emva`` and its options to ``subparsers``; returns its parser."""
    parser = subparsers.add_parser(
        "emva",
        help="simulate the EMVA 1288 measurement of the camera and analyse it with the reference implementation",
        description=(
            "Simulate the EMVA 1288 photon-transfer measurement of the configured camera (pairs of flat frames at "
            "a monochromatic 550 nm light from dark to beyond saturation, dark and bright stacks for DSNU / PRNU), "
            "analyse it with the emva1288 package and compare what the standard recovers (system gain K, temporal "
            "dark noise, quantum efficiency, saturation capacity, DSNU, PRNU) with the configuration. Writes "
            "OUT/report.md, OUT/emva.json and PNG plots."
        ),
    )
    parser.add_argument("--preset", metavar="NAME|PATH.toml",
                        help="sensor preset to measure (default emva-12bit: a 12-bit machine-vision-like sensor, "
                             "K = 0.4 DN/e⁻; paper-table1 shows the 8-bit, 35 e⁻/DN case, where quantisation "
                             "dominates the dark noise), or a camera preset (camsim list) or preset file")
    parser.add_argument("--iso", metavar="ISO", type=positive_float, help="ISO of a camera preset")
    parser.add_argument("--sensor", metavar="NAME=VALUE", type=sensor_setting, action="append", default=[],
                        help="set a sensor parameter of the preset (repeatable; as camsim render's --sensor), e.g. "
                             "dsnu_dark_current_percent=10 for a dark-current DSNU")
    parser.add_argument("--dsnu-exposure-factor", metavar="F", type=positive_float,
                        help="also take the dark stack at F times the exposure time (F > 1 and ≤ 100), for the DSNU at "
                             "two exposure times split into its offset part and its dark-current part (∝ T); "
                             "default: only for a sensor with a dark-current DSNU, at F = 4")
    parser.add_argument("--temperatures", metavar="C", type=float, nargs="+",
                        help="also measure the dark current at these sensor temperatures (°C, at least two): the slope "
                             "of the dark mean against the exposure time at each, and the doubling temperature "
                             "through them (EMVA 1288's μ_I,ref · 2^((ϑ − ϑ_ref)/T_d))")
    parser.add_argument("--out", metavar="DIR", type=Path, help="output folder (default outputs/emva)")
    parser.add_argument("--size", metavar="N", type=ROI_SIDE_PX, default=256,
                        help="side of the square region of interest in pixels, 16 to 4096 (default 256)")
    parser.add_argument("--seed", metavar="N", type=non_negative_int, default=0,
                        help="seed of the temporal noise (integer ≥ 0, default 0); the fixed pattern is the "
                             "sensor's own (its sensor_seed)")
    parser.add_argument("--quiet", "-q", action="store_true",
                        help="no progress bar, no table, no colour-science warnings")
    return parser


def run(args) -> int:
    """Carry out ``camsim emva``; returns the exit status (0)."""
    from camsim.emva import DEFAULT_PRESET, EmvaSetup, write_outputs
    from camsim.emva import run as measure
    from camsim.sensor.presets import camera_preset, sensor_preset

    setup = EmvaSetup(size=args.size, seed=args.seed, dsnu_exposure_factor=args.dsnu_exposure_factor,
                      temperatures=tuple(args.temperatures or ()))
    name, sensor = args.preset, None
    if name is not None:
        name = preset_argument(name)
    if args.sensor or args.iso is not None or (name is not None and camera_preset(name) is not None):
        overrides = dict(args.sensor)
        name = name or DEFAULT_PRESET
        sensor = sensor_preset(name, args.iso, **overrides)
        if args.iso is not None:
            name += f" at ISO {args.iso:g}"
        if overrides:
            name += " with " + ", ".join(f"{key}={value}" for key, value in overrides.items())
    out = args.out if args.out is not None else DEFAULT_OUT / "emva"
    with writing_to(out):
        result = measure(name, setup, sensor=sensor, progress=not args.quiet)
        paths = write_outputs(result, out)
    if not args.quiet:
        width = max(14, *map(len, result.comparison()))
        for key, row in result.comparison().items():
            ok = result.within_target(key)
            mark = "" if ok is None else ("  ok" if ok else "  outside target")
            rel = "" if row["relative_error"] is None else f"  {100 * row['relative_error']:+.2f} %"
            recovered = "—" if row["recovered"] is None else f"{row['recovered']:.5g}"
            print(f"  {key:<{width}} configured {row['configured']:<10.5g} recovered {recovered:<10}{rel}{mark}")
    print(f"EMVA 1288 of preset {result.measurement.preset_name}: {paths['report']}, {paths['json']}")
    return 0
