"""A dataset draws the sensor's temperature like any parameter (issue 28): ``temperature_c`` in ``[random]`` gives
each frame its own temperature, and each frame's dark level follows D(T) = D_ref · 2^((T − T_ref)/T_d), the closed
form computed here."""

import numpy as np
import pytest

from camsim.dataset.frame_render import render_frame
from camsim.dataset.spec import plan_spec
from tests.helpers import ROOT, write_text_file

SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()
# emva-12bit: K = 0.4 DN/e⁻, 25 e⁻/s at its reference temperature, read noise 3 e⁻, DSNU 2 e⁻; a pedestal keeps the
# coldest dark level clear of the ADC's 0 (the ADC adds P + ½ before its floor: a dark mean of P + K · D · t)
SPEC = f"""
name = "warm"
scene = "{SCENE}"
seed = 3

[frame]
width = 64
height = 48

[fixed]
preset = "emva-12bit"
cfa = "none"
pedestal_dn = 64
exposure_s = 2.0
intensity_factor = 1e-30
illuminant = "D65"
dark_current_doubling_c = 7.0

[random]
count = 5
temperature_c = {{ uniform = [5.0, 45.0] }}
"""


def test_random_temperatures_give_dark_frames_that_follow_the_doubling_law(tmp_path):
    frames = list(plan_spec(write_text_file(tmp_path, "warm.toml", SPEC)).frames())
    temperatures = [f.record["temperature_c"] for f in frames]
    assert len(set(temperatures)) == 5 and all(5.0 <= t <= 45.0 for t in temperatures)
    for spec_frame, temperature in zip(frames, temperatures):
        frame, _ = render_frame(spec_frame)
        dn = frame.digital_dn.astype(np.float64)
        dark_e = 25.0 * 2.0 ** ((temperature - 25.0) / 7.0) * 2.0
        expected = 64 + 0.4 * dark_e
        # standard error of the mean over 3 · 64 · 48 values: √(σ²_read + D) K per value (temporal), the DSNU's
        # mean 2 K / √(3 · 64 · 48)
        error = np.sqrt(3.0**2 + dark_e) * 0.4 / np.sqrt(dn.size) + 2.0 * 0.4 / np.sqrt(dn.size)
        assert abs(dn.mean() - expected) < 5 * error, (temperature, dn.mean(), expected)


def test_a_grid_of_temperatures_orders_the_dark_levels(tmp_path):
    text = SPEC.replace("[random]\ncount = 5\ntemperature_c = { uniform = [5.0, 45.0] }\n",
                        "[grid]\ntemperature_c = [10.0, 24.0, 38.0]\n")
    frames = list(plan_spec(write_text_file(tmp_path, "grid.toml", text)).frames())
    assert [f.record["temperature_c"] for f in frames] == [10.0, 24.0, 38.0]
    means = [render_frame(f)[0].digital_dn.mean() - 64 for f in frames]
    # 14 °C = 2 doubling temperatures apart: each dark signal 2^2 = 4 times the last, within the noise
    assert means[1] / means[0] == pytest.approx(4.0, rel=0.05)
    assert means[2] / means[1] == pytest.approx(4.0, rel=0.02)
