"""How the four raw readers develop camsim's DNGs: a table of the black and grey patches, per reader and layout.

Renders the default scene (``macbeth_26``, Table I sensor, 8 bits, D65, F = 1) as a three-chip LinearRaw DNG and as
a Bayer (``--cfa RGGB``) DNG, plus a dark frame of each (F = 1e-6: the black level and noise only), and develops
each with every reader installed, each with its own default pipeline to an 8-bit-scaled sRGB picture:

* rawpy (LibRaw): ``postprocess(use_camera_wb=True)`` (chart; dark frame with ``no_auto_bright=True``);
* dcraw: ``dcraw -c -w -T`` (chart; dark frame with ``-W``, no auto-brightening);
* darktable: ``darktable-cli IN OUT.tif --core --configdir TMP --library :memory:`` (its default scene-referred
  pipeline; it reads a three-chip frame's black level from camsim's ``NAME.dng.xmp`` sidecar by itself);
* RawTherapee: ``rawtherapee-cli -o OUT.tif -t -Y -c IN`` (its default profile; it crops 4 pixels at each edge).

Printed per reader and layout: the developed dark frame's mean R, G, B (black honoured: near 0; a reader that
subtracts no black shows the black level through its tone curve), and the ColorChecker's black (patch 24), neutral
3.5 (23) and neutral 5 (22) patches as R, G, B with R/G and B/G (1 = neutral: no cast). Run from the repository
root::

    python tools/raw_readers.py            # about 20 s
    python tools/raw_readers.py --keep DIR # keep the DNGs and the developed pictures in DIR
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PATCHES = {"black": 23, "neutral 3.5": 22, "neutral 5": 21}  # ColorChecker order, 0-based
LAYOUTS = {"three-chip": (), "Bayer RGGB": ("--cfa", "RGGB")}
READERS = ("rawpy", "dcraw", "darktable", "RawTherapee")


def render(out: Path, intensity: float, extra: tuple, size: str | None) -> Path:
    """One frame of the default scene (D65) rendered by ``camsim render`` (in this process) into ``out``; its DNG."""
    from camsim.cli import main

    argv = ["render", "macbeth_26", "--illuminant", "D65", "--intensity", str(intensity), "--out", str(out), "-q",
            *extra, *(("--size", size) if size else ())]
    if main(argv) != 0:
        raise RuntimeError(f"camsim {' '.join(argv)} failed")
    return next(out.glob("*.dng"))


def available(reader: str) -> bool:
    """Whether ``reader`` can run here."""
    if reader == "rawpy":
        try:
            import rawpy  # noqa: F401
        except ImportError:
            return False
        return True
    return shutil.which({"dcraw": "dcraw", "darktable": "darktable-cli", "RawTherapee": "rawtherapee-cli"}[reader]) \
        is not None


def develop(reader: str, dng: Path, dark: bool = False) -> np.ndarray:
    """``dng`` developed by ``reader`` with its defaults: (H, W, 3) float, 0–255 (16-bit outputs scaled by 1/257).

    ``dark``: a dark frame, developed without auto-brightening where the reader has it (rawpy, dcraw).
    """
    import tifffile

    out = dng.with_name(f"{dng.stem}.{reader}.tif")
    if reader == "rawpy":
        import rawpy

        with rawpy.imread(str(dng)) as raw:
            return raw.postprocess(use_camera_wb=True, no_auto_bright=dark).astype(np.float64)
    if reader == "dcraw":
        with open(out, "wb") as fh:
            subprocess.run(["dcraw", "-c", "-w", "-T", *(["-W"] if dark else []), str(dng)], stdout=fh, check=True,
                           stderr=subprocess.DEVNULL, timeout=300)
    elif reader == "darktable":
        with tempfile.TemporaryDirectory() as config:
            subprocess.run(["darktable-cli", str(dng), str(out), "--core", "--configdir", config, "--library",
                            ":memory:"], check=True, capture_output=True, timeout=300)
    else:
        subprocess.run(["rawtherapee-cli", "-o", str(out), "-t", "-Y", "-c", str(dng)], check=True,
                       capture_output=True, timeout=300)
    if not out.exists():
        raise RuntimeError(f"{reader} wrote no picture for {dng}")
    image = tifffile.imread(out)[..., :3].astype(np.float64)
    return image / 257 if image.max() > 255 else image


def patch_rgb(image: np.ndarray, meta: dict, index: int, border: int = 6) -> np.ndarray:
    """Mean R, G, B of patch ``index`` (0-based) of the chart in a developed picture, centred as the reader
    cropped it (RawTherapee takes 4 pixels off each edge)."""
    dy = (image.shape[0] - meta["height_px"]) // 2
    dx = (image.shape[1] - meta["width_px"]) // 2
    x, y, w, h = meta["patches"][index]["rect_xywh"]
    return image[y + dy + border: y + dy + h - border, x + dx + border: x + dx + w - border].reshape(-1, 3).mean(0)


def measure(folder: Path, size: str | None = None, readers=READERS) -> list[dict]:
    """Render the frames into ``folder`` and develop them: one record per (layout, reader) installed."""
    rows = []
    for layout, extra in LAYOUTS.items():
        slug = layout.split()[0].lower()
        chart = render(folder / f"{slug}-chart", 1.0, extra, size)
        dark = render(folder / f"{slug}-dark", 1e-6, extra, size)
        meta = json.loads(chart.with_suffix(".json").read_text())
        black_dn = meta.get("black_level_tag_dn", meta["black_level_dn"])
        for reader in readers:
            if not available(reader):
                continue
            picture = develop(reader, chart)
            patches = {name: patch_rgb(picture, meta, i) for name, i in PATCHES.items()}
            rows.append({"layout": layout, "reader": reader, "black_level_dn": black_dn,
                         "dark_rgb": develop(reader, dark, dark=True).reshape(-1, 3).mean(0), "patches": patches})
    return rows


def _rgb(v) -> str:
    return "/".join(f"{c:.0f}" for c in v)


def _ratios(v) -> str:
    return f"{v[0] / v[1]:.2f} / {v[2] / v[1]:.2f}"


def table(rows: list[dict]) -> str:
    """The records as a Markdown table."""
    lines = ["| layout | reader | dark frame R/G/B | black patch R/G/B | black R/G, B/G | neutral 3.5 R/G, B/G | "
             "neutral 5 R/G, B/G |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        p = r["patches"]
        lines.append(f"| {r['layout']} | {r['reader']} | {_rgb(r['dark_rgb'])} | {_rgb(p['black'])} | "
                     f"{_ratios(p['black'])} | {_ratios(p['neutral 3.5'])} | {_ratios(p['neutral 5'])} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", metavar="DIR", type=Path, help="write the frames and pictures here and keep them")
    parser.add_argument("--size", metavar="WxH", help="frame size (default the scene's 600x400)")
    args = parser.parse_args(argv)
    missing = [r for r in READERS if not available(r)]
    if missing:
        print(f"not installed (left out): {', '.join(missing)}", file=sys.stderr)
    if args.keep:
        args.keep.mkdir(parents=True, exist_ok=True)
        rows = measure(args.keep, args.size)
    else:
        with tempfile.TemporaryDirectory() as folder:
            rows = measure(Path(folder), args.size)
    print(f"black level (DN, R/G/B): {', '.join(f'{b:.4f}' for b in rows[0]['black_level_dn'])}" if rows else "")
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
