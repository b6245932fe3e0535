"""Synthetic targets ([target]): the dead-leaves chart and the slanted edge, against closed forms computed here."""

import hashlib
import json
import math

import colour
import numpy as np
import pytest
from scipy import stats

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.light.spectra import WavelengthGrid
from camsim.scene.builtin_scenes import builtin_scene_names
from camsim.scene.radiance import scene_radiance
from camsim.scene.scene_file import load_scene
from camsim.scene.sources import SOURCES, TargetSource
from camsim.scene.sources.target import (
    DeadLeavesTarget,
    SlantedEdgeTarget,
    _dead_leaves_cached,
    dead_leaves,
    edge_coverage,
)

GRID = WavelengthGrid()


# ------------------------------------------------------------------------------------------------ dead leaves
def _r3_cdf(r, a, b):
    """The CDF of density ∝ r⁻³ on [a, b]: ∫_a^r t⁻³ dt / ∫_a^b t⁻³ dt."""
    return (a ** -2 - np.asarray(r) ** -2) / (a ** -2 - b ** -2)


def test_radii_follow_the_r3_law_and_centres_are_uniform():
    a, b = 2.0, 40.0
    d = dead_leaves(160, 120, a, b, 24, 11, keep_disks=True)
    cx, cy, r, spectrum = d.disks.T
    assert d.disks.shape == (d.n_disks, 4) and d.n_disks > 5000
    assert r.min() >= a and r.max() <= b
    assert stats.kstest(r, lambda x: _r3_cdf(x, a, b)).pvalue > 1e-3
    # the test has power: the r⁻² law (CDF (1/a − 1/r)/(1/a − 1/b)) on the same range is rejected outright
    assert stats.kstest(r, lambda x: (1 / a - 1 / x) / (1 / a - 1 / b)).pvalue < 1e-9
    # E[r²] = 2 ln(b/a) / (a⁻² − b⁻²), within 5 standard errors
    assert abs((r ** 2).mean() - 2 * math.log(b / a) / (a ** -2 - b ** -2)) < 5 * (r ** 2).std() / math.sqrt(r.size)
    # centres uniform on the frame grown by r_max on every side; spectra uniform on 0..K-1
    assert stats.kstest(cx, stats.uniform(-b, 160 + 2 * b).cdf).pvalue > 1e-3
    assert stats.kstest(cy, stats.uniform(-b, 120 + 2 * b).cdf).pvalue > 1e-3
    counts = np.bincount(spectrum.astype(int), minlength=24)
    assert counts.size == 24 and stats.chisquare(counts).pvalue > 1e-3


def test_each_pixel_shows_the_topmost_disk_over_its_centre():
    """Brute force from the drawn disks (top first): the first that contains the pixel centre gives its label."""
    width, height = 48, 32
    d = dead_leaves(width, height, 1.5, 12.0, 5, np.random.default_rng(3), keep_disks=True)
    cx, cy, r, spectrum = d.disks.T
    ys, xs = np.mgrid[0:height, 0:width]
    px, py = xs.ravel() + 0.5, ys.ravel() + 0.5
    inside = (px[:, None] - cx[None]) ** 2 + (py[:, None] - cy[None]) ** 2 <= r[None] ** 2  # pixels × disks
    assert inside.any(axis=1).all()  # every pixel covered
    first = inside.argmax(axis=1)
    np.testing.assert_array_equal(d.labels.ravel(), spectrum[first].astype(int))
    # drawing stopped with the batch (here of 256 disks, the smallest) in which the last pixel was covered
    assert d.n_disks - 256 <= first.max() < d.n_disks


def test_full_coverage_and_all_spectra_on_a_larger_frame():
    d = dead_leaves(640, 480, 2.0, 100.0, 26, 0)
    assert d.labels.shape == (480, 640) and d.labels.dtype == np.uint8
    assert set(np.unique(d.labels)) == set(range(26))  # no uncovered (255) pixel, every spectrum used


def test_more_than_256_spectra_use_uint16_labels():
    d = dead_leaves(64, 48, 1.0, 4.0, 300, 2)
    assert d.labels.dtype == np.uint16 and d.labels.max() < 300


def _dead_leaves_source(**table):
    return TargetSource.from_table({"kind": "dead-leaves", **table}, None, "test")


def test_seed_key_fixes_the_pattern():
    same_a = _dead_leaves_source(seed=5).spectra(GRID, 200, 150).labels
    _dead_leaves_cached.cache_clear()
    same_b = _dead_leaves_source(seed=5).spectra(GRID, 200, 150).labels
    other = _dead_leaves_source(seed=6).spectra(GRID, 200, 150).labels
    np.testing.assert_array_equal(same_a, same_b)
    assert (same_a != other).mean() > 0.5  # a different pattern, not a shifted copy
    # the rng argument: a seed and a Generator seeded alike give the same map
    np.testing.assert_array_equal(dead_leaves(90, 60, 2, 30, 24, 9).labels,
                                  dead_leaves(90, 60, 2, 30, 24, np.random.default_rng(9)).labels)


def test_spectra_are_the_reflectance_set_and_the_greys():
    source = _dead_leaves_source(greys=[0.25, 1])
    out = source.spectra(GRID, 300, 200)
    sds = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    wl = GRID.wavelengths_nm
    expected = np.array([np.interp(wl, sd.wavelengths, sd.values) for sd in sds.values()])  # linear, on the grid
    assert out.spectra.shape == (26, wl.size) and out.kind == "reflectance"
    np.testing.assert_allclose(out.spectra[:24], expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out.spectra[24:], [[0.25] * wl.size, [1.0] * wl.size])
    assert out.patch_names == [] and not out.surround and out.labels.max() == 25
    assert out.target["kind"] == "dead-leaves" and out.target["spectra"] == 26
    assert out.target["spectrum_names"][:2] == list(sds)[:2] and out.target["spectrum_names"][-1] == "grey 1"


def test_too_small_radius_for_the_frame_is_refused():
    with pytest.raises(CamsimError, match=r"may need up to .* disks .*raise radius_min_px"):
        dead_leaves(4000, 3000, 0.01, 10.0, 24, 0)


# ----------------------------------------------------------------------------------------------- slanted edge
def _clipped_area(corners_d):
    """Area of the unit square's part where d > 0, d linear, given d at the corners (0,0), (1,0), (1,1), (0,1):
    Sutherland–Hodgman clipping of the square against the half-plane, then the shoelace formula."""
    square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    poly = []
    for k in range(4):
        (p, dp), (q, dq) = (square[k], corners_d[k]), (square[(k + 1) % 4], corners_d[(k + 1) % 4])
        if dp > 0:
            poly.append(p)
        if (dp > 0) != (dq > 0):
            t = dp / (dp - dq)
            poly.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    if len(poly) < 3:
        return 0.0
    return 0.5 * abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(poly, poly[1:] + poly[:1])))


def _exact_coverage(width, height, angle_deg, offset):
    """Per pixel the clipped area, and whether the square lies wholly on one side (corners all ≤ 0 or all ≥ 0)."""
    th = math.radians(angle_deg)
    area, whole = np.empty((height, width)), np.empty((height, width), dtype=bool)
    for i in range(height):
        for j in range(width):
            corners = [(j + u - width / 2) * math.cos(th) - (i + v - height / 2) * math.sin(th) - offset
                       for u, v in ((0, 0), (1, 0), (1, 1), (0, 1))]
            area[i, j] = _clipped_area(corners)
            whole[i, j] = min(corners) >= 0 or max(corners) <= 0
    return area, whole


@pytest.mark.parametrize(("angle", "offset"), [(5.0, 0.0), (-5.0, 1.3), (0.0, 0.25), (0.0, 0.0), (2.0, -3.7),
                                               (30.0, 0.0), (-45.0, 2.0), (45.0, 0.0), (1e-7, 0.4)])
def test_edge_coverage_is_the_exact_clipped_area(angle, offset):
    width, height = 36, 24
    area, _ = _exact_coverage(width, height, angle, offset)
    np.testing.assert_allclose(edge_coverage(width, height, angle, offset), area, rtol=0, atol=1e-9)


def test_edge_through_the_centre_halves_the_frame():
    """A line through a rectangle's centre splits it into two congruent halves: Σ coverage = W·H / 2."""
    for angle in (5.0, -17.0, 44.0):
        assert edge_coverage(601, 403, angle).sum() == pytest.approx(601 * 403 / 2, abs=1e-6)


@pytest.mark.parametrize(("angle", "offset", "levels"), [(5.0, 0.0, 64), (-12.0, 2.5, 7), (0.0, 0.5, 2)])
def test_quantised_levels_labels_and_mixtures(angle, offset, levels):
    width, height = 40, 30
    source = TargetSource.from_table({"kind": "slanted-edge", "angle_deg": angle, "offset_px": offset,
                                      "levels": levels, "low": 0.05, "high": 0.9}, None, "test")
    out = source.spectra(GRID, width, height)
    assert out.spectra.shape == (levels, GRID.size) and not out.surround
    level_of = np.array(out.target["spectrum_levels"])
    a_spectrum = level_of / (levels - 1)
    np.testing.assert_allclose(out.spectra, np.broadcast_to(((1 - a_spectrum) * 0.05 + a_spectrum * 0.9)[:, None],
                               out.spectra.shape), rtol=0, atol=1e-15)
    assert a_spectrum[0] == 0 and a_spectrum[1] == 1  # the dark and bright spectra come first
    area, whole = _exact_coverage(width, height, angle, offset)
    a = a_spectrum[out.labels]
    assert np.abs(a - area).max() <= 1 / (2 * (levels - 1)) + 1e-9
    # away from the edge: exactly the dark or the bright spectrum
    np.testing.assert_array_equal(out.labels[whole], np.where(area[whole] > 0.5, 1, 0))
    # the record's signed distance puts each pixel centre on the side its coverage says
    t = out.target
    ys, xs = np.mgrid[0:height, 0:width] + 0.5
    d = (xs - t["centre_xy"][0]) * t["normal_xy"][0] + (ys - t["centre_xy"][1]) * t["normal_xy"][1] - t["offset_px"]
    assert np.all((d > 0.75) <= (area == 1)) and np.all((d < -0.75) <= (area == 0))


def test_flat_patches_lie_away_from_the_edge():
    out = load_scene("slanted_edge").source.spectra(GRID, 120, 80)
    assert out.patch_names == ["dark", "bright"]
    for label, (x, y, w, h) in enumerate(out.patch_rects):
        assert w >= 4 and h >= 4 and x >= 0 and y >= 0 and x + w <= 120 and y + h <= 80
        assert np.all(out.labels[y:y + h, x:x + w] == label)  # spectrum 0 (dark) or 1 (bright), wholly
    # an edge pushed out of the frame leaves no dark side: no patches
    gone = TargetSource.from_table({"kind": "slanted-edge", "offset_px": -200.0}, None, "t").spectra(GRID, 120, 80)
    assert gone.patch_names == [] and gone.patch_rects == [] and np.all(gone.labels == 1)


def test_named_patches_as_the_sides():
    source = TargetSource.from_table({"kind": "slanted-edge", "low": "black 2 (1.5 D)", "high": "white 9.5 (.05 D)",
                                      "levels": 3}, None, "t")
    out = source.spectra(GRID, 64, 48)
    sds = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    wl = GRID.wavelengths_nm
    black, white = (np.interp(wl, sds[n].wavelengths, sds[n].values) for n in ("black 2 (1.5 D)", "white 9.5 (.05 D)"))
    np.testing.assert_allclose(out.spectra, [black, white, (black + white) / 2], rtol=0, atol=1e-12)
    with pytest.raises(CamsimError, match="no patch 'ivory'"):
        TargetSource.from_table({"kind": "slanted-edge", "low": "ivory"}, None, "t").spectra(GRID, 64, 48)


# ------------------------------------------------------------------------------------ scene files and the CLI
def test_registered_and_built_in():
    assert SOURCES["target"] is TargetSource
    assert {"dead_leaves", "slanted_edge"} <= set(builtin_scene_names())
    assert isinstance(load_scene("dead_leaves").source, DeadLeavesTarget)
    assert isinstance(load_scene("slanted_edge").source, SlantedEdgeTarget)


@pytest.mark.parametrize("name", ["dead_leaves", "slanted_edge"])
def test_cli_renders_each_built_in_target(tmp_path, name):
    out = tmp_path / name
    assert main(["render", name, "--size", "120x80", "--out", str(out), "-q"]) == 0
    stem = f"{name}_D65_F1"
    assert {f"{stem}.dng", f"{stem}.exr", f"{stem}.json"} <= {p.name for p in out.iterdir()}
    meta = json.loads((out / f"{stem}.json").read_text())
    assert (meta["width_px"], meta["height_px"]) == (120, 80) and meta["surround"] is None
    assert meta["target"]["kind"] == name.replace("_", "-")
    if name == "slanted_edge":
        dark, bright = meta["patches"]
        assert (dark["name"], bright["name"]) == ("dark", "bright")
        # flat greys 0.1 and 0.8 under one light: the expected signals are in the ratio 8 in every channel
        np.testing.assert_allclose(np.array(bright["signal_e"]) / np.array(dark["signal_e"]), 8.0, rtol=1e-12)
    else:
        assert meta["patches"] == [] and meta["target"]["disks_drawn"] > 0


def test_same_seed_same_files(tmp_path):
    digests = []
    for run in ("a", "b"):
        _dead_leaves_cached.cache_clear()
        out = tmp_path / run
        assert main(["render", "dead_leaves", "--size", "96x64", "--intensity", "1", "--out", str(out), "-q"]) == 0
        digests.append({p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in out.iterdir()
                        if p.suffix in (".dng", ".exr", ".json")})
    assert digests[0] == digests[1] and len(digests[0]) == 4  # DNG, EXR, JSON and manifest.json


def test_radiance_is_lit_per_spectrum_not_per_pixel():
    scene = load_scene("dead_leaves").replace(width=120, height=80)
    radiance = scene_radiance(scene, "D65")
    assert radiance.radiance.shape == (26, GRID.size) and radiance.labels.shape == (80, 120)


def _write(tmp_path, target: str) -> str:
    path = tmp_path / "s.toml"
    path.write_text(f"[target]\n{target}\n")
    return str(path)


@pytest.mark.parametrize(("table", "message"), [
    ('kind = "dead-leaves"\nradius_min_px = -1', r"radius_min_px must be 0.01 to 1e\+06 pixels, got -1"),
    ('kind = "dead-leaves"\nradius_max_px = 1e308', r"radius_max_px must be 0.01 to 1e\+06 pixels, got 1e\+308"),
    ('kind = "dead-leaves"\nradius_min_px = 10\nradius_max_px = 5',
     r"radius_min_px \(10\) must not exceed radius_max_px \(5\)"),
    ('kind = "dead-leaves"\nradius_max_px = inf', r"radius_max_px must be a finite number, got inf"),
    ('kind = "dead-leaves"\nseed = -3', r"seed must be a non-negative integer, got -3"),
    ('kind = "dead-leaves"\ngreys = [0.5, 2]', r"greys must be reflectances in \[0, 1\], got 2"),
    ('kind = "slanted-edge"\nangle_deg = 60', r"angle_deg must be in \[-45, 45\] degrees from vertical, got 60"),
    ('kind = "slanted-edge"\nlevels = 1', r"levels must be an integer in \[2, 4096\], got 1"),
    ('kind = "slanted-edge"\nlow = 0.8\nhigh = 0.2', r"low \(0.8\) must be below high \(0.2\)"),
    ('kind = "slanted-edge"\nhigh = 1.5', r"high must be a reflectance in \[0, 1\], got 1.5"),
    ('kind = "slanted-edge"\nangle_deg = "steep"', r"angle_deg must be of type float, got 'steep'"),
    ('kind = "slanted-edge"\nseed = 1', r"key\(s\) seed do not apply to kind = 'slanted-edge'"),
    ('kind = "zone-plate"', r"\[target\] kind must be one of dead-leaves, slanted-edge, flat, got 'zone-plate'"),
    ('radius_min_px = 2', r"\[target\] kind must be one of dead-leaves, slanted-edge, flat, got None"),
    ('kind = "dead-leaves"\nradius = 3', r"unknown key\(s\) in \[target\]: radius"),
])
def test_bad_tables_are_one_clear_error(tmp_path, table, message):
    with pytest.raises(CamsimError, match=message) as info:
        load_scene(_write(tmp_path, table))
    assert "\n" not in str(info.value)


def test_cli_reports_a_bad_table_on_one_line(tmp_path, capsys):
    path = _write(tmp_path, 'kind = "dead-leaves"\nradius_min_px = 0')
    assert main(["render", path, "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("camsim: error:") and "radius_min_px" in err[0]
