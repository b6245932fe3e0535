"""Speed of re-noising a 24 MP raw (issue 27): ``render_raw_frame`` against the bare numpy draws of its per-pixel law.

The source: 6000 × 4000 electrons (float32, RGGB sites), a smooth ramp of 0 to 8000 e⁻ with a few electrons of
read noise (some negative), made dark by the ratio (default ×100: f = 0.01, so 0 to 80 e⁻ a pixel). The target
sensor: 14 bits, pedestal 512, k = 0.8 DN/e⁻, Gaussian read noise 3 e⁻, dark current per channel, full well
30 000 e⁻; no fixed-pattern maps, no row noise (``--busy`` turns on DSNU of both kinds, PRNU, row noise and the
Tukey λ read noise, which the bare draws do not have: for information).

The floor ("bare"): what a user writes with numpy for the same per-pixel law, on the same threads by the same
row blocks, one ``numpy.random.Generator`` per block (``SeedSequence.spawn``): mean = f · max(s, 0) + D̄_c (the
site's channel's dark mean), ``Generator.poisson`` of it, plus ``standard_normal`` (float32) · σ_read, times k,
plus the pedestal, rounded and clipped to 14 bits; "bare thin" the same with ``thin``'s draws,
Binomial(round(max(s, 0)), f) + Poisson(D̄_c) (numpy's binomial sampler is about twice as slow as its Poisson, and
the law needs a second draw for the dark charge). ``render_raw_frame`` also keeps the float32 DN before the ADC and
the clean layer, clips at the full well, and (``thin``) draws a binomial instead of the Poisson.

Prints the best of ``--repeat`` runs (interleaved) of each, in seconds, and the ratio to the floor. Target
(issue 27): ``add`` ≤ 1.5× the floor on two threads (``thin`` is shown against both floors).

    PYTHONPATH=. python tools/bench_raw.py [--threads 2] [--repeat 3] [--ratio 100] [--busy]
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from camsim.render.frame import BLOCK_PIXELS
from camsim.render.raw_frame import render_raw_frame
from camsim.sensor.cfa import cfa_sites
from camsim.sensor.params import SensorParams

WIDTH, HEIGHT = 6000, 4000


def make_source(seed: int = 0) -> np.ndarray:
    """(H, W) float32 electrons: a ramp of 0 to 8000 e⁻ across the frame, plus 3 e⁻ of Gaussian read noise."""
    rng = np.random.default_rng(seed)
    ramp = np.linspace(0.0, 1.0, WIDTH, dtype=np.float32) ** 2 * np.float32(8000.0)
    source = np.empty((HEIGHT, WIDTH), dtype=np.float32)
    source[...] = ramp
    source += rng.standard_normal(source.shape, dtype=np.float32) * np.float32(3.0)
    return source


def make_sensor(busy: bool) -> SensorParams:
    values = dict(cfa="RGGB", bits=14, pedestal_dn=512, analog_gain_dn_per_v=4000.0, conversion_gain_v_per_e=0.0002,
                  read_noise_e=3.0, full_well_e=30000.0, exposure_s=0.01)
    if busy:
        values.update(dsnu_e=1.0, dsnu_dark_current_percent=20.0, prnu_percent=0.5, row_noise_e=0.5,
                      read_noise_model="tukey-lambda")
    return SensorParams(**values)


def bare(source: np.ndarray, sensor: SensorParams, fraction: float, threads: int, seed: int,
         law: str = "add") -> np.ndarray:
    """The per-pixel law with plain numpy draws, on ``threads`` threads by row blocks: the floor (``thin``:
    Binomial(round(max(s, 0)), f) + Poisson(D̄_c) in place of the one Poisson draw)."""
    height, width = source.shape
    rows = max(2, BLOCK_PIXELS // width // 2 * 2)
    starts = list(range(0, height, rows))
    generators = [np.random.Generator(np.random.PCG64(s)) for s in np.random.SeedSequence(seed).spawn(len(starts))]
    dark = np.empty((rows, width), dtype=np.float32)
    for dy, dx, c in cfa_sites(sensor.cfa):
        dark[dy::2, dx::2] = sensor.dark_mean_e[c]
    k, sigma, pedestal, top = sensor.dn_per_electron, sensor.read_noise_e, sensor.pedestal_dn, sensor.max_dn
    out = np.empty((height, width), dtype=np.uint16)

    def block(index: int) -> None:
        r0 = starts[index]
        r1 = min(height, r0 + rows)
        rng = generators[index]
        if law == "add":
            mean = np.maximum(source[r0:r1], np.float32(0.0))
            mean *= np.float32(fraction)
            mean += dark[: r1 - r0]
            x = rng.poisson(mean).astype(np.float32)
        else:
            count = np.rint(np.maximum(source[r0:r1], np.float32(0.0))).astype(np.int64)
            x = rng.binomial(count, fraction)
            x += rng.poisson(dark[: r1 - r0])
            x = x.astype(np.float32)
        x += rng.standard_normal(x.shape, dtype=np.float32) * np.float32(sigma)
        x *= np.float32(k)
        x += np.float32(pedestal)
        np.rint(x, out=x)
        np.clip(x, 0, top, out=x)
        out[r0:r1] = x

    with ThreadPoolExecutor(max_workers=threads) as pool:
        list(pool.map(block, range(len(starts))))
    return out


def best_of(function, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--ratio", type=float, default=100.0, help="exposure ratio T_src / (F T): f = 1 / ratio")
    parser.add_argument("--busy", action="store_true", help="DSNU, PRNU, row noise and Tukey λ read noise on")
    args = parser.parse_args()
    source, sensor, fraction = make_source(), make_sensor(args.busy), 1.0 / args.ratio
    runs = {"bare": lambda: bare(source, sensor, fraction, args.threads, 1),
            "add": lambda: render_raw_frame(source, sensor, fraction, law="add", rng=1, workers=args.threads),
            "bare thin": lambda: bare(source, sensor, fraction, args.threads, 1, law="thin"),
            "thin": lambda: render_raw_frame(source, sensor, fraction, law="thin", rng=1, workers=args.threads)}
    for run in runs.values():  # warm-up: the maps, the thread pool, first-touch pages
        run()
    best = {name: float("inf") for name in runs}
    for _ in range(args.repeat):  # interleaved: the machine's load falls on all alike
        for name, run in runs.items():
            best[name] = min(best[name], best_of(run, 1))
    print(f"24 MP ({WIDTH}x{HEIGHT}) raw, f = 1/{args.ratio:g}, {args.threads} threads, best of {args.repeat}"
          f"{', busy sensor' if args.busy else ''}")
    print(f"{'':10s} {'seconds':>8s} {'× bare':>7s} {'× bare thin':>12s}")
    for name in runs:
        print(f"{name:10s} {best[name]:8.3f} {best[name] / best['bare']:7.2f} "
              f"{best[name] / best['bare thin']:12.2f}")


if __name__ == "__main__":
    main()
