"""A thin torch wrapper of :mod:`camsim.pairs`: an ``IterableDataset`` of batches of torch tensors.

torch is an optional extra (``pip install '.[torch]'`` in camsim's folder; docs, 'Getting started', for its size and a
CPU build) and is imported only when :func:`pair_dataset` is called: importing this module imports nothing but
camsim. On a GPU the tensors are the
batch's CuPy arrays, handed over by DLPack (``torch.from_dlpack``: the same device memory, no copy through the host);
on the CPU numpy's (``torch.from_numpy``). Give the dataset to a ``DataLoader`` with ``batch_size=None`` (the
batches are formed already); with CPU workers each worker renders every n-th batch, so a run's batches do not depend
on the number of workers (CUDA sources render in the main process: ``num_workers=0``). Burst sources
(``burst_frames``) give (B, N, planes, H, W) noisy frames, the (B, planes, H, W) clean reference and (B, N, 3, 3)
homographies (:func:`batch_tensors`).

:func:`written_pairs` is a map-style ``Dataset`` over a dataset written by ``camsim dataset`` (files or a Zarr
store): item *i* is frame *i*'s pair in a domain (:class:`camsim.pairs.WrittenPairs`) as tensors, batched by a
``DataLoader`` with :func:`collate_pairs`.
"""

from __future__ import annotations

from camsim.pairs import PairBatch, PairBatches, PairSource, WrittenPairs

_CLASSES: dict = {}


def to_torch(array):
    """A numpy or CuPy array as a torch tensor sharing its memory (``from_numpy``, or DLPack for CuPy)."""
    import numpy as np
    import torch

    if isinstance(array, np.ndarray):
        return torch.from_numpy(array)
    return torch.from_dlpack(array)


def batch_tensors(batch: PairBatch) -> dict:
    """A :class:`~camsim.pairs.PairBatch` as a dict of tensors: ``noisy``, ``clean`` (float32, in the batch's
    domain: DN, normalised raw or sRGB), ``digital`` (the raw numbers as float32, exact below 2²⁴; None without
    quantisation and outside the ``dn`` domain), ``params`` (list of dict), ``index``, ``domain`` and ``isp`` (per
    pair, how the arrays were made; None in ``dn``).

    A burst batch (``burst_frames = N``) adds ``homographies`` (B, N, 3, 3) float64 (reference crop pixel → frame
    pixel) and ``frames_clean`` (B, N, planes, H, W) float32 (each frame's own expectation); its ``noisy`` and
    ``digital`` are (B, N, planes, H, W), its ``clean`` (B, planes, H, W) the static crop's expectation. Both keys
    are None for single pairs. With a rolling shutter ``row_homographies`` (B, N, H, 3, 3) float32 (each row's, at its
    exposure's middle), with flicker ``flicker_factor`` (B, N, H) float64 (each row's share of the light); None
    otherwise."""
    digital = None
    if batch.digital is not None:
        digital = to_torch(batch.digital.astype(batch.noisy.dtype))
    burst = {"homographies": None if batch.homographies is None else to_torch(batch.homographies),
             "frames_clean": None if batch.frames_clean is None else to_torch(batch.frames_clean),
             "row_homographies": None if batch.row_homographies is None else to_torch(batch.row_homographies),
             "flicker_factor": None if batch.flicker_factor is None else to_torch(batch.flicker_factor)}
    return {"noisy": to_torch(batch.noisy), "clean": to_torch(batch.clean), "digital": digital,
            "params": batch.params, "index": batch.index, "domain": batch.domain, "isp": batch.isp, **burst}


def _dataset_class():
    """The ``IterableDataset`` subclass, made on first use (torch is imported then)."""
    if "dataset" not in _CLASSES:
        import torch

        class PairDataset(torch.utils.data.IterableDataset):
            """Batches ``start``, ``start + 1``, … (before ``stop``) of a :class:`~camsim.pairs.PairSource` as dicts
            of tensors (:func:`batch_tensors`); split between a data loader's workers, worker w of n taking every
            n-th batch from ``start + w``."""

            def __init__(self, source: PairSource, start: int = 0, stop: int | None = None):
                super().__init__()
                self.source, self.start, self.stop = source, start, stop

            def __iter__(self):
                info = torch.utils.data.get_worker_info()
                worker, workers = (0, 1) if info is None else (info.id, info.num_workers)
                for batch in PairBatches(self.source, self.start + worker, self.stop, workers):
                    yield batch_tensors(batch)

        _CLASSES["dataset"] = PairDataset
    return _CLASSES["dataset"]


def _written_class():
    """The map-style ``Dataset`` subclass over a written dataset, made on first use (torch is imported then)."""
    if "written" not in _CLASSES:
        import torch

        class WrittenPairDataset(torch.utils.data.Dataset):
            """Frame *i*'s pair of a written dataset (:class:`~camsim.pairs.WrittenPairs`) as a dict: ``noisy``,
            ``clean`` (float32 tensors, (planes, H, W)) and ``meta``."""

            def __init__(self, pairs: WrittenPairs):
                super().__init__()
                self.pairs = pairs

            def __len__(self) -> int:
                return len(self.pairs)

            def __getitem__(self, i: int) -> dict:
                noisy, clean, meta = self.pairs.read(i)
                item = {"noisy": torch.from_numpy(noisy), "clean": torch.from_numpy(clean), "meta": meta}
                if self.pairs.burst:  # each frame's homography, reference pixel → frame pixel
                    item["homography"] = torch.from_numpy(meta["homography"])
                return item

        _CLASSES["written"] = WrittenPairDataset
    return _CLASSES["written"]


def written_pairs(path, domain: str = "dn", crop: tuple | None = None, seed: int = 0, burst: bool = False):
    """A map-style ``torch.utils.data.Dataset`` over the dataset written by ``camsim dataset`` into ``path`` (its
    output folder, files or Zarr): item *i* is ``{"noisy", "clean", "meta"}``, the pair of its *i*-th complete
    frame in ``domain`` (``"dn"``, ``"raw"``, ``"srgb"``), cut to ``crop`` (width, height) at an offset drawn from
    ``seed`` and *i* (:class:`camsim.pairs.WrittenPairs`). Batch with ``DataLoader(..., collate_fn=collate_pairs)``
    (the pairs of a batch must have one size: give a ``crop`` where the frames' sizes differ).

    ``burst=True`` (a dataset of bursts): item *i* is its *i*-th burst, ``noisy`` (N, P, H, W) the frames,
    ``clean`` (P, H, W) the clean reference (the static scene), and ``homography`` (N, 3, 3) float64, reference
    pixel → frame pixel; :func:`collate_pairs` stacks them into (B, N, P, H, W), (B, P, H, W) and (B, N, 3, 3)."""
    return _written_class()(WrittenPairs(path, domain, crop, seed, burst=burst))


def collate_pairs(items: list) -> dict:
    """A ``DataLoader``'s ``collate_fn`` for :func:`written_pairs`: ``noisy`` and ``clean`` stacked into (B, planes,
    H, W) tensors (bursts: (B, N, planes, H, W) and ``homography`` (B, N, 3, 3)), ``meta`` a list of the items'
    dicts."""
    import torch

    out = {"noisy": torch.stack([item["noisy"] for item in items]),
           "clean": torch.stack([item["clean"] for item in items]), "meta": [item["meta"] for item in items]}
    if "homography" in items[0]:
        out["homography"] = torch.stack([item["homography"] for item in items])
    return out


def pair_dataset(source: PairSource, start: int = 0, stop: int | None = None):
    """A ``torch.utils.data.IterableDataset`` of the batches ``start`` … ``stop − 1`` of ``source`` (without end
    for None), each a dict of tensors (:func:`batch_tensors`)."""
    return _dataset_class()(source, start, stop)


__all__ = ["batch_tensors", "collate_pairs", "pair_dataset", "to_torch", "written_pairs"]
