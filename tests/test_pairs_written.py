"""Reading the pairs of a written dataset (camsim.pairs.WrittenPairs, and its torch Dataset where torch is installed):
each domain's pair equals what is read from the files directly (the EXR's layers, the mosaic's sites, the
normalisation and packing done here, the PNGs decoded by OpenImageIO); a Zarr store gives the same pairs as the
files; a crop is the same region in every domain and on every read."""

import json

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.dataset import read_manifest, run_dataset
from camsim.pairs import WrittenPairs
from tests.support.helpers import ROOT, write_text_file

SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()


def spec_text(cfa: str) -> str:
    return f"""
name = "written"
scene = "{SCENE}"
seed = 9
srgb = "png16"

[frame]
width = 48
height = 32

[fixed]
preset = "emva-12bit"
cfa = "{cfa}"

[grid]
illuminants = ["D65", "A"]

[random]
count = 2
intensity_factor = {{ log_uniform = [0.01, 0.5] }}
"""


@pytest.fixture(scope="module", params=["RGGB", "GBRG", "none"])
def datasets(request, tmp_path_factory):
    """The same spec written as files and as a Zarr store."""
    folder = tmp_path_factory.mktemp(f"written-{request.param}")
    spec = write_text_file(folder, "written.toml", spec_text(request.param))
    run_dataset(spec, folder / "files", workers=1, progress=False, echo=None)
    run_dataset(spec, folder / "store", workers=1, progress=False, echo=None, output="zarr")
    return request.param, folder / "files", folder / "store"


def direct(out, record):
    """A frame's EXR layers, sidecar and developed PNG codes, read here (OpenImageIO for the PNGs)."""
    import OpenImageIO as oiio

    from camsim.io.exr import read_exr

    noisy, clean, _ = read_exr(out / record["files"]["exr"]["name"])
    meta = json.loads((out / record["files"]["json"]["name"]).read_text())
    png = {}
    for layer in ("srgb_noisy", "srgb_clean"):
        image = oiio.ImageInput.open(str(out / record["files"][layer]["name"]))
        png[layer] = np.asarray(image.read_image(0, 0, 0, 3, "uint16")).transpose(2, 0, 1)
        image.close()
    return noisy, clean, meta, png



def mosaic_of(clean, pattern):
    out = np.empty(clean.shape[1:], clean.dtype)
    for i, colour in enumerate(pattern):
        dy, dx = divmod(i, 2)
        out[dy::2, dx::2] = clean["RGB".index(colour), dy::2, dx::2]
    return out


def packed(mosaic, pattern):
    """R, G1 (the green on R's row), G2, B planes, found from the pattern's letters here."""
    r = pattern.index("R")
    ry, rx = divmod(r, 2)
    return np.stack([mosaic[ry::2, rx::2], mosaic[ry::2, 1 - rx::2], mosaic[1 - ry::2, rx::2],
                     mosaic[1 - ry::2, 1 - rx::2]])


def test_each_domain_is_what_the_files_hold(datasets):
    cfa, files, _ = datasets
    records = read_manifest(files)
    pairs = {domain: WrittenPairs(files, domain) for domain in ("dn", "raw", "srgb")}
    assert all(len(p) == len(records) == 4 for p in pairs.values())
    for i, record in enumerate(records):
        noisy, clean, meta, png = direct(files, record)
        dark = np.asarray(meta["dark_level_dn"], dtype=np.float64)
        # the white of the values before the ADC: 2^nb − 1 less the offset of the quantised black level (the ISP's rule)
        white = float(meta["white_level_dn"]) - np.mean(np.subtract(meta["black_level_dn"], meta["dark_level_dn"]))
        n, c, info = pairs["dn"][i]
        assert info["id"] == record["id"] and info["domain"] == "dn" and info["crop"] is None
        if cfa == "none":
            assert n.shape == c.shape == (3, 32, 48)
            assert np.array_equal(n, noisy) and np.array_equal(c, clean)
            expected = [(x - dark[:, None, None]) / (white - dark[:, None, None]) for x in (noisy, clean)]
        else:
            assert n.shape == c.shape == (1, 32, 48)
            assert np.array_equal(n, noisy) and np.array_equal(c[0], mosaic_of(clean, cfa))
            site_dark = packed(mosaic_of(np.broadcast_to(dark[:, None, None], clean.shape), cfa), cfa)
            expected = [(packed(m, cfa) - site_dark) / (white - site_dark)
                        for m in (noisy[0].astype(np.float64), mosaic_of(clean, cfa).astype(np.float64))]
        rn, rc, rinfo = pairs["raw"][i]
        assert rn.shape == expected[0].shape and rn.dtype == np.float32
        np.testing.assert_allclose(rn, expected[0], rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(rc, expected[1], rtol=1e-6, atol=1e-7)
        assert rinfo["packed"] == (None if cfa == "none" else ["R", "G1", "G2", "B"])
        sn, sc, sinfo = pairs["srgb"][i]
        assert np.array_equal(sn, png["srgb_noisy"].astype(np.float32) / np.float32(65535))
        assert np.array_equal(sc, png["srgb_clean"].astype(np.float32) / np.float32(65535))
        assert sinfo["isp"] == record["srgb"]["isp"]


def test_a_zarr_store_gives_the_same_pairs_as_the_files(datasets):
    _, files, store = datasets
    for domain in ("dn", "raw", "srgb"):
        a, b = WrittenPairs(files, domain), WrittenPairs(store / "dataset.zarr", domain)
        assert len(a) == len(b) == 4
        for i in range(4):
            (an, ac, am), (bn, bc, bm) = a[i], b[i]
            assert an.tobytes() == bn.tobytes() and ac.tobytes() == bc.tobytes()
            assert am["id"] == bm["id"] and am["record"]["seed"] == bm["record"]["seed"]


def test_a_crop_is_one_region_in_every_domain(datasets):
    cfa, files, _ = datasets
    whole = {d: WrittenPairs(files, d) for d in ("dn", "raw", "srgb")}
    cut = {d: WrittenPairs(files, d, crop=(16, 10), seed=3) for d in ("dn", "raw", "srgb")}
    for i in range(4):
        regions = {d: cut[d][i][2]["crop"] for d in cut}
        assert len(set(regions.values())) == 1
        x, y, w, h = regions["dn"]
        assert (w, h) == (16, 10) and (cfa == "none" or (x % 2 == 0 and y % 2 == 0))
        assert cut["dn"][i][2]["crop"] == WrittenPairs(files, "dn", crop=(16, 10), seed=3)[i][2]["crop"]
        for d in ("dn", "srgb"):
            assert np.array_equal(cut[d][i][0], whole[d][i][0][:, y:y + h, x:x + w])
            assert np.array_equal(cut[d][i][1], whole[d][i][1][:, y:y + h, x:x + w])
        if cfa != "none":
            assert cut["raw"][i][0].shape == (4, 5, 8)
            np.testing.assert_array_equal(cut["raw"][i][0], whole["raw"][i][0][:, y // 2:(y + h) // 2,
                                                                                 x // 2:(x + w) // 2])
    offsets = {WrittenPairs(files, "dn", crop=(16, 10), seed=s)[0][2]["crop"] for s in range(8)}
    assert len(offsets) > 1  # the seed moves the crop


def test_bad_reads_are_refused(tmp_path, datasets):
    _, files, _ = datasets
    with pytest.raises(CamsimError, match="holds no camsim dataset"):
        WrittenPairs(tmp_path)
    with pytest.raises(CamsimError, match="unknown pair domain"):
        WrittenPairs(files, "xyz")
    with pytest.raises(CamsimError, match="larger than the frames"):
        WrittenPairs(files, crop=(100, 10))[0]
    with pytest.raises(IndexError):
        WrittenPairs(files)[4]
    plain = write_text_file(tmp_path, "plain.toml", spec_text("none").replace('srgb = "png16"', ""))
    run_dataset(plain, tmp_path / "plain", workers=1, progress=False, echo=None)
    with pytest.raises(CamsimError, match="no sRGB outputs"):
        WrittenPairs(tmp_path / "plain", "srgb")


def test_the_torch_dataset_over_a_written_dataset(datasets):
    torch = pytest.importorskip("torch")
    from camsim.pairs_torch import collate_pairs, written_pairs

    _, files, store = datasets
    data = written_pairs(store, "raw", crop=(16, 10), seed=1)
    reference = WrittenPairs(files, "raw", crop=(16, 10), seed=1)
    assert len(data) == 4 and isinstance(data, torch.utils.data.Dataset)
    item = data[2]
    assert torch.equal(item["noisy"], torch.from_numpy(reference[2][0])) and item["meta"]["id"] == reference[2][2]["id"]
    loader = torch.utils.data.DataLoader(data, batch_size=2, collate_fn=collate_pairs)
    batches = list(loader)
    assert len(batches) == 2 and batches[0]["noisy"].shape[0] == 2 and batches[0]["noisy"].dtype == torch.float32
    assert torch.equal(batches[1]["clean"][0], torch.from_numpy(reference[2][1]))
    assert [m["id"] for b in batches for m in b["meta"]] == [reference[i][2]["id"] for i in range(4)]
