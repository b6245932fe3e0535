"""Error and cost of each RGB → spectrum recovery method (camsim.colour.recovery) on the ColorChecker.

For each of the 24 patches of colour-science's ``SDS_COLOURCHECKERS["ColorChecker N Ohta"]``:

1. its linear sRGB under D65 (``colour.sd_to_XYZ`` with the CIE 1931 2° functions and D65, then
   ``colour.XYZ_to_RGB`` to sRGB with no adaptation); a negative component (a patch outside sRGB's gamut) is
   clipped to 0, as an image file would hold it, and the patch is named;
2. its spectrum recovered by each method on the scene grid (default 380–780 nm every 4 nm);
3. CIE 2000 ΔE (``colour.delta_E``) between the recovered and the measured spectrum (both on the grid), each
   integrated with ``colour.sd_to_XYZ`` under D65 (the round-trip colour: ~0 for an exact method, apart from
   any clip), CIE A and FL2 (the metameric error that a camera under another light sees), each against the
   white of its own illuminant;
4. the Nikon 5100 (NPL) camera's responses Σ R E Qe to the recovered and measured spectra, under the same three
   lights: |difference| in % of the perfect white's response in that channel.

Prints a table (mean / max over patches, and the camera over patches and channels) and the cost: seconds per
distinct colour from a cold cache for Otsu 2018 and Jakob 2019, a cached look-up, and Mallett 2019's route for an
image (build the 3 × 3 matrix; apply it to a 1000 × 1000 linear RGB image).

    PYTHONPATH=. python tools/recovery_error.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from camsim.colour.recovery import RECOVERY_METHODS, basis_matrix, clear_cache, mallett_basis, rgb_to_distinct_spectra
from camsim.light.spectra import CMFS_NAME, WavelengthGrid, camera_sensitivities, illuminant_spd, import_colour

CHART = "ColorChecker N Ohta"
LIGHTS = ("D65", "A", "FL2")
CAMERA = "Nikon 5100 (NPL)"


def chart_rgb(colour):
    """Linear sRGB of the chart's patches under D65 (clipped at 0), the names, and the unclipped minimum."""
    chart = colour.SDS_COLOURCHECKERS[CHART]
    cmfs = colour.MSDS_CMFS[CMFS_NAME]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    xyz = np.array([colour.sd_to_XYZ(sd, cmfs, d65) / 100 for sd in chart.values()])
    rgb = colour.XYZ_to_RGB(xyz, "sRGB", illuminant=colour.CCS_ILLUMINANTS[CMFS_NAME]["D65"],
                            chromatic_adaptation_transform=None)
    return list(chart.keys()), rgb


def lab_on_grid(colour, reflectances, grid, light):
    """CIELAB (against the light's own white) of reflectances (K, N) on ``grid`` under ``light``."""
    cmfs = colour.MSDS_CMFS[CMFS_NAME]
    illuminant = colour.SDS_ILLUMINANTS[light]
    wl = grid.wavelengths_nm
    xyz = np.array([colour.sd_to_XYZ(colour.SpectralDistribution(r, wl), cmfs, illuminant,
                                     method="Integration") / 100
                    for r in reflectances])
    white = colour.sd_to_XYZ(colour.SpectralDistribution(np.ones(wl.size), wl), cmfs, illuminant,
                              method="Integration") / 100
    return colour.XYZ_to_Lab(xyz, colour.XYZ_to_xy(white))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats (the fastest is printed)")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    colour = import_colour()
    grid = WavelengthGrid()
    names, rgb_raw = chart_rgb(colour)
    rgb = np.maximum(rgb_raw, 0.0)
    for name, row in zip(names, rgb_raw):
        if row.min() < 0:
            print(f"note: patch {name!r} is outside sRGB (linear sRGB {np.round(row, 4).tolist()}); clipped at 0")
    from camsim.light.spectra import reflectance_set
    _, measured = reflectance_set(CHART, grid)
    _, qe = camera_sensitivities(CAMERA, grid)

    lab_measured = {light: lab_on_grid(colour, measured, grid, light) for light in LIGHTS}
    camera_weights = {light: qe * illuminant_spd(light, grid) for light in LIGHTS}  # (3, N)

    print(f"\nColorChecker N Ohta, 24 patches, grid {grid.start_nm:g}–{grid.end_nm:g} nm step {grid.step_nm:g}; "
          f"ΔE00 of recovered against measured spectra (mean / max); camera {CAMERA}: |Δ response| in % of the "
          "white's, over patches and channels (mean / max)")
    inside = rgb_raw.min(axis=1) >= 0
    header = ["method", "round trip ΔE00 (recorded)", f"ΔE00 D65, {int(inside.sum())} in sRGB"] + \
             [f"ΔE00 {light}" for light in LIGHTS] + \
             [f"camera {light} %" for light in LIGHTS] + ["outside"]
    print(" | ".join(header))
    costs = {}
    for method in RECOVERY_METHODS:
        clear_cache()
        result = rgb_to_distinct_spectra(rgb, method, grid=grid)
        recovered = result.expand()  # (24, N): one spectrum per patch
        costs[method] = result.seconds_per_colour
        cells = [method, f"{result.delta_e.mean():.3f} / {result.delta_e.max():.3f}"]
        de = colour.delta_E(lab_measured["D65"][inside], lab_on_grid(colour, recovered[inside], grid, "D65"),
                            method="CIE 2000")
        cells.append(f"{de.mean():.2f} / {de.max():.2f}")
        for light in LIGHTS:
            de = colour.delta_E(lab_measured[light], lab_on_grid(colour, recovered, grid, light), method="CIE 2000")
            cells.append(f"{de.mean():.2f} / {de.max():.2f}")
        for light in LIGHTS:
            w = camera_weights[light]
            white = w.sum(axis=1)
            diff = 100 * np.abs(recovered @ w.T - measured @ w.T) / white
            cells.append(f"{diff.mean():.2f} / {diff.max():.2f}")
        cells.append(f"{int(result.outside.sum())}")
        print(" | ".join(cells))

    print("\nCost (fastest of", args.repeats, "repeats; a shared 2-core machine)")
    for method in RECOVERY_METHODS:
        best = np.inf
        for _ in range(args.repeats if method != "Jakob 2019" else 1):
            clear_cache()
            best = min(best, rgb_to_distinct_spectra(rgb, method, grid=grid).seconds_per_colour)
        line = f"  {method}: {best * 1e3:.3f} ms per colour (cold cache)"
        if method != "Mallett 2019":
            start = time.perf_counter()
            again = rgb_to_distinct_spectra(rgb, method, grid=grid)
            hit = time.perf_counter() - start
            assert again.computed == 0
            line += f"; a call whose 24 colours are all cached: {hit * 1e3:.2f} ms in all (ΔE bookkeeping included)"
        print(line)
    basis = mallett_basis(grid)
    image = np.random.default_rng(1).random((1000, 1000, 3))
    build, apply = np.inf, np.inf
    for _ in range(args.repeats):
        start = time.perf_counter()
        matrix = basis_matrix(basis, camera_weights["D65"])
        build = min(build, time.perf_counter() - start)
        start = time.perf_counter()
        electrons = image @ matrix.T
        apply = min(apply, time.perf_counter() - start)
    assert electrons.shape == (1000, 1000, 3)
    print(f"  Mallett 2019 image route: 3 × 3 matrix built in {build * 1e6:.1f} µs; applied to 1000 × 1000 pixels "
          f"in {apply * 1e3:.1f} ms ({apply * 1e3:.1f} ns per pixel), no H × W × N cube")


if __name__ == "__main__":
    main()
