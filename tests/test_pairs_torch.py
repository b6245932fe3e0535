"""The torch wrapper of the pairs (camsim.pairs_torch), where torch is installed (skipped otherwise): the dataset's
tensors are the batches' arrays, without a copy, and a data loader with workers gives the same batches as one
without. Importing the wrapper module never imports torch."""

import subprocess
import sys

import numpy as np
import pytest

from tests.support.helpers import ROOT


def test_importing_the_wrapper_does_not_import_torch():
    code = "import sys, camsim.pairs_torch; print('torch' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert done.stdout.strip() == "False"


def _source(**settings):
    from camsim.pairs import PairSource

    base = {"crop": (32, 32), "batch_size": 2, "cameras": ("sony-a7s2",), "intensity": (1e-2, 0.1), "seed": 9}
    return PairSource.from_scene("macbeth_26", ROOT / "scenes" / "images", **(base | settings))


def test_dataset_yields_the_batches_as_tensors():
    torch = pytest.importorskip("torch")
    from camsim.pairs_torch import batch_tensors, pair_dataset

    source = _source()
    batches = list(pair_dataset(source, start=2, stop=5))
    assert [b["index"] for b in batches] == [2, 3, 4]
    direct = source.batch(3)
    assert torch.equal(batches[1]["noisy"], torch.from_numpy(direct.noisy))
    assert batches[1]["digital"].dtype == torch.float32 and batches[1]["params"] == direct.params
    shared = batch_tensors(direct)
    assert shared["noisy"].data_ptr() == direct.noisy.ctypes.data  # the same memory: no copy
    assert np.array_equal(shared["digital"].numpy(), direct.digital.astype(np.float32))


def test_burst_batches_are_tensors_too():
    torch = pytest.importorskip("torch")
    from camsim.pairs_torch import batch_tensors, pair_dataset

    source = _source(burst_frames=3, shake_px=0.5, pan_px_per_s=(1.0, 0.0))
    batch = next(iter(pair_dataset(source, start=1, stop=2)))
    direct = source.batch(1)
    assert batch["noisy"].shape == batch["frames_clean"].shape == batch["digital"].shape == (2, 3, 1, 32, 32)
    assert batch["clean"].shape == (2, 1, 32, 32) and batch["homographies"].shape == (2, 3, 3, 3)
    assert batch["homographies"].dtype == torch.float64
    assert torch.equal(batch["noisy"], torch.from_numpy(direct.noisy))
    assert torch.equal(batch["homographies"], torch.from_numpy(direct.homographies))
    shared = batch_tensors(direct)
    assert shared["frames_clean"].data_ptr() == direct.frames_clean.ctypes.data  # no copy
    single = batch_tensors(_source().batch(0))
    assert single["homographies"] is None and single["frames_clean"] is None


@pytest.mark.slow
def test_workers_split_the_batches_and_change_nothing():
    torch = pytest.importorskip("torch")
    from camsim.pairs_torch import pair_dataset

    source = _source()
    alone = list(torch.utils.data.DataLoader(pair_dataset(source, stop=4), batch_size=None))
    workers = list(torch.utils.data.DataLoader(pair_dataset(source, stop=4), batch_size=None, num_workers=2))
    assert sorted(b["index"] for b in workers) == [0, 1, 2, 3]
    by_index = {b["index"]: b for b in workers}
    for b in alone:
        assert torch.equal(b["clean"], by_index[b["index"]]["clean"])
        assert torch.equal(b["noisy"], by_index[b["index"]]["noisy"])


def test_cuda_batches_reach_torch_on_the_gpu_without_a_copy():
    torch = pytest.importorskip("torch")
    from camsim.core.errors import CamsimError
    from camsim.pairs_torch import batch_tensors
    from camsim.render.backends import cuda_module

    try:
        cuda_module()
    except CamsimError as exc:
        pytest.skip(f"no GPU: {exc}")
    if not torch.cuda.is_available():
        pytest.skip("torch without CUDA")
    batch = _source(device="cuda").batch(0)
    tensors = batch_tensors(batch)
    assert tensors["noisy"].is_cuda and tensors["noisy"].data_ptr() == batch.noisy.data.ptr
    assert tensors["clean"].shape == (2, 1, 32, 32)
