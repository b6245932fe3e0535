"""Optional benchmark: camsim against the ESA detector simulator Pyxel (PyPI ``pyxel-sim``) on workload W1.

W1: ``scenes/macbeth_26.toml`` under D65 at F = 1, 4000 × 3000 pixels × 3 channels (R, G, B at every pixel), the
``paper-table1`` sensor with every stage on. Pyxel is installed once into its own venv ``outputs/.pyxel-venv`` and
runs in a child process of it (memory measured apart). Having no three-chip colour detector, it runs three exposures
of a W × H CMOS detector, one per channel, in one process, on camsim's mean signal electrons per pixel (photon flux ×
QE, float32 ``.npy``) taken as photons with QE = 1, T = 1 s. Models: ``load_image`` → ``shot_noise`` (Poisson) →
``simple_conversion`` (QE 1, binomial off: the identity) → ``simple_dark_current`` (Poisson, the channel's e⁻/s) →
``simple_collection`` → ``simple_full_well`` → ``simple_measurement`` (V/e⁻) → ``output_node_noise`` (read
noise in V) → ``simple_amplifier`` (camsim's G, as V/V) → ``simple_adc`` (range [0, 2^nb − 1] V: 1 V = 1 DN,
truncating like camsim). Pyxel draws photon and dark Poisson separately, camsim their sum once (the same distribution).

Measured: ``pyxel.run_mode`` for the three channels (median of the repeats; import and configuration excluded; its
``load_image`` time, reading the input, reported and also subtracted) and the Pyxel child's peak RSS after one pass;
camsim ``render_frame`` (``poisson``, ``auto``; 2 workers; median; no file writing) and the peak RSS of a fresh
child that sets up and renders W1 once. Sanity: the white patch's mean DN per channel, Pyxel against camsim.
Targets: camsim ≥ 8× faster, peak memory under a quarter of Pyxel's.

Run:  python tools/bench_pyxel.py [--size WxH] [--repeats N]   (camsim's venv; default 4000x3000, 3 repeats)
Exit status 3: Pyxel could not be installed. The last stdout line is one JSON object. The tests never need this.
"""

from __future__ import annotations

import argparse
import json
import statistics
import string
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_w1 import ROOT, SEED, fmt, peak_rss_mb, render, setup  # noqa: E402  (stdlib only)

VENV = ROOT / "outputs" / ".pyxel-venv"
PYXEL_PIN = "pyxel-sim==3.0.2"
WHITE = "white"
TARGET_SPEEDUP, TARGET_MEMORY_RATIO = 8.0, 0.25

PYXEL_YAML = string.Template("""\
exposure:
  readout:
    times: [$exposure]
    non_destructive: false
  result_type: image
  pipeline_seed: null
cmos_detector:
  geometry: {row: $rows, col: $cols}
  environment: {temperature: 300.0}
  characteristics:
    quantum_efficiency: 1.0
    charge_to_volt: {value: $gve}
    pre_amplification: $gain
    full_well_capacity: $full_well
    adc_bit_resolution: $bits
    adc_voltage_range: [0.0, $max_dn]
pipeline:  # every model enabled (Pyxel's default)
  photon_collection:
    - {name: load_image, func: pyxel.models.photon_collection.load_image,
       arguments: {image_file: $image, convert_to_photons: false}}
    - {name: shot_noise, func: pyxel.models.photon_collection.shot_noise, arguments: {type: poisson}}
  charge_generation:
    - {name: photoelectrons, func: pyxel.models.charge_generation.simple_conversion,
       arguments: {quantum_efficiency: 1.0, binomial_sampling: false}}
    - {name: dark_current, func: pyxel.models.charge_generation.simple_dark_current, arguments: {dark_rate: $dark_rate}}
  charge_collection:
    - {name: simple_collection, func: pyxel.models.charge_collection.simple_collection}
    - {name: full_well, func: pyxel.models.charge_collection.simple_full_well, arguments: {fwc: $full_well}}
  charge_measurement:
    - {name: simple_measurement, func: pyxel.models.charge_measurement.simple_measurement}
    - {name: output_node_noise, func: pyxel.models.charge_measurement.output_node_noise,
       arguments: {std_deviation: $read_noise_v}}
  readout_electronics:
    - {name: simple_amplifier, func: pyxel.models.readout_electronics.simple_amplifier}
    - {name: simple_adc, func: pyxel.models.readout_electronics.simple_adc, arguments: {data_type: uint8}}
""")


def progress(message: str) -> None:
    print(f"[bench_pyxel] {message}", file=sys.stderr, flush=True)


def ensure_pyxel() -> tuple[Path, str]:
    """The Pyxel venv's python and Pyxel's version; creates the venv on first use. Exits 3 if that fails."""
    python, want = VENV / "bin" / "python", PYXEL_PIN.split("==")[1]
    check = [str(python), "-c", "import importlib.metadata as m; print(m.version('pyxel-sim'))"]

    def found():
        return python.exists() and subprocess.run(check, capture_output=True, text=True).stdout.strip()

    if found() == want:
        return python, want
    steps = [] if python.exists() else [["python3", "-m", "venv", str(VENV)]]
    for cmd in steps + [[str(python), "-m", "pip", "install", "--upgrade", "pip"],
                        [str(python), "-m", "pip", "install", PYXEL_PIN]]:
        progress(f"installing Pyxel into {VENV} (may take minutes): {' '.join(cmd[-3:])}")
        try:
            reason = f"exit {subprocess.run(cmd, stdout=sys.stderr, stderr=subprocess.STDOUT).returncode}"
        except OSError as exc:
            reason = str(exc)
        if reason != "exit 0":
            print(f"Pyxel unavailable: '{' '.join(cmd)}' failed ({reason}; delete {VENV} to start over)", flush=True)
            sys.exit(3)
    if found() != want:
        print(f"Pyxel unavailable: {PYXEL_PIN} installed into {VENV} but cannot be imported", flush=True)
        sys.exit(3)
    return python, want


# --- camsim children (camsim's venv) ----------------------------------------------------------------------------


def white_rect(w: dict) -> list:
    """The white patch's interior (x0, y0, x1, y1), 3 pixels in from its edges."""
    r = w["radiance"]
    x, y, width, height = r.patch_rects[[WHITE in n.lower() for n in r.patch_names].index(True)]
    return [x + 3, y + 3, x + width - 3, y + height - 3]


def region_means(image, rect) -> dict:
    """Per channel (image: sequence of 3 2-D arrays) the mean DN of the white patch and of the whole frame."""
    x0, y0, x1, y1 = rect
    return {"white": [float(im[y0:y1, x0:x1].mean()) for im in image], "frame": [float(im.mean()) for im in image]}


def child_prepare(args) -> dict:
    """W1's Pyxel input: per channel the mean signal electrons per pixel, as float32 .npy; and the sensor."""
    import numpy as np

    from camsim.sensor.params import STAGES

    w = setup(args.width, args.height)
    ex, labels, s = w["expected"], w["radiance"].labels, w["scene"].sensor
    assert all(getattr(s, k) for k in STAGES), "W1 has every sensor stage on"
    files = [str(Path(args.tmp) / f"signal_e_{name}.npy") for name in "RGB"]
    for c, f in enumerate(files):
        np.save(f, ex.signal_e[:, c][labels].astype(np.float32))
    return {"files": files, "rect": white_rect(w), "dark_e_per_s": list(s.dark_current_e_per_s),
            "exposure_s": s.exposure_s, "gve": s.conversion_gain_v_per_e, "gain": s.analog_gain_dn_per_v,
            "full_well": s.full_well_e, "read_noise_e": s.read_noise_e, "bits": s.bits, "max_dn": s.max_dn}


def child_camsim_rss(args) -> dict:
    w = setup(args.width, args.height)
    after_setup = peak_rss_mb()
    render(w, args.method)
    return {"rss_setup_mb": after_setup, "rss_peak_mb": peak_rss_mb()}


def child_camsim_timing(args) -> dict:
    w = setup(args.width, args.height)
    render(w, "auto")  # auto tabulates its KS distances once per process
    runs = [("poisson", "poisson", 2), ("auto", "auto", 2), ("poisson_1worker", "poisson", 1)]
    times = {name: [] for name, *_ in runs}
    for r in range(args.repeats):
        for name, method, workers in runs:
            progress(f"camsim repeat {r + 1}/{args.repeats}: {name}")
            t0 = time.perf_counter()
            render(w, method, workers)
            times[name].append(time.perf_counter() - t0)
    dn = render(w, "poisson").digital_dn
    return {"times": times, "dn": region_means(dn, white_rect(w))}


# --- Pyxel child (Pyxel's venv: stdlib, numpy and pyxel only) ---------------------------------------------------


def child_pyxel(args) -> dict:
    t0 = time.perf_counter()
    import dask.utils  # noqa: F401  (the first run_mode imports these lazily: count them as import, not run)
    import numpy as np
    import pyxel
    import xarray  # noqa: F401

    p = json.loads(Path(args.params).read_text())
    yaml = Path(args.tmp) / "w1_pyxel.yaml"
    yaml.write_text(PYXEL_YAML.substitute(
        exposure=p["exposure_s"], rows=args.height, cols=args.width, gve=p["gve"], gain=p["gain"],
        full_well=p["full_well"], bits=p["bits"], max_dn=float(p["max_dn"]), image=p["files"][0],
        dark_rate=p["dark_e_per_s"][0], read_noise_v=p["read_noise_e"] * p["gve"]))
    config, model_s = pyxel.load(yaml), {}

    def timed_model(name, func):
        def run(detector, **kwargs):
            t = time.perf_counter()
            func(detector, **kwargs)
            model_s[name] = model_s.get(name, 0.0) + time.perf_counter() - t
        return run

    pipe = config.pipeline
    for group in pipe.model_group_names:
        for model in getattr(pipe, group) or []:
            model._func = timed_model(model.name, model.func)  # model.func resolves (imports) the model now
    out = {"version": pyxel.__version__, "import_s": time.perf_counter() - t0, "rss_import_mb": peak_rss_mb(),
           "times": [], "models": []}
    np.random.seed(SEED)
    for r in range(args.repeats):
        model_s.clear()
        total, images = 0.0, []
        for c in range(3):
            progress(f"Pyxel repeat {r + 1}/{args.repeats}: channel {'RGB'[c]}")
            pipe.photon_collection.load_image.arguments["image_file"] = p["files"][c]
            pipe.charge_generation.dark_current.arguments["dark_rate"] = p["dark_e_per_s"][c]
            t = time.perf_counter()
            result = pyxel.run_mode(config)
            total += time.perf_counter() - t
            images.append(np.asarray(result["bucket"]["image"].values[-1]))
            del result
        out["times"].append(total)
        out["models"].append(dict(model_s))
        out.setdefault("rss_pass1_mb", peak_rss_mb())
    return {**out, "rss_all_mb": peak_rss_mb(), "dtype": str(images[0].dtype), "dn": region_means(images, p["rect"])}


# --- parent -----------------------------------------------------------------------------------------------------


def run_child(python, name: str, args, *extra: str) -> dict:
    cmd = [str(python), str(Path(__file__).resolve()), "--child", name, "--size", f"{args.width}x{args.height}",
           "--repeats", str(args.repeats), "--tmp", args.tmp, *extra]
    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="4000x3000", help="frame WxH (default 4000x3000 = W1)")
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats, camsim and Pyxel (default 3)")
    for hidden in ("--child", "--method", "--tmp", "--params"):
        parser.add_argument(hidden, help=argparse.SUPPRESS)
    args = parser.parse_args()
    args.width, args.height = (int(v) for v in args.size.lower().split("x"))
    args.repeats = max(1, args.repeats)
    if args.child:
        children = {"prepare": child_prepare, "camsim-rss": child_camsim_rss, "camsim-timing": child_camsim_timing,
                    "pyxel": child_pyxel}
        print(json.dumps(children[args.child](args)))
        return
    full = (args.width, args.height) == (4000, 3000)
    print(f"camsim vs Pyxel, W1: macbeth_26 chart, D65, F = 1, {args.width} x {args.height} x 3 channels, "
          "paper-table1 (shot, dark, full well, read noise, 8-bit ADC)" + ("" if full else "   [NOT the W1 size]"))
    pyxel_python, version = ensure_pyxel()
    with tempfile.TemporaryDirectory(prefix="bench_pyxel_") as tmp:
        args.tmp = tmp
        progress("camsim: W1 input for Pyxel (mean signal electrons per pixel and channel)")
        (Path(tmp) / "params.json").write_text(json.dumps(run_child(sys.executable, "prepare", args)))
        progress(f"Pyxel {version}: three exposures per repeat (one per channel)")
        px = run_child(pyxel_python, "pyxel", args, "--params", str(Path(tmp) / "params.json"))
    progress("camsim: peak RSS, fresh children (poisson, auto)")
    rss = {m: run_child(sys.executable, "camsim-rss", args, "--method", m)["rss_peak_mb"] for m in ("poisson", "auto")}
    progress("camsim: timings")
    cs = run_child(sys.executable, "camsim-timing", args)

    model_s = {k: statistics.median(m[k] for m in px["models"]) for k in px["models"][0]}  # median per model
    pyxel_s, load_s = statistics.median(px["times"]), model_s.get("load_image", 0.0)
    models_s = statistics.median(sum(m.values()) for m in px["models"])
    med = {k: statistics.median(v) for k, v in cs["times"].items()}
    rss_pyxel, rss_camsim = px["rss_pass1_mb"], rss["poisson"]
    speed_p, speed_a, mem_ratio = pyxel_s / med["poisson"], pyxel_s / med["auto"], rss_camsim / rss_pyxel
    wp, wc = px["dn"]["white"], cs["dn"]["white"]
    rel = max(abs(a - b) / b for a, b in zip(wp, wc))
    dn3 = lambda xs: ", ".join(f"{v:7.2f}" for v in xs)  # noqa: E731

    print(f"\nPyxel {version} (own venv; numpy on 1 core, legacy np.random): 3 exposures of a {args.width} x "
          f"{args.height} CMOS detector, one per channel")
    print(f"   run_mode x 3 channels   {fmt(px['times'])}   (first repeat {px['times'][0]:.2f} s; import + "
          f"config {px['import_s']:.1f} s, excluded)")
    print(f"   of which load_image (reading the .npy input) {load_s:.3f} s, so {pyxel_s - load_s:.3f} s without it; "
          f"models {models_s:.3f} s, Pyxel's own overhead (buckets, DataTree) {pyxel_s - models_s:.3f} s")
    print("   per model, s (3 channels, median of the repeats): "
          + ", ".join(f"{k} {v:.2f}" for k, v in sorted(model_s.items(), key=lambda kv: -kv[1])))
    print(f"   memory: after import + config {px['rss_import_mb']:.0f} MB, peak after one pass over the 3 channels "
          f"{rss_pyxel:.0f} MB (after all repeats {px['rss_all_mb']:.0f} MB); output dtype {px['dtype']}")
    print("camsim render_frame (no file writing)")
    print(f"   poisson, 2 workers      {fmt(cs['times']['poisson'])}")
    print(f"   auto, 2 workers         {fmt(cs['times']['auto'])}")
    print(f"   poisson, 1 worker       {fmt(cs['times']['poisson_1worker'])}   (for reference: Pyxel uses 1 core)")
    print(f"   memory (fresh process, imports + setup + render): peak {rss_camsim:.0f} MB poisson, "
          f"{rss['auto']:.0f} MB auto")
    print("Sanity: mean DN per channel (R, G, B)")
    print(f"   white patch  Pyxel {dn3(wp)}   camsim {dn3(wc)}   largest difference {100 * rel:.2f} %"
          + ("" if rel < 0.03 else "   <-- NOT THE SAME WORK?"))
    print(f"   whole frame  Pyxel {dn3(px['dn']['frame'])}   camsim {dn3(cs['dn']['frame'])}")
    print(f"\nTargets: at least {TARGET_SPEEDUP:g}x faster: poisson {speed_p:.1f}x -> "
          f"{'MET' if speed_p >= TARGET_SPEEDUP else 'NOT MET'}, auto {speed_a:.1f}x -> "
          f"{'MET' if speed_a >= TARGET_SPEEDUP else 'NOT MET'} (without Pyxel's input loading: "
          f"{(pyxel_s - load_s) / med['poisson']:.1f}x, {(pyxel_s - load_s) / med['auto']:.1f}x);  peak memory under "
          f"1/4 of Pyxel's: {rss_camsim:.0f} / {rss_pyxel:.0f} MB = {mem_ratio:.3f} -> "
          f"{'MET' if mem_ratio < TARGET_MEMORY_RATIO else 'NOT MET'}" + ("" if full else "   [reduced frame]"))
    print(json.dumps({
        "pyxel_version": version, "pyxel_s": pyxel_s, "pyxel_s_without_load": pyxel_s - load_s,
        "pyxel_load_image_s": load_s, "pyxel_import_s": px["import_s"], "pyxel_model_s": model_s,
        "pyxel_times_s": px["times"], "peak_rss_mb_pyxel": rss_pyxel, "peak_rss_mb_pyxel_all_repeats": px["rss_all_mb"],
        "camsim_poisson_s": med["poisson"], "camsim_auto_s": med["auto"],
        "camsim_poisson_1worker_s": med["poisson_1worker"], "peak_rss_mb_camsim": rss_camsim,
        "peak_rss_mb_camsim_auto": rss["auto"], "speedup_poisson": speed_p, "speedup_auto": speed_a,
        "speedup_poisson_without_load": (pyxel_s - load_s) / med["poisson"], "memory_ratio": mem_ratio,
        "white_patch_dn_pyxel": wp, "white_patch_dn_camsim": wc, "white_patch_max_rel_diff": rel,
        "frame_dn_pyxel": px["dn"]["frame"], "frame_dn_camsim": cs["dn"]["frame"], "width": args.width,
        "height": args.height, "repeats": args.repeats, "camsim_workers": 2, "pyxel_exposures": "3 (one per channel)",
    }))


if __name__ == "__main__":
    main()
