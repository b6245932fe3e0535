"""Fault × sub-command → outcome, with real processes: what each ``camsim`` sub-command does when its output is
under a file, the disk is full (a real tmpfs with 64 kB left; needs root on Linux, else reported as not run), another
run holds the folder, or it is sent SIGINT, SIGTERM or SIGKILL while it works.

For each case: the exit status, seconds from start to exit, the first line of stderr, whether a traceback was
printed, what was left in the output folder (temporary ``.partial`` files, pixel files no sidecar claims) and
whether any child process outlived the run.

    python tools/fault_matrix.py                 # every sub-command × fault, a Markdown table
    python tools/fault_matrix.py --only render dataset --faults SIGTERM full-disk
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FAULTS = ("out-under-file", "full-disk", "busy-folder", "SIGINT", "SIGTERM", "SIGKILL")
COMMANDS = ("render", "dataset", "analyze", "denoise-eval", "emva", "experiment")
SPEC = """
name = "faults"
scene = "{scene}"
seed = 3
[frame]
width = 512
height = 384
[fixed]
preset = "emva-12bit"
illuminant = "D65"
[random]
count = 40
intensity_factor = {{ log_uniform = [0.001, 1.0] }}
"""


def env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}


def camsim(*argv) -> list[str]:
    return [sys.executable, "-m", "camsim", *argv]


def argv_for(command: str, work: Path, frames: Path) -> list[str]:
    """A run of ``command`` that lasts a few seconds (long enough to be interrupted)."""
    if command == "render":
        return camsim("render", "macbeth_26", "--size", "1500x1000", "--illuminant", "D65", "A", "--intensity",
                      "1", "0.5", "0.25", "-q")
    if command == "dataset":
        spec = work / "spec.toml"
        spec.write_text(SPEC.format(scene=(ROOT / "scenes" / "macbeth_26.toml").as_posix()), encoding="utf-8")
        return camsim("dataset", str(spec), "--workers", "2", "-q")
    if command == "analyze":
        return camsim("analyze", str(frames), "--source", "exr", "-q")
    if command == "denoise-eval":
        return camsim("denoise-eval", str(frames), "-d", "identity", "-d", "wavelet", "-q")
    if command == "emva":
        return camsim("emva", "--size", "512", "-q")
    if command == "experiment":
        return camsim("experiment", "scenario1", "-q")
    raise ValueError(command)


def descendants_alive(pids: set[int]) -> list[int]:
    return [pid for pid in pids if Path(f"/proc/{pid}").exists() and _state(pid) not in ("Z", None)]


def _state(pid: int) -> str | None:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return None


def children_of(root_pid: int) -> set[int]:
    """Every live process descending from ``root_pid`` (by /proc parent links)."""
    parents = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            with contextlib.suppress(OSError, IndexError):
                parents[int(entry.name)] = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
    found, frontier = set(), {root_pid}
    while frontier:
        frontier = {pid for pid, ppid in parents.items() if ppid in frontier} - found
        found |= frontier
    return found


def leftovers(out: Path) -> tuple[int, int]:
    """(temporary files, pixel files that no sidecar claims) under ``out``."""
    if not out.is_dir():
        return 0, 0
    partial = sum(1 for _ in out.rglob(".*.partial"))
    claimed = set()
    for sidecar in out.rglob("*.json"):
        with contextlib.suppress(OSError, ValueError, AttributeError, TypeError):
            files = json.loads(sidecar.read_text()).get("files") or {}
            claimed |= {(sidecar.parent / name).resolve() for name in files.values() if isinstance(name, str)}
    pixel = [p for p in out.rglob("*") if p.suffix in (".dng", ".exr") and not p.name.startswith(".")]
    return partial, sum(1 for p in pixel if p.resolve() not in claimed)


@contextlib.contextmanager
def tiny_disk(mount: Path, size_bytes: int = 4 << 20, free_bytes: int = 64 << 10):
    """A real file system (tmpfs) with ``free_bytes`` left: the probe file fits, the outputs do not."""
    mount.mkdir(parents=True, exist_ok=True)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_bytes}", "tmpfs", str(mount)], check=True,
                   capture_output=True)
    try:
        (mount / "filler").write_bytes(b"\0" * (shutil.disk_usage(mount).free - free_bytes))
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], check=False, capture_output=True)


def can_mount() -> bool:
    return sys.platform.startswith("linux") and os.geteuid() == 0 and shutil.which("mount") is not None


def run_case(command: str, fault: str, work: Path, frames: Path) -> dict:
    out = work / "out"
    argv = argv_for(command, work, frames)
    holder = None
    if fault == "out-under-file":
        (work / "a-file").write_text("x")
        out = work / "a-file" / "out"
    elif fault == "busy-folder":
        out.mkdir()
        holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from camsim.io.output_folder import "
                                   "output_folder\nwith output_folder(sys.argv[1]):\n print('held', flush=True)\n"
                                   " time.sleep(60)", str(out)], env=env(), stdout=subprocess.PIPE, text=True)
        holder.stdout.readline()
    disk = contextlib.nullcontext()
    if fault == "full-disk":
        if not can_mount():
            return {"outcome": "not run (needs root to mount a small tmpfs)"}
        disk = tiny_disk(work / "disk")
        out = work / "disk" / "out"
    with disk:
        start = time.monotonic()
        proc = subprocess.Popen([*argv, "--out", str(out)], env=env(), stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)
        family: set[int] = set()
        if fault.startswith("SIG"):
            # wait until the run is at work (its folder exists), then a little longer, noting its children
            while not out.is_dir() and proc.poll() is None:
                time.sleep(0.01)
            deadline = time.monotonic() + 1.5
            while time.monotonic() < deadline and proc.poll() is None:
                family |= children_of(proc.pid)
                time.sleep(0.05)
            if proc.poll() is None:
                family |= children_of(proc.pid)
                proc.send_signal(getattr(signal, fault))
        _, err = proc.communicate(timeout=600)
        seconds = time.monotonic() - start
        time.sleep(3.0 if family else 0.0)  # the "within a few seconds"
        orphans = descendants_alive(family)
        partial, unclaimed = leftovers(out)
        if holder is not None:
            holder.kill()
            holder.wait()
        lines = [line for line in err.splitlines() if line.strip()]
        first = next((line for line in lines if line.startswith("camsim:")), lines[0] if lines else "")
        return {"rc": proc.returncode, "seconds": round(seconds, 1), "message": first[:110],
                "traceback": any("Traceback" in line for line in lines), "partial_files": partial,
                "unclaimed_pixel_files": unclaimed, "orphans": len(orphans)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", choices=COMMANDS, default=list(COMMANDS))
    parser.add_argument("--faults", nargs="+", choices=FAULTS, default=list(FAULTS))
    parser.add_argument("--json", action="store_true", help="also print the results as one JSON line")
    args = parser.parse_args(argv)
    results = []
    with tempfile.TemporaryDirectory(prefix="camsim-faults-") as tmp:
        frames = Path(tmp) / "frames"
        subprocess.run(camsim("render", "macbeth_26", "--size", "2000x1500", "--illuminant", "D65", "--intensity",
                              "1", "0.5", "0.1", "0.01", "-q", "--out", str(frames)), env=env(), check=True,
                       stdout=subprocess.DEVNULL)
        for command in args.only:
            for fault in args.faults:
                work = Path(tempfile.mkdtemp(dir=tmp))
                result = {"command": command, "fault": fault, **run_case(command, fault, work, frames)}
                results.append(result)
                print(json.dumps(result, ensure_ascii=False), file=sys.stderr, flush=True)
    print("| sub-command | fault | exit | s | message (first line) | traceback | .partial | unclaimed | orphans |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in results:
        if "rc" not in r:
            print(f"| {r['command']} | {r['fault']} | {r['outcome']} | | | | | | |")
            continue
        message = r["message"].replace("|", "\\|")
        print(f"| {r['command']} | {r['fault']} | {r['rc']} | {r['seconds']} | {message} | "
              f"{'yes' if r['traceback'] else 'no'} | {r['partial_files']} | {r['unclaimed_pixel_files']} | "
              f"{r['orphans']} |")
    if args.json:
        print(json.dumps(results, ensure_ascii=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
