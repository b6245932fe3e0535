"""Make ``camsim/scenes/images/``: three small photographs from scikit-image's bundled sample data.

``astronaut`` (NASA, public domain), ``coffee`` and ``chelsea`` (CC0), as ``skimage.data`` gives them
(8-bit sRGB), downscaled in linear light (sRGB decoded, area-weighted anti-aliased resampling, sRGB encoded) to
:data:`LONG_SIDE` pixels on the long side and written as PNG: natural content for the example dataset
``scenes/denoise_small.toml``, small enough to commit. See ``camsim/scenes/images/README.md`` for the sources
and licences.

Run:  python tools/make_example_images.py   (needs scikit-image and Pillow; overwrites the three files)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "camsim" / "scenes" / "images"
NAMES = ("astronaut", "coffee", "chelsea")
#: Pixels on the long side of each image.
LONG_SIDE = 432


def srgb_decode(v: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] → linear (IEC 61966-2-1)."""
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def srgb_encode(x: np.ndarray) -> np.ndarray:
    """Linear values in [0, 1] → sRGB-encoded (IEC 61966-2-1)."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def main() -> None:
    from PIL import Image
    from skimage import data, transform

    OUT.mkdir(parents=True, exist_ok=True)
    for name in NAMES:
        image = getattr(data, name)()[:, :, :3]
        scale = LONG_SIDE / max(image.shape[:2])
        linear = srgb_decode(image / 255.0)
        if scale < 1:
            linear = transform.rescale(linear, scale, channel_axis=2, anti_aliasing=True, order=1)
        codes = np.clip(np.round(srgb_encode(linear) * 255), 0, 255).astype(np.uint8)
        path = OUT / f"{name}.png"
        tmp = path.with_name(f".{path.name}.partial")
        Image.fromarray(codes).save(tmp, format="PNG", optimize=True)
        tmp.replace(path)
        print(f"{path.relative_to(ROOT)}: {codes.shape[1]} x {codes.shape[0]}, {path.stat().st_size // 1024} kB")


if __name__ == "__main__":
    main()
