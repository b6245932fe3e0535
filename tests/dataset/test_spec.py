"""camsim dataset's planning: the frame list, ids and seeds are those of the first implementation (hard-coded
here), frames that differ only in own-value parameters share a resolution that matches a full one, ids widen past
99 999 frames and sort, the seeds' batch computation is NumPy's SeedSequence, and the dry run streams."""

import dataclasses
import hashlib
import json
import pickle
import random
import tracemalloc
from pathlib import Path

import pytest

from camsim.cli.commands.dataset import print_plan
from camsim.core.errors import CamsimError
from camsim.core.seeding import dataset_frame_seed, dataset_frame_seeds
from camsim.dataset import spec_parts
from camsim.dataset.spec import load_spec, plan_spec
from camsim.dataset.spec_parts import OWN_VALUE_PARAMS

# a scene file of its own (not scenes/macbeth_26.toml, which may change), named relative to the spec, so that the
# records and ids below do not depend on the repository or its path
SCENE_TEXT = """
name = "chart"
[spectral]
start_nm = 380
end_nm = 780
step_nm = 4
[chart]
reflectances = "ColorChecker N Ohta"
columns = 6
rows = 4
[light]
illuminants = ["D65", "A", "FL2"]
luminance_cd_m2 = 100
intensity_factors = [1.0, 0.1]
[camera]
name = "Nikon 5100 (NPL)"
[sensor]
preset = "paper-table1"
"""

# the scene's 3 illuminants x 2 intensity factors x 2 layouts x 2 exposures x 2 draws x 2 repeats = 96 frames;
# own-value parameters (exposure, read noise, bits, the photon-noise switch, Tukey's lambda) and others (the CFA,
# the dark current, the analog gain, the read-noise law) on every axis
MIXED = """
name = "mixed"
scene = "scene.toml"
seed = 11
repeats = 2

[frame]
width = 64
height = 48

[fixed]
preset = "emva-12bit"
row_noise_e = 0.5

[grid]
cfa = ["none", "RGGB"]
exposure_s = [0.5, 1]

[random]
count = 2
read_noise_e = { uniform = [2, 6] }
dark_current_e_per_s = { uniform = [1, 30] }
bits = { integers = [10, 14] }
analog_gain_dn_per_v = { choice = [5000.0, 10000] }
photon_noise = { choice = [true, false] }
read_noise_model = { choice = ["gaussian", "tukey-lambda"] }
tukey_lambda = { uniform = [-0.2, 0.1] }
"""

#: From the implementation before planning was made lean (commit b8baa21): the same frames, ids and seeds.
MIXED_FRAMES = [(0, "00000-40da2f7f20", 2287903995121479), (1, "00001-3956d2710f", 3186045419184324),
                (2, "00002-2ceeb1de67", 7975740651865468), (95, "00095-eba9979409", 1766289721755665)]
MIXED_RECORDS_SHA256 = "4e88864e266d0963b08c9360a1a110a2af7357ab6733160aebf7fd06c39904f6"
MIXED_TASKS_SHA256 = "ce4ae28b14f6048000c7b6ee5d3f8c1eed4d872d367104bcb1ea8d973333f232"


def write(folder: Path, text: str, name: str = "spec.toml") -> Path:
    (folder / "scene.toml").write_text(SCENE_TEXT, encoding="utf-8")
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def random_spec(count: int, seed: int = 0) -> str:
    return f"""
scene = "scene.toml"
seed = {seed}
[fixed]
illuminant = "D65"
[random]
count = {count}
intensity_factor = {{ log_uniform = [1e-3, 1.0] }}
"""


def test_frames_ids_and_seeds_are_unchanged(tmp_path):
    spec = load_spec(write(tmp_path, MIXED))
    assert len(spec) == 96
    assert [(spec.frames[i].index, spec.frames[i].id, spec.frames[i].seed) for i, *_ in MIXED_FRAMES] == MIXED_FRAMES
    records = json.dumps([f.record for f in spec.frames])  # every value, and the keys' order (the manifest's)
    assert hashlib.sha256(records.encode()).hexdigest() == MIXED_RECORDS_SHA256
    tasks = json.dumps([[f.scene_changes, f.sensor_overrides, f.illuminant, f.intensity_factor, f.width, f.height,
                         Path(f.scene_path).name] for f in spec.frames], sort_keys=True)
    assert hashlib.sha256(tasks.encode()).hexdigest() == MIXED_TASKS_SHA256


def test_frames_pickle_and_compare(tmp_path):
    spec = load_spec(write(tmp_path, MIXED))
    frame = spec.frames[5]
    again = pickle.loads(pickle.dumps(frame))
    assert again == frame and again.record == frame.record and again.sensor_overrides == frame.sensor_overrides
    assert frame.record is not frame.record  # a new dict each time: a caller may change it
    assert all(frame.get(key) == value for key, value in frame.record.items())
    with pytest.raises(KeyError):
        frame.get("files")
    assert frame.group is spec.frames[4].group  # differs from frame 4 only in its repeat


#: Two valid values of every own-value parameter (a new one must be added here, and so checked).
OWN_VALUES = {
    "intensity_factor": (1.0, 0.25), "full_well_e": (9000.0, 5000.0), "read_noise_e": (4.0, 1.5),
    "exposure_s": (1.0, 0.125), "photon_noise": (True, False), "dark_current": (True, False),
    "saturation": (True, False), "read_noise": (True, False), "dsnu_e": (0.0, 2.5), "row_noise_e": (0.0, 0.75),
    "tukey_lambda": (-0.1, 0.3), "sensor_seed": (0, 7), "bits": (8, 12),
}


@pytest.mark.parametrize("name", sorted(OWN_VALUES))
def test_own_value_parameters_match_a_full_resolution(tmp_path, name):
    """A frame whose own value is set per frame (shared resolution) has the record of one whose value is fixed
    (resolved in full): the same parameters, the same hash."""
    assert set(OWN_VALUES) == OWN_VALUE_PARAMS
    a, b = OWN_VALUES[name]
    base = 'scene = "scene.toml"\n[frame]\nwidth = 64\nheight = 48\n[fixed]\nilluminant = "A"\n' + (
        "" if name == "intensity_factor" else "intensity_factor = 0.5\n")
    grid = load_spec(write(tmp_path, base + f"[grid]\n{name} = {json.dumps([a, b])}\n", "grid.toml"))
    for frame, value in zip(grid.frames, (a, b)):
        alone = load_spec(write(tmp_path, base.replace("[fixed]\n", f"[fixed]\n{name} = {json.dumps(value)}\n"),
                                f"fixed_{frame.index}.toml")).frames[0]

        def strip(record):
            return {k: v for k, v in record.items() if k not in ("id", "index", "seed")}

        assert strip(frame.record) == strip(alone.record) and frame.record[name] == value
        assert frame.id.split("-")[1] == alone.id.split("-")[1]
        assert frame.sensor_overrides == alone.sensor_overrides and frame.intensity_factor == alone.intensity_factor


def test_an_own_value_out_of_range_names_its_frame(tmp_path):
    text = random_spec(4).replace("[random]", "[grid]\nread_noise_e = [1.0, -1.0]\n[random]")
    with pytest.raises(CamsimError, match=r"frame 4 \(.*read_noise_e=-1.0.*\): sensor parameter: read_noise_e must be"):
        load_spec(write(tmp_path, text))


def test_planning_is_lean(tmp_path):
    load_spec(write(tmp_path, random_spec(3), "warm.toml"))  # the caches of the checks (illuminants, camera)
    path = write(tmp_path, random_spec(3000))
    tracemalloc.start()
    try:
        spec = load_spec(path)
        current, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(spec) == 3000 and current / len(spec) < 1000  # bytes per frame held (about 300)


def test_ids_widen_to_the_frame_count(tmp_path, monkeypatch):
    """At least ID_DIGITS digits; more where the last index needs them: every id of a spec has one width and the
    ids sort in frame order. (ID_DIGITS is made 2 here, for a 101-frame spec; the next test has 100 001 frames.)"""
    short = load_spec(write(tmp_path, random_spec(100), "short.toml"))
    assert {len(f.id) for f in short.frames} == {16} and short.frames[-1].id.startswith("00099-")
    monkeypatch.setattr(spec_parts, "ID_DIGITS", 2)
    for count, digits in ((100, 2), (101, 3)):
        spec = load_spec(write(tmp_path, random_spec(count), f"s{count}.toml"))
        ids = [f.id for f in spec.frames]
        assert {len(i.split("-")[0]) for i in ids} == {digits} and sorted(ids) == ids
        assert [i.split("-")[1] for i in ids[:100]] == [f.id.split("-")[1] for f in short.frames]  # same hashes
        assert all(f.seed == dataset_frame_seed(0, f.id) for f in spec.frames)


@pytest.mark.slow
def test_ids_sort_past_99999_frames(tmp_path):
    spec = plan_spec(write(tmp_path, random_spec(100_001)))
    ids = [f.id for f in spec.frames()]
    assert ids[0].startswith("000000-") and ids[-1].startswith("100000-") and {len(i) for i in ids} == {17}
    assert sorted(ids) == ids
    small = load_spec(write(tmp_path, random_spec(3), "small.toml"))
    assert [i[1:] for i in ids[:3]] == [f.id for f in small.frames]  # a zero more, the same hash


def test_batched_seeds_are_seed_sequence_seeds():
    rng = random.Random(3)
    ids = [f"{rng.randrange(10**6):06d}-{rng.getrandbits(40):010x}" for _ in range(200)] + ["", "é-ü"]
    for seed in (0, 1, 7, 2**32 - 1, 2**32, 2**64 + 5, 2**127 + 3, 2**128, 2**200 + 12345):
        assert dataset_frame_seeds(seed, ids) == [dataset_frame_seed(seed, i) for i in ids]
    assert dataset_frame_seeds(0, []) == []


def test_dry_run_streams(tmp_path):
    """The header first, then the frames in chunks as they are made: the first chunk is out before the last
    frame is made."""
    plan = plan_spec(write(tmp_path, random_spec(3000)))
    made = []

    def counting():
        for frame in plan.make_frames():
            made.append(frame.index)
            yield frame

    writes = []
    print_plan(dataclasses.replace(plan, make_frames=counting), lambda text: writes.append((len(made), text)),
               chunk=500)
    assert writes[0] == (0, "dataset spec: 3000 frames of 256x192; varied: intensity_factor (random)\n")
    assert len(writes) == 1 + 6 + 1 and writes[1][0] < 3000  # the header, 6 chunks, an empty rest
    lines = "".join(text for _, text in writes[1:]).splitlines()
    frames = load_spec(plan.path).frames
    assert [json.loads(line)["id"] for line in lines] == [f.id for f in frames]
    assert json.loads(lines[7]) == {"id": frames[7].id, "scene": "chart", "repeat": 0,
                                    "intensity_factor": frames[7].intensity_factor, "seed": frames[7].seed}
