"""The experiment's figure makers write legible PNGs from small real frames, and skip undefined values."""

import contextlib
import copy
from pathlib import Path

import matplotlib.image as mpimg
import pytest

from camsim.analysis.analyze import analyse_paths
from camsim.analysis.patches import AnalysisSettings
from camsim.experiments.datapoints import DataPoint
from camsim.experiments.figures import scenario_figures, snr_figures
from camsim.render.run import render_scene
from camsim.scene.scene_file import load_scene

ROOT = Path(__file__).resolve().parents[2]
N_POINTS = 4


@pytest.fixture(scope="module")
def analysed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("frames")
    scene = load_scene(ROOT / "scenes" / "macbeth_26.toml").replace(
        width=120, height=80, illuminants=("D65",), intensity_factors=(1.0, 0.01))
    render_scene(scene, folder, progress=False)
    results = analyse_paths([folder], AnalysisSettings(), progress=False)
    points = [DataPoint(i + 1, results[0]["patches"][i]["name"], "D65", i < 3,
                        results[0]["patches"][i]["center_x"], results[0]["patches"][i]["center_y"])
              for i in range(N_POINTS)]
    return results, points


@contextlib.contextmanager
def pyplot_left_alone():
    """The figures drawn within open no figure in pyplot (colour-science's plots draw on ours). Each test's own
    call of a maker is checked, so the check draws nothing of its own."""
    import matplotlib.pyplot as plt

    plt.close("all")  # pyplot's current figure, if any, would hide a figure opened through it
    yield
    assert plt.get_fignums() == []


def assert_pngs(out_dir, figures, keys):
    assert set(figures) == set(keys)
    for name in figures.values():
        path = out_dir / name
        assert path.is_file() and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        image = mpimg.imread(path)
        assert image.shape[0] >= 300 and image.shape[1] >= 300


@pytest.mark.slow
def test_scenario_figures(analysed, tmp_path):
    results, points = analysed
    pixel = copy.deepcopy(results)
    # undefined values on purpose: a degenerate ellipse, missing angle/size/ΔE, a NaN, a missing frame file
    pixel[0]["patches"][0].update(ellipse_status="constant", center_x=None, center_y=None, semi_major_xy=None,
                                  semi_minor_xy=None, angle_deg=None, size_xy=None)
    pixel[1]["patches"][1].update(delta_e_ab_mean=None, size_xy=float("nan"))
    pixel[1]["frame_file"] = str(tmp_path / "gone.dng")
    with pyplot_left_alone():
        figures = scenario_figures("scenario1", {"paper": results, "pixel": pixel}, points,
                                   {"paper": (0.31, 0.33), "pixel": None}, tmp_path, magnified_point=3)
    assert figures == {key: f"scenario1_{key}.png"
                       for key in ("samples", "centres", "magnified", "angle", "size", "delta_e")}
    assert_pngs(tmp_path, figures, figures)


@pytest.mark.slow
def test_scenario_figures_without_results(analysed, tmp_path):
    _, points = analysed
    with pyplot_left_alone():
        figures = scenario_figures("scenario2", {"paper": [], "pixel": []}, points, {}, tmp_path, magnified_point=99)
    assert_pngs(tmp_path, figures, ("samples", "centres", "magnified", "angle", "size", "delta_e"))


@pytest.mark.slow
def test_snr_figures(tmp_path):
    rows = []
    for stat in ("paper", "pixel"):
        for variant, scale in (("read+10%", 0.5), ("dark+10%", 5.0)):  # no quantisation rows: "no data"
            for term in ("mean-square", "variance"):
                for f in (0.1, 0.05, 0.01, 0.005, 0.001):
                    for point in (1, 2, 3):
                        for channel in "RGB":
                            model = scale * point / (1 + 100 * f)
                            rows.append({"statistics": stat, "protocol": "all-on", "variant": variant,
                                         "quantisation_term": term, "intensity_factor": f, "point": point,
                                         "channel": channel, "delta_snr_eq13_pct": model,
                                         "delta_snr_eq13_unquantised_numerator_pct": 1.1 * model,
                                         "delta_snr_statistics_variance_pct": scale,
                                         "delta_snr_empirical_pct": None if point == 2 else model * 1.1})
    rows[0]["delta_snr_eq13_pct"] = None
    rows[1]["delta_snr_eq13_pct"] = float("nan")
    rows[2]["delta_snr_empirical_pct"] = 1e6  # beyond the axes: counted, not drawn
    with pyplot_left_alone():
        figures = snr_figures(rows, tmp_path)
    assert figures == {f"snr_{noise}_{protocol}": f"snr_{noise}_{protocol}.png"
                       for noise in ("read", "dark", "quantisation") for protocol in ("one_at_a_time", "all_on")}
    assert_pngs(tmp_path, figures, figures)
