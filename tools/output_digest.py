"""SHA-256 of every file camsim writes for a fixed matrix of commands: the byte-identity check of a refactor.

Runs each case of :data:`CASES` in this process (``camsim.cli.main`` for the commands, so it measures the checkout
that ``camsim`` is imported from) into a temporary folder, hashes every file written, and prints one
``CASE/PATH SHA256`` line each. ``--save FILE`` keeps the digests as JSON; ``--compare FILE`` compares them with
a saved set and exits 1 on any difference (listing it). Typical use, around a change that must not change bytes::

    git stash; python tools/output_digest.py --save /tmp/before.json; git stash pop
    python tools/output_digest.py --compare /tmp/before.json

The cases cover, at small sizes (about 30 s in all on the shared 2-core machine), every kind of frame camsim draws:

* chart frames: every method, both photon statistics, a Bayer sensor, fixed-pattern, row and Tukey-λ noise,
  stages disabled, previews;
* a reflectance cube, an image scene (``skimage:astronaut`` cropped and resampled by ``[image]``) and a dead-leaves
  target (Bayer);
* optics: the built-in ``slanted_edge_lens`` (diffraction, OLPF) and a Bayer chart through every ``[optics]`` stage
  (diffraction, defocus, OLPF, fill factor, cos⁴ vignetting, lateral chromatic aberration);
* raw scenes of a camera DNG made here (:func:`_prepare`, by the tests' independent writer
  ``tests/support/phone_dng.py``; Orientation 6, saturated sites): a crop at an odd offset under ``thin``, a
  ``[sequence]`` under ``add`` with shake and pan (the saturation mask moving), and a static ``thin`` sequence;
* chart sequences: shake and pan (three chips), a rolling shutter with flicker (Bayer), and given homographies
  with optics, written with ``--format zarr``;
* datasets: photograph crops (``denoise_small``), bursts with motion (as files, and as a Zarr store with sRGB
  outputs), ``[raws]`` crops of two cameras (Sony RGGB, Nikon GRBG) and bursts of ``[raws]`` crops;
* ``camsim.pairs`` in this process (each batch's arrays written with ``numpy.save``, its records as JSON):
  ``PairSource`` batches in the ``dn`` (virtual cameras), ``raw`` (Bayer and three chips) and ``srgb`` domains,
  bursts with shake and pan, and with a rolling shutter and flicker; ``WrittenPairs`` reading written datasets
  (frames in the three domains, cropped, and bursts);
* ``camsim develop`` of rendered DNGs (JPEG, 16 bits, a noise report), of a raw scene's frame and of a camera DNG
  by its own tags; ``camsim denoise-eval`` with built-in denoisers on a three-chip and a Bayer dataset; an
  experiment and an EMVA run.

Not covered: ``--device cuda`` (frames and pairs drawn on a GPU; this machine has none) and a ``--scheduler``
(Dask) dataset.

Every byte is hashed as written except two normalisations: the run's scratch folder is written ``<TMP>`` wherever a
file names it (records and reports name their paths), and in ``camsim denoise-eval``'s outputs the seconds each
denoiser took (:data:`TIMED`, the only figures that change from run to run) are written ``<SECONDS>``. No file is
left out.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import hashlib
import io
import json
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "scenes" / "macbeth_26.toml")
IMAGES = str(ROOT / "scenes" / "images")
SMALL = ["--illuminant", "D65", "A", "--intensity", "1", "0.01", "--size", "96x64", "-q"]
DATASET = ["-q", "--workers", "1"]


def _pairs(out: Path, tmp: Path, batches=(0, 1), sensor=None, **settings) -> None:
    """``PairSource`` batches of the built-in ``macbeth_26`` (its ``[sensor]`` overridden by ``sensor``) on the
    photographs of scenes/images, each batch's arrays ``numpy.save``d and its records written as JSON."""
    from camsim.pairs import PairSource
    from camsim.scene.scene_file import load_scene

    scene = load_scene("macbeth_26")
    if sensor:
        scene = scene.with_sensor(**sensor)
    base = dict(crop=(32, 24), batch_size=3, intensity=(1e-2, 0.3), cameras=("sony-a7s2",), seed=1)
    source = PairSource.from_scene(scene, IMAGES, **(base | settings))
    for b in batches:
        _save_batch(out / f"batch{b}", source.batch(b))


def _save_batch(folder: Path, batch) -> None:
    folder.mkdir(parents=True)
    for name in ("noisy", "clean", "digital", "frames_clean", "homographies", "row_homographies", "flicker_factor"):
        value = getattr(batch, name)
        if value is not None:
            np.save(folder / f"{name}.npy", np.asarray(value))
    _write_json(folder / "params.json", {"index": batch.index, "domain": batch.domain, "params": batch.params,
                                         "isp": batch.isp})


def _write_json(path: Path, value) -> None:
    def plain(v):
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, np.generic):
            return v.item()
        if isinstance(v, Path):
            return str(v)
        raise TypeError(f"{type(v).__name__} in a record")

    path.write_text(json.dumps(value, indent=1, sort_keys=True, default=plain))


def _written_pairs(out: Path, tmp: Path) -> None:
    """``WrittenPairs`` of two datasets written here (their files hashed too): a Bayer one with sRGB outputs read in
    the three domains with a crop, and a burst one read as bursts."""
    from camsim.cli import main
    from camsim.pairs import WrittenPairs

    for spec, name in (("written.toml", "frames"), ("bursts.toml", "bursts")):
        status = main(["dataset", str(tmp / spec), *DATASET, "--out", str(out / name)])
        if status != 0:
            raise SystemExit(f"WrittenPairs' dataset {spec} failed with status {status}")
    reads = [("frames", domain, (16, 12), False) for domain in ("dn", "raw", "srgb")]
    reads += [("frames", "dn", None, False), ("bursts", "dn", (32, 24), True), ("bursts", "raw", None, True)]
    for name, domain, crop, burst in reads:
        pairs = WrittenPairs(out / name, domain, crop=crop, seed=3, burst=burst)
        for i in range(len(pairs)):
            noisy, clean, meta = pairs[i]
            folder = out / "read" / f"{name}-{domain}-{'crop' if crop else 'whole'}" / str(i)
            folder.mkdir(parents=True)
            np.save(folder / "noisy.npy", noisy)
            np.save(folder / "clean.npy", clean)
            _write_json(folder / "meta.json", meta)


#: name -> what the case runs: one camsim command (a list of arguments), several in turn (a tuple of lists), or a
#: function ``f(out, tmp)`` run in this process that writes into ``out``. In the arguments ``{out}`` is the case's
#: output folder and ``{tmp}`` the run's scratch folder (the inputs :func:`_prepare` writes).
CASES = {
    "render-poisson": ["render", SCENE, *SMALL, "--out", "{out}"],
    "render-spectral-paper": ["render", SCENE, *SMALL, "--method", "spectral", "--statistics", "paper",
                              "--intensity", "1e-13", "--out", "{out}"],
    "render-gaussian": ["render", SCENE, *SMALL, "--method", "gaussian", "--preset", "ideal", "--out", "{out}"],
    "render-auto": ["render", SCENE, *SMALL, "--method", "auto", "--preset", "ideal", "--intensity", "1e-4",
                    "--out", "{out}"],
    "render-auto-paper": ["render", SCENE, *SMALL, "--method", "auto", "--statistics", "paper", "--out", "{out}"],
    "render-bayer-fpn": ["render", "{tmp}/fpn.toml", *SMALL, "--cfa", "GRBG", "--method", "auto", "--out", "{out}"],
    "render-fpn-poisson": ["render", "{tmp}/fpn.toml", *SMALL, "--preview", "--out", "{out}"],
    "render-bayer-spectral": ["render", SCENE, *SMALL, "--cfa", "RGGB", "--method", "spectral", "--out", "{out}"],
    "render-disable-exposure": ["render", SCENE, *SMALL, "--disable", "read_noise", "quantisation",
                                "--exposure", "0.25", "--seed", "9", "--out", "{out}"],
    "render-cube": ["render", "{tmp}/cube.toml", "-q", "--out", "{out}"],
    "render-image": ["render", "{tmp}/image.toml", "-q", "--preview", "--out", "{out}"],
    "render-dead-leaves": ["render", str(ROOT / "scenes" / "dead_leaves.toml"), "--size", "96x64", "--cfa", "RGGB",
                           "-q", "--out", "{out}"],
    "render-optics-lens": ["render", "slanted_edge_lens", "--size", "96x64", "-q", "--out", "{out}"],
    "render-optics-stages": ["render", "{tmp}/optics.toml", "--size", "96x64", "-q", "--out", "{out}"],
    "render-raw": ["render", "{tmp}/raw.toml", "-q", "--out", "{out}"],
    "render-raw-sequence": ["render", "{tmp}/raw_sequence.toml", "-q", "--out", "{out}"],
    "render-raw-sequence-thin": ["render", "{tmp}/raw_static.toml", "-q", "--out", "{out}"],
    "render-sequence-shake": ["render", "{tmp}/sequence.toml", "--size", "64x48", "-q", "--out", "{out}"],
    "render-sequence-shutter": ["render", "{tmp}/shutter.toml", "--size", "64x48", "--cfa", "GBRG", "-q",
                                "--out", "{out}"],
    "render-sequence-zarr": ["render", "{tmp}/homographies.toml", "--size", "48x32", "--format", "zarr", "-q",
                             "--out", "{out}"],
    "dataset": ["dataset", str(ROOT / "scenes" / "denoise_small.toml"), *DATASET, "--out", "{out}"],
    "dataset-bursts": ["dataset", "{tmp}/bursts.toml", *DATASET, "--out", "{out}"],
    "dataset-bursts-zarr": ["dataset", "{tmp}/bursts.toml", *DATASET, "--format", "zarr", "--srgb", "png",
                            "--out", "{out}"],
    "dataset-raws": ["dataset", "{tmp}/raws.toml", *DATASET, "--out", "{out}"],
    "dataset-raws-bursts": ["dataset", "{tmp}/raws_bursts.toml", *DATASET, "--out", "{out}"],
    "pairs-dn-virtual": lambda out, tmp: _pairs(out, tmp, batches=(0, 5), cameras=("sony-a7s2", "nikon-d850"),
                                                cameras_mode="virtual"),
    "pairs-raw": lambda out, tmp: _pairs(out, tmp, domain="raw", cameras=("sony-a7s2", "nikon-d850"),
                                         iso=(200.0, 6400.0)),
    "pairs-raw-three-chip": lambda out, tmp: _pairs(out, tmp, batches=(3,), domain="raw", cameras=("sony-imx174",)),
    "pairs-srgb": lambda out, tmp: _pairs(out, tmp, batches=(2,), domain="srgb"),
    "pairs-burst": lambda out, tmp: _pairs(out, tmp, batches=(0,), batch_size=2, burst_frames=3, shake_px=0.5,
                                           shake_deg=0.1, pan_px_per_s=(2.0, -1.0)),
    "pairs-burst-shutter": lambda out, tmp: _pairs(out, tmp, batches=(1,), batch_size=2, burst_frames=2,
                                                   shake_px=0.6, pan_px_per_s=(300.0, -100.0), frame_interval_s=0.01,
                                                   rolling_shutter_row_s=1e-4, flicker_hz=120.0, flicker_depth=0.5,
                                                   flicker_phase_deg=-40.0, intensity=(1.0, 3.0),
                                                   cameras=("sony-imx174",), sensor={"exposure_s": 0.004}),
    "pairs-written": _written_pairs,
    "develop": (["render", SCENE, "--preset", "sony-a7s2", "--illuminant", "D65", "--intensity", "1", "0.05",
                 "--size", "64x48", "-q", "--out", "{out}/frames"],
                ["develop", "{out}/frames", "--gain", "white", "--jpeg-quality", "90", "-q", "--out", "{out}/isp"],
                ["develop", "{out}/frames/macbeth_26_D65_F0.05.dng", "--demosaic", "menon2007", "--tone", "filmic",
                 "--bits", "16", "--noise-report", "-q", "--out", "{out}/isp-menon"],
                ["develop", "{tmp}/tags.dng", "--matrix", "dng", "--demosaic", "bilinear", "--gain", "4", "-q",
                 "--out", "{out}/isp-dng-tags"],
                ["render", "{tmp}/raw.toml", "--intensity", "0.05", "-q", "--out", "{out}/raw-frames"],
                ["develop", "{out}/raw-frames", "--matrix", "dng", "--gain", "auto", "-q", "--out", "{out}/isp-raw"]),
    "denoise-eval": (["dataset", "{tmp}/eval.toml", *DATASET, "--out", "{out}/dataset"],
                     ["denoise-eval", "{out}/dataset", "--denoiser", "identity", "--denoiser", "tv", "-q",
                      "--out", "{out}/eval"],
                     ["dataset", "{tmp}/eval_bayer.toml", *DATASET, "--out", "{out}/dataset-bayer"],
                     ["denoise-eval", "{out}/dataset-bayer", "--denoiser", "identity", "--denoiser", "wavelet", "-q",
                      "--out", "{out}/eval-bayer"]),
    "experiment-scenario2": ["experiment", "scenario2", "--size", "50x40", "-q", "--out", "{out}"],
    "emva": ["emva", "--size", "32", "-q", "--out", "{out}"],
}

#: Per case, the files whose bytes hold the run's own timings (``camsim denoise-eval``'s seconds per denoiser and
#: frame: the ``seconds`` column of its CSVs, ``seconds`` and ``seconds_per_frame`` in its JSON, the ``s/frame``
#: column and the run-time line of its report), which :func:`_without_seconds` writes ``<SECONDS>`` before hashing.
TIMED = {"denoise-eval": tuple(f"{folder}/{name}" for folder in ("eval", "eval-bayer")
                               for name in ("frames.csv", "bands.csv", "summary.json", "report.md"))}
SECONDS = "<SECONDS>"

# The scene and spec files of :func:`_prepare` (file name -> text).
INPUTS = {
    "fpn.toml": "name = \"fpn\"\n[chart]\n[light]\nilluminants = [\"D65\"]\n[sensor]\npreset = \"emva-12bit\"\n"
                "row_noise_e = 1.5\nread_noise_model = \"tukey-lambda\"\nsensor_seed = 3\n[render]\nseed = 4\n",
    "cube.toml": "name = \"cube\"\n[cube]\npath = \"cube.npy\"\n[light]\nilluminants = [\"D65\"]\n"
                 "intensity_factors = [1.0, 0.05]\n",
    "image.toml": "name = \"astronaut_small\"\n[image]\npath = \"skimage:astronaut\"\nkind = \"reflectance\"\n"
                  "colourspace = \"sRGB\"\nrecovery = \"Mallett 2019\"\ncrop = [96, 32, 320, 240]\nsize = [64, 48]\n"
                  "[light]\nilluminants = [\"D65\", \"A\"]\nintensity_factors = [1.0, 0.05]\n[sensor]\n"
                  "preset = \"emva-12bit\"\n[render]\nseed = 2\n",
    "optics.toml": "name = \"optics\"\n[chart]\n[light]\nilluminants = [\"D65\"]\nintensity_factors = [0.5]\n"
                   "[sensor]\npreset = \"emva-12bit\"\ncfa = \"RGGB\"\n[optics]\nf_number = 8.0\n"
                   "focal_length_mm = 12.0\npixel_pitch_um = 4.0\ndiffraction = true\ndefocus_waves = 0.5\n"
                   "olpf = true\nolpf_shift_px = 1.0\nfill_factor = 0.7\nvignetting = \"cos4\"\n"
                   "lateral_ca = [1.002, 1.0, 0.998]\n[render]\nseed = 5\n",
    "raw.toml": "name = \"raw\"\n[raw]\npath = \"src.dng\"\ncrop = [3, 2, 40, 28]\nphoton_law = \"thin\"\n"
                "[light]\nintensity_factors = [0.1, 0.01]\n[sensor]\niso = 3200\n[render]\nseed = 7\n",
    "raw_sequence.toml": "name = \"rawseq\"\n[raw]\npath = \"src.dng\"\ncrop = [0, 0, 48, 32]\n[light]\n"
                         "intensity_factors = [0.008]\n[sensor]\niso = 1600\n[sequence]\nframes = 3\n"
                         "frame_interval_s = 0.5\nshake_px = 0.7\nshake_deg = 0.1\npan_px_per_s = [2.0, -1.0]\n"
                         "[render]\nseed = 8\n",
    "raw_static.toml": "name = \"rawstatic\"\n[raw]\npath = \"src.dng\"\ncrop = [8, 6, 32, 24]\n"
                       "photon_law = \"thin\"\n[light]\nintensity_factors = [0.008]\n[sequence]\nframes = 2\n"
                       "frame_interval_s = 0.5\n[render]\nseed = 10\n",
    "homographies.toml": "name = \"homog\"\n[chart]\n[light]\nilluminants = [\"FL2\"]\nintensity_factors = [0.1]\n"
                         "[sensor]\npreset = \"emva-12bit\"\ncfa = \"BGGR\"\nexposure_s = 0.02\n[optics]\n"
                         "f_number = 4.0\npixel_pitch_um = 4.0\ndiffraction = true\n[sequence]\nframes = 3\n"
                         "frame_interval_s = 0.05\nblur_subsamples = 4\nhomographies = [[[1, 0, 0], [0, 1, 0], "
                         "[0, 0, 1]], [[1, 0, 1.5], [0, 1, -0.75], [0, 0, 1]], [[0.999, 0.02, 2.25], "
                         "[-0.02, 0.999, -1.5], [0, 0, 1]]]\n[render]\nseed = 11\n",
    "sequence.toml": "name = \"seq\"\n[chart]\n[light]\nilluminants = [\"D65\"]\nintensity_factors = [0.5, 0.05]\n"
                     "[sensor]\npreset = \"emva-12bit\"\nexposure_s = 0.01\n[sequence]\nframes = 3\n"
                     "frame_interval_s = 0.033\nshake_px = 0.8\nshake_deg = 0.05\npan_px_per_s = [120.0, 0.0]\n"
                     "[render]\nseed = 6\n",
    "shutter.toml": "name = \"shutter\"\n[chart]\n[light]\nilluminants = [\"D65\"]\nintensity_factors = [0.5]\n"
                    "[sensor]\npreset = \"emva-12bit\"\nexposure_s = 0.01\n[sequence]\nframes = 3\n"
                    "frame_interval_s = 0.033\nshake_px = 0.3\npan_px_per_s = [60.0, 20.0]\n"
                    "rolling_shutter_row_s = 1e-4\nflicker_hz = 100.0\nflicker_depth = 0.3\n"
                    "flicker_phase_deg = 30.0\n[render]\nseed = 9\n",
    "burst_scene.toml": "name = \"leaves\"\n[target]\nkind = \"dead-leaves\"\nseed = 1\n[light]\n"
                        "illuminants = [\"D65\"]\nintensity_factors = [0.05]\n[camera.scale]\nkind = \"anchor\"\n"
                        "reference_electrons = 8000\n[sensor]\npreset = \"emva-12bit\"\nexposure_s = 0.01\n"
                        "prnu_percent = 2\ndsnu_e = 3\n",
    "bursts.toml": "name = \"bursts\"\nscene = \"burst_scene.toml\"\nseed = 5\n[frame]\nwidth = 48\nheight = 32\n"
                   "[fixed]\nburst_frames = 3\nframe_interval_s = 0.02\npan_x_px_per_s = 40.0\n[random]\ncount = 2\n"
                   "shake_px = { uniform = [0.2, 1.0] }\nshake_deg = { uniform = [0.0, 0.2] }\n",
    "raws.toml": "name = \"raws\"\nseed = 0\n[raws]\nfolder = \"raws\"\ncrop = [32, 24]\nflips = true\n[grid]\n"
                 "ratio = [50.0, 200.0]\n[random]\ncount = 2\n"
                 "preset = { choice = [\"sony-a7s2\", \"nikon-d850\"] }\n",
    "raws_bursts.toml": "name = \"rawbursts\"\nseed = 4\n[raws]\nfolder = \"raws\"\ncrop = [32, 24]\nflips = true\n"
                        "[fixed]\nburst_frames = 3\nframe_interval_s = 0.01\nshake_px = 1.5\n"
                        "pan_x_px_per_s = 120.0\npan_y_px_per_s = -70.0\nratio = 100.0\n[random]\ncount = 2\n",
    "written.toml": "name = \"written\"\nscene = \"macbeth_26\"\nseed = 9\nsrgb = \"png16\"\n[frame]\nwidth = 48\n"
                    "height = 32\n[fixed]\npreset = \"emva-12bit\"\ncfa = \"RGGB\"\n[grid]\n"
                    "illuminants = [\"D65\", \"A\"]\n[random]\ncount = 1\n"
                    "intensity_factor = { log_uniform = [0.01, 0.5] }\n",
    "eval_bayer.toml": "name = \"evalbayer\"\nscene = \"macbeth_26\"\nseed = 3\n[frame]\nwidth = 64\nheight = 48\n"
                       "[fixed]\npreset = \"sony-a7s2\"\nilluminant = \"D65\"\n[grid]\n"
                       "intensity_factor = [1.0, 0.03]\n",
    "eval.toml": "name = \"eval\"\nscene = \"macbeth_26\"\nseed = 2\n[frame]\nwidth = 72\nheight = 48\n[fixed]\n"
                 "preset = \"emva-12bit\"\nilluminant = \"D65\"\n[grid]\nintensity_factor = [1.0, 0.1, 0.01]\n",
}


def _camera_dng(path: Path, pattern: str, make: str, model: str, *, seed: int, orientation: int = 1,
                saturated: bool = False, thumbnail: bool = True, black=(512, 512, 512, 512)) -> None:
    """A small camera DNG (64 × 48, a smooth blob with a little noise of its own over ``black``, per site of the
    2 × 2 cell; ISO 100, 0.5 s) by the tests' independent writer (not camsim's), optionally with a block of sites at
    the white level; the raw in a SubIFD behind a thumbnail, or in IFD0."""
    sys.path.insert(0, str(ROOT))
    try:
        from tests.support.phone_dng import write_phone_dng
    finally:
        sys.path.remove(str(ROOT))
    y, x = np.mgrid[0:48, 0:64]
    blob = 400 + 8000 * np.exp(-((x - 30.0) ** 2 + (y - 22.0) ** 2) / (2 * 9.0 ** 2)) + 30 * x
    mosaic = np.rint(np.mean(black) + blob + np.random.default_rng(seed).normal(0, 15, blob.shape))
    if saturated:
        mosaic[4:8, 40:46] = 16383
    write_phone_dng(path, np.clip(mosaic, 0, 16383).astype(np.uint16), pattern=pattern, black_per_site=black,
                    white=16383, iso=100, exposure_s=0.5, make=make, model=model,
                    color_matrix1=[[0.6, -0.1, -0.05], [-0.4, 1.3, 0.1], [-0.08, 0.2, 0.6]],
                    color_matrix2=[[0.7, -0.2, -0.05], [-0.4, 1.2, 0.1], [-0.1, 0.25, 0.55]],
                    as_shot_neutral=[0.5, 1.0, 0.7], orientation=orientation, thumbnail=thumbnail)


def _prepare(tmp: Path) -> None:
    """The inputs some cases need: the scene and spec files of :data:`INPUTS`, a small reflectance cube, and camera
    DNGs: ``src.dng`` (a Sony, RGGB, turned by Orientation 6, with saturated sites), ``raws/a.dng``, ``raws/b.dng``
    (a Sony RGGB one, its raw in IFD0, and a Nikon GRBG one, for the ``[raws]`` datasets) and ``tags.dng`` (BGGR,
    fractional black levels, its raw in IFD0: developed by its own tags; camsim's DNG reader takes BlackLevel as
    RATIONAL, as camsim writes it)."""
    for name, text in INPUTS.items():
        (tmp / name).write_text(text, encoding="utf-8")
    cube = np.random.default_rng(0).uniform(0.05, 0.9, size=(30, 40, 101))
    np.save(tmp / "cube.npy", cube)
    _camera_dng(tmp / "src.dng", "RGGB", "SONY", "ILCE-7SM2", seed=1, orientation=6, saturated=True)
    (tmp / "raws").mkdir()
    _camera_dng(tmp / "raws" / "a.dng", "RGGB", "SONY", "ILCE-7SM2", seed=2, thumbnail=False)
    _camera_dng(tmp / "raws" / "b.dng", "GRBG", "NIKON CORPORATION", "NIKON D850", seed=3)
    _camera_dng(tmp / "tags.dng", "BGGR", "SONY", "ILCE-7SM2", seed=4, thumbnail=False,
                black=(512.5, 511.25, 511.75, 512.0))


def _without_seconds(relative: str, data: bytes) -> bytes:
    """``data`` (a file of :data:`TIMED`) with every timing written :data:`SECONDS`; the rest as it was (a CSV and
    a JSON file read and written again, a report line by line)."""
    text = data.decode("utf-8")
    if relative.endswith(".csv"):
        rows = list(csv.reader(io.StringIO(text)))
        column = rows[0].index("seconds")
        for row in rows[1:]:
            if len(row) > column and row[column]:
                row[column] = SECONDS
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerows(rows)
        return buffer.getvalue().encode("utf-8")
    if relative.endswith(".json"):
        def strip(value):
            if isinstance(value, dict):
                return {k: (SECONDS if k == "seconds" else {n: SECONDS for n in v} if k == "seconds_per_frame"
                            else strip(v)) for k, v in value.items()}
            return [strip(v) for v in value] if isinstance(value, list) else value

        return json.dumps(strip(json.loads(text)), indent=1).encode("utf-8")
    lines, column = text.split("\n"), None
    for i, line in enumerate(lines):
        cells = line.split("|")
        if " s/frame " in cells:
            column = cells.index(" s/frame ")
        elif column is not None and line.startswith("|") and re.fullmatch(r" [0-9.e+-]+ ", cells[column]):
            cells[column] = f" {SECONDS} "
            lines[i] = "|".join(cells)
        elif column is not None and not line.startswith("|"):
            column = None
        if line.startswith("* **Run time**"):
            lines[i] = re.sub(r" \S+ s/frame", f" {SECONDS} s/frame", line)
    return "\n".join(lines).encode("utf-8")


def _normalised(name: str, relative: str, data: bytes, tmp: Path) -> bytes:
    """The bytes hashed: the scratch folder's path written ``<TMP>`` (records and reports name their paths), and the
    timings of :data:`TIMED` files written :data:`SECONDS`."""
    data = data.replace(str(tmp).encode(), b"<TMP>")
    return _without_seconds(relative, data) if relative in TIMED.get(name, ()) else data


def _run(name: str, tmp: Path, folder: Path) -> None:
    from camsim.cli import main

    case = CASES[name]
    if callable(case):
        folder.mkdir(parents=True)
        with contextlib.redirect_stdout(io.StringIO()):
            case(folder, tmp)
        return
    for command in case if isinstance(case, tuple) else (case,):
        argv = [a.replace("{out}", str(folder)).replace("{tmp}", str(tmp)) for a in command]
        with contextlib.redirect_stdout(io.StringIO()):
            status = main(argv)
        if status != 0:
            raise SystemExit(f"case {name} failed with status {status}: camsim {' '.join(argv)}")


def digests(cases=None) -> dict:
    """``{case/relative path: sha256}`` of every file each case writes."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        _prepare(tmp)
        for name in cases or CASES:
            folder = tmp / "out" / name
            started = time.perf_counter()
            _run(name, tmp, folder)
            for path in sorted(p for p in folder.rglob("*") if p.is_file()):
                relative = path.relative_to(folder).as_posix()
                data = _normalised(name, relative, path.read_bytes(), tmp)
                out[f"{name}/{relative}"] = hashlib.sha256(data).hexdigest()
            print(f"{name}: {sum(k.startswith(name + '/') for k in out)} files, "
                  f"{time.perf_counter() - started:.1f} s", file=sys.stderr)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--save", type=Path, help="write the digests to this JSON file")
    parser.add_argument("--compare", type=Path, help="compare with digests saved by --save; exit 1 if any differ")
    parser.add_argument("--case", action="append", choices=sorted(CASES), help="run only these cases")
    args = parser.parse_args(argv)
    now = digests(args.case)
    if args.save:
        args.save.write_text(json.dumps(now, indent=1, sort_keys=True))
    if not args.compare:
        for key, value in now.items():
            print(key, value)
        return 0
    before = json.loads(args.compare.read_text())
    if args.case:
        before = {k: v for k, v in before.items() if k.split("/")[0] in args.case}
    changed = sorted(k for k in set(before) & set(now) if before[k] != now[k])
    missing, added = sorted(set(before) - set(now)), sorted(set(now) - set(before))
    for label, keys in (("changed", changed), ("missing", missing), ("new", added)):
        for key in keys:
            print(f"{label}: {key}")
    same = len(set(before) & set(now)) - len(changed)
    print(f"{same} files identical, {len(changed)} changed, {len(missing)} missing, {len(added)} new")
    return 1 if changed or missing or added else 0


if __name__ == "__main__":
    sys.exit(main())
