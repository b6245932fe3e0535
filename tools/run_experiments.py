"""Run every experiment of the paper (``camsim experiment all``), with the default camera and — when the SFU data
is present beside the repository — again with the paper's own camera, the Sony DXC-930.

    python tools/run_experiments.py [--out outputs/experiments]

Writes OUT/nikon/<experiment>/report.md and, with the SFU curves, OUT/sony-dxc930/<experiment>/report.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SONY = ROOT.parent / "shared" / "data" / "sfu" / "sony_dxc930_rgb_sensitivities_380_780_4nm.csv"


def main() -> int:
    from camsim.cli import main as camsim

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "outputs" / "experiments")
    args = parser.parse_args()
    code = camsim(["experiment", "all", "--out", str(args.out / "nikon")])
    if SONY.is_file():
        code = code or camsim(["experiment", "all", "--camera", str(SONY), "--out", str(args.out / "sony-dxc930")])
    else:
        print(f"SFU Sony DXC-930 curves not found at {SONY}: ran the default camera only")
    return code


if __name__ == "__main__":
    sys.exit(main())
