"""The default frame (three-chip LinearRaw, 8 bits) and its Bayer twin develop right in every raw reader installed.

Each reader (rawpy/LibRaw, dcraw, darktable-cli, rawtherapee-cli; a missing one is skipped) develops a rendered
ColorChecker frame and a dark frame with its own defaults (``tools/raw_readers.py``, which prints the same as a
table). Developed right means, on the 0–255 scale of the reader's sRGB picture:

* black honoured: the dark frame's mean is below 20 in every channel (a reader that subtracts no black shows the
  8-bit Table I sensor's 5–6 DN as 50–75);
* no cast: on the black patch R/G and B/G within 1 ± 0.25, on the neutral 3.5 and 5 patches within 1 ± 0.08 (the
  Bayer files' own spread: every reader truncates a CFA black level, so B's 5.68 DN is taken as 5, which tints the
  black patch by B/G 1.12–1.18; dcraw, and darktable through its sidecar, subtract one level from all three
  channels of a three-chip file, which leaves G 0.5–1 DN above black: R/G 0.80 on the black patch).

The frames are the scene's 600 × 400: RawTherapee 5.9 refused (``Error loading file``) smaller ones we tried
(256 × 128, 180 × 160, 160 × 108) and took 240 × 160 and up.

darktable 4.2 reads no BlackLevel of an image of more than one sample per pixel (rawspeed
``DngDecoder::decodeBlackLevels``: ``getCpp() != 1``): it takes the three-chip frame's black level from the
``NAME.dng.xmp`` sidecar camsim writes beside the DNG, and without it subtracts nothing.
"""

import importlib.util
import json

import pytest

from tests.support.helpers import ROOT

_spec = importlib.util.spec_from_file_location("raw_readers", ROOT / "tools" / "raw_readers.py")
raw_readers = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(raw_readers)

pytestmark = pytest.mark.slow  # renders four frames and runs the raw developers (about 20 s)

DARK_MAX = 20.0
BLACK_PATCH_TOLERANCE = 0.25
GREY_TOLERANCE = 0.08


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """Chart (F = 1) and dark (F = 1e-6) frames of the default scene, three-chip and Bayer RGGB."""
    folder = tmp_path_factory.mktemp("readers")
    out = {}
    for layout, extra in raw_readers.LAYOUTS.items():
        slug = layout.split()[0].lower()
        chart = raw_readers.render(folder / f"{slug}-chart", 1.0, extra, None)
        out[layout] = {"chart": chart, "dark": raw_readers.render(folder / f"{slug}-dark", 1e-6, extra, None),
                       "meta": json.loads(chart.with_suffix(".json").read_text())}
    return out


@pytest.mark.parametrize("layout", [
    "Bayer RGGB",
    "three-chip",
])
@pytest.mark.parametrize("reader", [
    "rawpy",
    "dcraw",
    "RawTherapee",
    "darktable",
])
def test_the_default_frame_develops_with_black_subtracted_and_no_cast(frames, reader, layout):
    if not raw_readers.available(reader):
        pytest.skip(f"{reader} is not installed")
    frame = frames[layout]
    dark = raw_readers.develop(reader, frame["dark"], dark=True).reshape(-1, 3).mean(0)
    assert dark.max() < DARK_MAX, f"{reader} {layout}: dark frame {dark.round(1).tolist()}: black not subtracted"
    picture = raw_readers.develop(reader, frame["chart"])
    for name, tolerance in (("black", BLACK_PATCH_TOLERANCE), ("neutral 3.5", GREY_TOLERANCE),
                            ("neutral 5", GREY_TOLERANCE)):
        r, g, b = raw_readers.patch_rgb(picture, frame["meta"], raw_readers.PATCHES[name])
        assert abs(r / g - 1) <= tolerance and abs(b / g - 1) <= tolerance, (
            f"{reader} {layout}: {name} patch R, G, B {r:.1f}, {g:.1f}, {b:.1f}: a cast")


def test_darktable_takes_a_three_chip_black_level_only_from_its_sidecar(frames, tmp_path):
    """Without ``NAME.dng.xmp`` darktable develops the three-chip frame from black 0 (its dark frame shows the 5–6 DN
    black level); the DNG is the same either way. A Bayer frame gets no sidecar: darktable reads its BlackLevel."""
    if not raw_readers.available("darktable"):
        pytest.skip("darktable is not installed")
    dark = frames["three-chip"]["dark"]
    assert dark.with_name(dark.name + ".xmp").is_file()
    assert not list(frames["Bayer RGGB"]["dark"].parent.glob("*.xmp"))
    bare = tmp_path / dark.name
    bare.write_bytes(dark.read_bytes())
    assert raw_readers.develop("darktable", bare, dark=True).reshape(-1, 3).mean(0).min() > 2 * DARK_MAX
