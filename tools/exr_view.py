"""An EXR frame as an image viewer shows it, and the black and white patches' values there.

Reads ``FRAME.exr`` with OpenImageIO plainly — the first subimage, its channels ``R, G, B`` (the channels a
viewer such as OpenImageIO's ``iv`` or ``oiiotool`` displays by default), no colour management — and writes what a
viewer puts on an sRGB screen: the values clamped to [0, 1] and sRGB-encoded (IEC 61966-2-1), as an 8-bit PNG.
Prints each ColorChecker patch's mean R, G, B as read (the sidecar in the EXR's header gives the patch
rectangles), the black and white patches first.

    python tools/exr_view.py FRAME.exr [--png OUT.png] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def viewer_rgb(path: str | Path) -> np.ndarray:
    """The pixels a viewer shows: OpenImageIO's first subimage, channels ``R, G, B``, shape (H, W, 3), float32."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise SystemExit(f"cannot open {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        names = list(spec.channelnames)
        pixels = np.asarray(inp.read_image(0, 0, 0, spec.nchannels, "float")).reshape(spec.height, spec.width, -1)
    finally:
        inp.close()
    if all(c in names for c in "RGB"):
        return pixels[..., [names.index(c) for c in "RGB"]]
    return np.repeat(pixels[..., :1], 3, axis=-1)  # a one-channel file: grey, as viewers show it


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Clamp to [0, 1] and encode with the sRGB transfer function; 8-bit, rounded to nearest."""
    x = np.clip(np.nan_to_num(linear, nan=0.0), 0.0, 1.0).astype(np.float64)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(encoded * 255.0).astype(np.uint8)


def patch_means(path: str | Path, rgb: np.ndarray) -> dict[str, list[float]]:
    """Each patch's mean R, G, B as the viewer reads them, from the rectangles of the sidecar in the header."""
    from camsim.render.frame_files import read_frame_meta

    meta = read_frame_meta(path)
    out = {}
    for patch in meta.get("patches") or []:
        x, y, w, h = patch["rect_xywh"]
        out[patch["name"]] = rgb[y:y + h, x:x + w].reshape(-1, 3).mean(axis=0).tolist()
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("exr", type=Path)
    parser.add_argument("--png", type=Path, help="write the viewer's picture here (8-bit sRGB PNG)")
    parser.add_argument("--json", action="store_true", help="print the patch means as JSON")
    args = parser.parse_args(argv)
    rgb = viewer_rgb(args.exr)
    if args.png:
        from PIL import Image

        args.png.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(srgb_encode(rgb)).save(args.png)
    means = patch_means(args.exr, rgb)
    order = sorted(means, key=lambda n: (not n.startswith("black"), not n.startswith("white")))
    if args.json:
        print(json.dumps({name: means[name] for name in order}))
    else:
        print(f"{args.exr}: viewer's R, G, B (OpenImageIO, first subimage), patch means; whole frame "
              f"min {np.nanmin(rgb):.4g}, max {np.nanmax(rgb):.4g}")
        for name in order:
            print(f"  {name:24s} " + " ".join(f"{v:9.4f}" for v in means[name]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
