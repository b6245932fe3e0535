"""Every EXR compression OpenEXR offers, on a 1-megapixel frame's noisy and clean layers: bytes, write and read time,
and whether it gives back every float32 bit; and the Zarr store's chunk compressors, on the same layers.

The frame: the ColorChecker of ``scenes/macbeth_26.toml`` at 1152 × 864 (0.995 MP), D65, F = 0.1, method
``poisson``, seed 1, with the ``emva-12bit`` sensor (DSNU and PRNU on: the clean layer has a per-pixel pattern)
and with ``paper-table1`` (no fixed pattern: the clean layer is constant over each patch). For each sensor and
compression, the noisy layer (``R, G, B``), the clean layer (``clean.R, clean.G, clean.B``) and both (the file
camsim writes) are written with one OpenEXR thread (as a dataset worker writes, ``--threads 1``) and read back
whole (``OpenEXR.File``). Times are medians over ``--repeats`` rounds, each round going through every
compression once (interleaved, so that a change in the machine's load hits them alike). ``exact``: every bit of
every value read back equals the one written (NaN payloads included).

With zarr installed, the same layers (and the digital numbers) as chunks of a Zarr array (one chunk per frame, as
``camsim dataset --format zarr`` writes them; zarr's codec threads limited to one) with each of :data:`ZARR_CODECS`
(``blosc-lz4-5``, Blosc LZ4 level 5 with byte shuffle, is the store's: :mod:`camsim.dataset.zarr_store`).

Run:  python tools/bench_exr_compression.py [--repeats R] [--markdown]
Progress goes to stderr; the last stdout line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import OpenEXR

ROOT = Path(__file__).resolve().parents[1]
WIDTH, HEIGHT = 1152, 864
PRESETS = ("emva-12bit", "paper-table1")
LAYERS = ("noisy", "clean", "both")
#: Zarr chunk compressors measured: name -> a function of the zarr module giving the compressors list.
ZARR_CODECS = {
    "none": lambda zarr: None,
    "zstd-0 (zarr's default)": lambda zarr: [zarr.codecs.ZstdCodec(level=0)],
    "blosc-lz4-5": lambda zarr: [zarr.codecs.BloscCodec(cname="lz4", clevel=5, shuffle="shuffle")],
    "blosc-lz4-1": lambda zarr: [zarr.codecs.BloscCodec(cname="lz4", clevel=1, shuffle="shuffle")],
    "blosc-zstd-1": lambda zarr: [zarr.codecs.BloscCodec(cname="zstd", clevel=1, shuffle="shuffle")],
}


def frame_layers(preset: str) -> dict:
    """The noisy and clean layers of the benchmark frame, as EXR channels (and, under ``arrays``, as the Zarr
    store's layers)."""
    from camsim.io.exr import CLEAN_CHANNELS, NOISY_CHANNELS
    from camsim.render.pipeline import scene_frame
    from camsim.scene.scene_file import load_scene

    scene = load_scene(ROOT / "scenes" / "macbeth_26.toml").replace(width=WIDTH, height=HEIGHT, preset_name=preset,
                                                                   method="poisson")
    frame, _ = scene_frame(scene, "D65", 0.1, seed=1, workers=1)
    noisy = {c: np.ascontiguousarray(frame.noisy_dn[i]) for i, c in enumerate(NOISY_CHANNELS)}
    clean_dn = frame.clean_dn()
    clean = {c: np.ascontiguousarray(clean_dn[i]) for i, c in enumerate(CLEAN_CHANNELS)}
    digital = frame.digital_dn.astype(np.uint8 if frame.sensor.bits <= 8 else np.uint16)
    return {"noisy": noisy, "clean": clean, "both": noisy | clean,
            "arrays": {"noisy": frame.noisy_dn, "clean": clean_dn, "digital": digital}}


def zarr_figures(layers: dict, folder: Path, repeats: int) -> dict:
    """(codec, layer) -> bytes, write_ms, read_ms, exact, for each of :data:`ZARR_CODECS`; {} without zarr."""
    try:
        import zarr
    except ImportError:
        return {}
    zarr.config.set({"threading.max_workers": 1})
    arrays = layers["arrays"]
    times = {(codec, layer): ([], []) for codec in ZARR_CODECS for layer in arrays}
    out = {}
    for repeat in range(repeats):
        for n, (codec, make) in enumerate(ZARR_CODECS.items()):
            group = zarr.open_group(folder / f"store{n}.zarr", mode="w")
            for layer, value in arrays.items():
                array = group.create_array(layer, shape=(1, *value.shape), chunks=(1, *value.shape),
                                           dtype=value.dtype, compressors=make(zarr),
                                           chunk_key_encoding={"name": "default", "separator": "."})
                start = time.perf_counter()
                array[0] = value
                written = time.perf_counter() - start
                start = time.perf_counter()
                back = array[0]
                times[codec, layer][0].append(written)
                times[codec, layer][1].append(time.perf_counter() - start)
                if repeat == 0:
                    out[codec, layer] = {"bytes": (folder / f"store{n}.zarr" / layer / "c.0.0.0.0").stat().st_size,
                                         "exact": np.array_equal(back.view(np.uint8), value.view(np.uint8))}
    for key, (writes, reads) in times.items():
        out[key].update(write_ms=1e3 * statistics.median(writes), read_ms=1e3 * statistics.median(reads))
    return out


def write(path: Path, constant, channels: dict) -> float:
    header = {"compression": constant, "type": OpenEXR.scanlineimage, "lineOrder": OpenEXR.INCREASING_Y}
    start = time.perf_counter()
    with OpenEXR.File(header, dict(channels)) as exr:  # the bindings replace the dict's arrays by Channels
        exr.write(str(path))
    return time.perf_counter() - start


def read(path: Path) -> tuple[float, dict]:
    start = time.perf_counter()
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        pixels = {name: channel.pixels.copy() for name, channel in exr.channels().items()}
    return time.perf_counter() - start, pixels


def exact(written: dict, back: dict) -> bool:
    return all(back[c].dtype == np.float32 and np.array_equal(back[c].view(np.uint32), v.view(np.uint32))
               for c, v in written.items())


def main() -> None:
    from camsim.io.exr import DEFAULT_EXR_COMPRESSION, EXR_COMPRESSIONS

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5, help="rounds over every compression (default 5)")
    parser.add_argument("--markdown", action="store_true",
                        help="print the table as Markdown (the docs' benchmarks page)")
    args = parser.parse_args()
    OpenEXR.set_global_thread_count(1)
    offered = {name: entry for name, entry in EXR_COMPRESSIONS.items() if hasattr(OpenEXR, entry[0])}
    results = {}
    zarr_results = {}
    with tempfile.TemporaryDirectory(prefix="camsim-bench-exr-") as tmp:
        path = Path(tmp) / "frame.exr"
        for preset in PRESETS:
            layers = frame_layers(preset)
            zarr_results.update({(preset, *key): value
                                 for key, value in zarr_figures(layers, Path(tmp), args.repeats).items()})
            times = {(name, layer): ([], []) for name in offered for layer in LAYERS}
            for repeat in range(args.repeats):
                for name, (constant, lossless, _) in offered.items():
                    for layer in LAYERS:
                        written = write(path, getattr(OpenEXR, constant), layers[layer])
                        took, back = read(path)
                        times[name, layer][0].append(written)
                        times[name, layer][1].append(took)
                        if repeat == 0:
                            results[preset, name, layer] = {"bytes": path.stat().st_size,
                                                            "exact": exact(layers[layer], back)}
                print(f"{preset}: round {repeat + 1} of {args.repeats}", file=sys.stderr)
            for (name, layer), (writes, reads) in times.items():
                results[preset, name, layer].update(write_ms=1e3 * statistics.median(writes),
                                                    read_ms=1e3 * statistics.median(reads))

    raw = WIDTH * HEIGHT * 4 * 3  # one layer, uncompressed
    print(f"EXR compression of a {WIDTH}x{HEIGHT} frame (float32; one layer = 3 channels, {raw / 1e6:.2f} MB "
          f"raw), OpenEXR {OpenEXR.__version__}, 1 thread, median of {args.repeats} interleaved rounds; "
          f"default: {DEFAULT_EXR_COMPRESSION}")
    for preset in PRESETS:
        print(f"  {preset}:")
        for name, (_, lossless, note) in offered.items():
            cells = "  ".join(f"{layer} {results[preset, name, layer]['bytes'] / 1e6:6.2f} MB "
                              f"w {results[preset, name, layer]['write_ms']:6.1f} ms "
                              f"r {results[preset, name, layer]['read_ms']:6.1f} ms" for layer in LAYERS)
            exactness = "exact" if all(results[preset, name, layer]["exact"] for layer in LAYERS) else "LOSSY"
            print(f"    {name:<9} {cells}  {exactness}{'' if lossless else ' (refused: ' + note + ')'}")
    if args.markdown:
        print("\n| compression | lossless for float32 | " + " | ".join(
            f"{p} {layer}: MB, write / read ms" for p in PRESETS for layer in ("noisy", "clean", "both")) + " |")
        print("|---|---|" + "---|" * (len(PRESETS) * 3))
        for name, (_, lossless, note) in offered.items():
            measured = all(results[p, name, layer]["exact"] for p in PRESETS for layer in LAYERS)
            label = "yes" if lossless else f"no ({note})" if not measured else f"bit-exact, refused ({note})"
            cells = " | ".join(f"{results[p, name, layer]['bytes'] / 1e6:.2f}, "
                               f"{results[p, name, layer]['write_ms']:.0f} / {results[p, name, layer]['read_ms']:.0f}"
                               for p in PRESETS for layer in ("noisy", "clean", "both"))
            print(f"| {name} | {label} | {cells} |")
    if zarr_results:
        print("Zarr chunks of the same frame (one chunk per layer; digital: the DNG's numbers), zarr's codec threads "
              f"1, median of {args.repeats} interleaved rounds:")
        for preset in PRESETS:
            print(f"  {preset}:")
            for codec in ZARR_CODECS:
                cells = "  ".join(f"{layer} {zarr_results[preset, codec, layer]['bytes'] / 1e6:6.2f} MB "
                                  f"w {zarr_results[preset, codec, layer]['write_ms']:6.1f} ms "
                                  f"r {zarr_results[preset, codec, layer]['read_ms']:6.1f} ms"
                                  for layer in ("noisy", "clean", "digital"))
                print(f"    {codec:<24} {cells}")
        if args.markdown:
            print("\n| Zarr compressor | " + " | ".join(f"{p} {layer}: MB, write / read ms" for p in PRESETS
                                                     for layer in ("noisy", "clean", "digital")) + " |")
            print("|---|" + "---|" * (len(PRESETS) * 3))
            for codec in ZARR_CODECS:
                cells = " | ".join(f"{zarr_results[p, codec, layer]['bytes'] / 1e6:.2f}, "
                                   f"{zarr_results[p, codec, layer]['write_ms']:.0f} / "
                                   f"{zarr_results[p, codec, layer]['read_ms']:.0f}"
                                   for p in PRESETS for layer in ("noisy", "clean", "digital"))
                print(f"| {codec} | {cells} |")
    summary = {"width": WIDTH, "height": HEIGHT, "openexr": OpenEXR.__version__, "repeats": args.repeats,
               "default": DEFAULT_EXR_COMPRESSION,
               "results": [{"preset": p, "compression": n, "layer": layer, "lossless": offered[n][1], **r}
                           for (p, n, layer), r in results.items()],
               "zarr": [{"preset": p, "compressor": c, "layer": layer, **r}
                        for (p, c, layer), r in zarr_results.items()]}
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
