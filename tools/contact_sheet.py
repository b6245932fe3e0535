"""A contact sheet of sRGB previews: the default scene under D65 and A at several intensity factors F.

Renders ``scenes/macbeth_26.toml`` (its sensor, camera, statistics and seed) at a modest size, develops every
frame with :func:`camsim.render.preview.preview_srgb` and tiles the pictures, at their own pixels (no resampling), into
one labelled PNG:

* row 1, D65 and row 2, A: the preview's default exposure (``"scene"``): the perfect white at F = 1 is sRGB
  white, so the frames darken with F as the light does — the PNGs ``camsim render --preview`` writes;
* row 3, D65 with the preview's ``exposure="auto"`` (a display gain 1 / F, not the sensor's auto exposure): every F
  shown like F = 1, so the low-light noise (shot noise, dark current, read noise and the 8-bit quantisation steps) is
  amplified with the signal.

The frames are those of ``camsim render scenes/macbeth_26.toml --illuminant D65 A --intensity ... --size WxH``
(same seeds).

    python tools/contact_sheet.py [--size 150x100] [--out docs/contact_sheet.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FACTORS = (1.0, 0.3, 0.1, 0.03, 0.01, 0.003)
ROWS = (("D65", "scene"), ("A", "scene"), ("D65", "auto"))
ROW_LABELS = {
    ("D65", "scene"): "D65",
    ("A", "scene"): "A (tungsten),\nwhite-balanced",
    ("D65", "auto"): "D65, preview\ngain × 1/F",
}


def previews(scene, illuminant, factors, exposure):
    """sRGB previews of ``scene`` under ``illuminant`` at each F, as ``camsim render --preview`` makes them."""
    from camsim.render.pipeline import light_scene, scene_frame
    from camsim.render.preview import preview_srgb

    lit = light_scene(scene, illuminant)
    pictures = []
    for factor in factors:
        frame, info = scene_frame(scene, illuminant, factor, lit=lit)
        pictures.append(preview_srgb(frame, info, exposure=exposure))
    return pictures


def contact_sheet(rows, factors, tile_shape, path):
    """Tile ``rows`` (lists of (H, W, 3) uint8 pictures) with labels into a PNG at ``path``, pixel for pixel."""
    import matplotlib

    matplotlib.use("Agg")
    import imageio.v3 as iio
    import matplotlib.pyplot as plt

    from camsim.io.atomic import atomic_path

    height, width = tile_shape
    gap, left, top, bottom = 8, 132, 30, 30
    n_rows, n_cols = len(rows), len(factors)
    fig_w = left + n_cols * width + (n_cols - 1) * gap + gap
    fig_h = top + n_rows * height + (n_rows - 1) * gap + bottom
    dpi = 100
    fig = plt.figure(figsize=(fig_w / dpi, fig_h / dpi), dpi=dpi, facecolor="white")
    for r, (label, pictures) in enumerate(rows):
        y0 = bottom + (n_rows - 1 - r) * (height + gap)  # figimage counts pixels from the bottom
        fig.text((left - 10) / fig_w, (y0 + height / 2) / fig_h, label, ha="right", va="center", fontsize=10)
        for c, picture in enumerate(pictures):
            fig.figimage(picture, xo=left + c * (width + gap), yo=y0, origin="upper")
    for c, factor in enumerate(factors):
        x = (left + c * (width + gap) + width / 2) / fig_w
        fig.text(x, 1 - (top - 8) / fig_h, f"F = {factor:g}", ha="center", va="bottom", fontsize=11)
    fig.text(0.5, 6 / fig_h, "ColorChecker (scenes/macbeth_26.toml), 100 cd/m² white at F = 1, Table I sensor, "
             "8-bit; camsim preview: least-squares camera → XYZ, von Kries to D65, sRGB",
             ha="center", va="bottom", fontsize=8, color="0.3")
    fig.canvas.draw()
    sheet = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()  # RGB: an alpha channel only costs bytes
    plt.close(fig)
    for r, (_, pictures) in enumerate(rows):  # the tiles are the previews' own pixels
        y0 = top + r * (height + gap)
        for c, picture in enumerate(pictures):
            x0 = left + c * (width + gap)
            assert np.array_equal(sheet[y0:y0 + height, x0:x0 + width], picture), (r, c)
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, sheet, extension=".png", optimize=True)  # no timestamp: same frames, same bytes
    return sheet


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="150x100", help="frame size WxH (pixels), default 150x100")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "contact_sheet.png")
    args = parser.parse_args(argv)
    from camsim.scene.scene_file import load_scene

    width, height = (int(v) for v in args.size.lower().split("x"))
    scene = load_scene(ROOT / "scenes" / "macbeth_26.toml").replace(width=width, height=height)
    rows = [(ROW_LABELS[(ill, exposure)], previews(scene, ill, FACTORS, exposure)) for ill, exposure in ROWS]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    contact_sheet(rows, FACTORS, (height, width), args.out)
    print(f"{args.out} ({args.out.stat().st_size / 1024:.0f} KiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
