"""The MTF figure of the docs: a built-in slanted edge rendered (noise on) and measured by ``camsim analyze``.

Renders SCENE (default: ``camsim/scenes/slanted_edge_lens.toml`` where it exists — the slanted edge behind an f/4
lens with diffraction and OLPF —, else ``slanted_edge.toml``, the bare target) at F = 1 and ``--size``, measures it
with ``camsim analyze`` (its e-SFR per channel beside the model of the sidecar's optics record) and copies the
figure to ``--png`` (default ``docs/mtf_<scene file's stem>.png``: the guide's ``docs/mtf_slanted_edge_lens.png`` and
``docs/mtf_slanted_edge.png``); prints the MTF50 and MTF at Nyquist per channel::

    python tools/mtf_figure.py [SCENE] [--size 400x800] [--png FILE]
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from camsim.cli import main  # noqa: E402


def run(argv=None) -> int:
    lens = ROOT / "camsim" / "scenes" / "slanted_edge_lens.toml"
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(lens if lens.exists() else lens.with_name("slanted_edge.toml")))
    parser.add_argument("--size", default="400x800")
    parser.add_argument("--png", type=Path)
    args = parser.parse_args(argv)
    if args.png is None:
        args.png = ROOT / "docs" / f"mtf_{Path(args.scene).stem}.png"
    with tempfile.TemporaryDirectory() as tmp:
        frames, out = Path(tmp) / "frames", Path(tmp) / "analysis"
        if main(["render", args.scene, "--size", args.size, "--intensity", "1", "--illuminant", "D65", "-q",
                 "--out", str(frames)]) != 0:
            return 2
        frame = next(frames.glob("*.dng"), None) or next(frames.glob("*.exr"))
        if main(["analyze", str(frame), "--out", str(out), "-q"]) != 0:
            return 2
        record = json.loads((out / "analysis.json").read_text())["frames"][0]["mtf"]
        for ch in record["channels"]:
            model = ch["model_mtf50_cy_per_px"]
            print(f"{ch['channel']:8s} MTF50 {ch['mtf50_cy_per_px']:.4f} cy/px (model "
                  f"{'—' if model is None else format(model, '.4f')}), MTF at Nyquist {ch['mtf_nyquist']:.4f}")
        shutil.copyfile(out / record["figure"], args.png)
    print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(run())
