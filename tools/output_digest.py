"""SHA-256 of every file camsim writes for a fixed matrix of commands: the byte-identity check of a refactor.

Runs each command of :data:`CASES` through ``camsim.cli.main`` (in this process, so it measures the checkout that
``camsim`` is imported from) into a temporary folder, hashes every file written, and prints one
``CASE/PATH SHA256`` line each. ``--save FILE`` keeps the digests as JSON; ``--compare FILE`` compares them with
a saved set and exits 1 on any difference (listing it). Typical use, around a change that must not change bytes::

    git stash; python tools/output_digest.py --save /tmp/before.json; git stash pop
    python tools/output_digest.py --compare /tmp/before.json

The cases cover every method, both photon statistics, a Bayer sensor, fixed-pattern, row and Tukey-λ noise,
a cube scene, previews, a dataset, an experiment and an EMVA run, at small sizes (about a minute in all).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "scenes" / "macbeth_26.toml")
SMALL = ["--illuminant", "D65", "A", "--intensity", "1", "0.01", "--size", "96x64", "-q"]

#: name -> camsim arguments (``{out}`` is the case's output folder, ``{tmp}`` the run's scratch folder).
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
    "dataset": ["dataset", str(ROOT / "scenes" / "denoise_small.toml"), "-q", "--workers", "1", "--out", "{out}"],
    "experiment-scenario2": ["experiment", "scenario2", "--size", "50x40", "-q", "--out", "{out}"],
    "emva": ["emva", "--size", "32", "-q", "--out", "{out}"],
}


def _prepare(tmp: Path) -> None:
    """The scene files some cases need: fixed-pattern noise on the chart, and a small reflectance cube."""
    (tmp / "fpn.toml").write_text(
        "name = \"fpn\"\n[chart]\n[light]\nilluminants = [\"D65\"]\n[sensor]\npreset = \"emva-12bit\"\n"
        "row_noise_e = 1.5\nread_noise_model = \"tukey-lambda\"\nsensor_seed = 3\n"
        "[render]\nseed = 4\n")
    cube = np.random.default_rng(0).uniform(0.05, 0.9, size=(30, 40, 101))
    np.save(tmp / "cube.npy", cube)
    (tmp / "cube.toml").write_text("name = \"cube\"\n[cube]\npath = \"cube.npy\"\n[light]\n"
                                   "illuminants = [\"D65\"]\nintensity_factors = [1.0, 0.05]\n")


def digests(cases=None) -> dict:
    """``{case/relative path: sha256}`` of every file each case writes."""
    from camsim.cli import main

    out = {}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        _prepare(tmp)
        for name in cases or CASES:
            folder = tmp / "out" / name
            argv = [a.replace("{out}", str(folder)).replace("{tmp}", str(tmp)) for a in CASES[name]]
            with contextlib.redirect_stdout(io.StringIO()):
                status = main(argv)
            if status != 0:
                raise SystemExit(f"case {name} failed with status {status}: camsim {' '.join(argv)}")
            for path in sorted(p for p in folder.rglob("*") if p.is_file()):
                data = path.read_bytes().replace(str(tmp).encode(), b"<TMP>")  # reports may name their paths
                out[f"{name}/{path.relative_to(folder)}"] = hashlib.sha256(data).hexdigest()
            print(f"{name}: {sum(k.startswith(name + '/') for k in out)} files", file=sys.stderr)
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
