"""Peak resident memory of reading a large ENVI cube through :func:`camsim.io.cube_files.read_cube`.

Writes a 4000 × 3000 × 101 float32 ENVI cube (BSQ by default: the least favourable layout for row blocks; 4.8 GB)
to a temporary folder, then in a fresh Python process for each case reads it with ``read_cube`` (which checks every
value in one pass, block by block) and converts every block to float64 on the scene grid (``CubeData.blocks``, the
pass a renderer makes), printing the process's peak RSS (``VmHWM``, which counts the file pages mapped into the
process as well as its own memory) before and after. Cases: the default, and the same with the mapped pages left
resident (``CubeData._release`` off), to show what releasing them does; and a render of one frame of a ``[cube]``
scene of the file (``paper-table1``, D65, F = 1, ``poisson``, 2 workers): the cube's pixels are the coefficients
of factored spectra (:class:`camsim.io.cube_files.CubeRows`), so its expected electrons are one pass over the file
and the frame needs (H · W, 3) moments, not the H · W · N spectra (9.7 GB as float64).

    PYTHONPATH=. python tools/bench_cube_rss.py [--interleave bsq|bil|bip] [--keep DIR]

Nothing is asserted: it prints the figures the docs (benchmarks page) quote.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HEIGHT, WIDTH, BANDS = 3000, 4000, 101


def write_cube(folder: Path, interleave: str) -> Path:
    """A float32 cube of smooth positive values, written band by band (or row by row) with bounded memory."""
    binary = folder / "big.img"
    rows = np.linspace(0.1, 0.9, HEIGHT, dtype=np.float32)[:, None]
    cols = np.linspace(0.5, 1.0, WIDTH, dtype=np.float32)[None, :]
    with open(binary, "wb") as f:
        if interleave == "bsq":
            for b in range(BANDS):
                f.write((rows * cols * (0.5 + b / (2 * BANDS))).astype("<f4").tobytes())
        else:
            bands = (0.5 + np.arange(BANDS, dtype=np.float32) / (2 * BANDS))
            for i in range(HEIGHT):
                line = rows[i, 0] * cols[0][:, None] * bands[None, :]  # W × B
                f.write(np.ascontiguousarray(line.T if interleave == "bil" else line).astype("<f4").tobytes())
    wavelengths = ", ".join(f"{380 + 4 * b:g}" for b in range(BANDS))
    header = folder / "big.hdr"
    header.write_text(f"ENVI\nsamples = {WIDTH}\nlines = {HEIGHT}\nbands = {BANDS}\nheader offset = 0\n"
                      f"data type = 4\ninterleave = {interleave}\nbyte order = 0\nwavelength units = Nanometers\n"
                      f"wavelength = {{{wavelengths}}}\n")
    return header


def vm_hwm_mib() -> float:
    """Peak resident set size of this process (VmHWM), MiB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmHWM in /proc/self/status")


def measure(header: str, release: bool) -> None:
    """Run in a child process: read the cube, pass over its blocks, print the peak RSS."""
    from camsim.io import cube_files
    from camsim.light.spectra import WavelengthGrid, import_colour

    import_colour()
    if not release:
        cube_files.CubeData._release = lambda self: None
    grid = WavelengthGrid()
    before = vm_hwm_mib()
    t0 = time.perf_counter()
    cube = cube_files.read_cube(header, grid)
    t1 = time.perf_counter()
    after_read = vm_hwm_mib()
    total = 0.0
    for _, block in cube.blocks():
        total += float(block[:, :, 50].sum())
    t2 = time.perf_counter()
    after_blocks = vm_hwm_mib()
    print(f"  release={release}: peak RSS after imports {before:.0f} MiB; after read_cube (checked every value) "
          f"{after_read:.0f} MiB ({t1 - t0:.1f} s); after a pass over every block on the grid {after_blocks:.0f} "
          f"MiB ({t2 - t1:.1f} s); block = {cube.block_rows} rows; resampled: {cube.resample is not None}; "
          f"checksum {total:.6g}")


def measure_render(header: str) -> None:
    """Run in a child process: render one frame of a [cube] scene of the file (paper-table1, D65, F = 1, poisson,
    2 workers), print the peak RSS and the times."""

    from camsim.render.pipeline import light_scene, make_frame
    from camsim.scene.scene_file import load_scene
    from camsim.scene.sources import CubeSource

    scene = load_scene(Path(__file__).resolve().parents[1] / "scenes" / "macbeth_26.toml")
    scene = scene.replace(source=CubeSource(path=Path(header)), illuminants=("D65",), intensity_factors=(1.0,),
                          preset_name="paper-table1", statistics="pixel")
    before = vm_hwm_mib()
    t0 = time.perf_counter()
    lit = light_scene(scene, "D65")
    t1 = time.perf_counter()
    expected = lit.expected(scene.sensor, 1.0, "pixel")
    t2 = time.perf_counter()
    after_expected = vm_hwm_mib()
    frame = make_frame(lit, scene.sensor, 1.0, statistics="pixel", method="poisson", rng=0,
                       workers=2)
    t3 = time.perf_counter()
    print(f"  render: peak RSS after imports {before:.0f} MiB; light_scene (reads, checks) {t1 - t0:.1f} s; expected "
          f"electrons of every pixel (one pass over the file) {t2 - t1:.1f} s, peak {after_expected:.0f} MiB; "
          f"make_frame (expected again + draws, 2 workers) {t3 - t2:.1f} s, peak {vm_hwm_mib():.0f} MiB; "
          f"mean DN {float(frame.digital_dn.mean()):.2f}; spectra per pixel: {expected.signal_e.shape[0]}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--interleave", choices=("bsq", "bil", "bip"), default="bsq")
    parser.add_argument("--keep", help="write the cube here (kept) instead of a temporary folder")
    parser.add_argument("--measure", help=argparse.SUPPRESS)
    parser.add_argument("--no-release", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--measure-render", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        measure(args.measure, release=not args.no_release)
        return 0
    if args.measure_render:
        measure_render(args.measure_render)
        return 0
    with tempfile.TemporaryDirectory(dir=args.keep) as tmp:
        folder = Path(args.keep or tmp)
        t0 = time.perf_counter()
        header = write_cube(folder, args.interleave)
        size = (folder / "big.img").stat().st_size
        print(f"{WIDTH} × {HEIGHT} × {BANDS} float32 ENVI cube, {args.interleave}: {size / 2**30:.2f} GiB "
              f"(written in {time.perf_counter() - t0:.0f} s)")
        env = dict(os.environ)
        for flags in (["--measure", str(header)], ["--measure", str(header), "--no-release"],
                      ["--measure-render", str(header)]):
            subprocess.run([sys.executable, __file__, *flags], check=True, env=env)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
