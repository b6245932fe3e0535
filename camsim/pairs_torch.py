"""A thin torch wrapper of :mod:`camsim.pairs`: an ``IterableDataset`` of batches of torch tensors.

torch is an optional extra (``pip install '.[torch]'`` in camsim's folder; docs, 'Getting started', for its size and a
CPU build) and is imported only when :func:`pair_dataset` is called: importing this module imports nothing but
camsim. On a GPU the tensors are the
batch's CuPy arrays, handed over by DLPack (``torch.from_dlpack``: the same device memory, no copy through the host);
on the CPU numpy's (``torch.from_numpy``). Give the dataset to a ``DataLoader`` with ``batch_size=None`` (the
batches are formed already); with CPU workers each worker renders every n-th batch, so a run's batches do not depend
on the number of workers (CUDA sources render in the main process: ``num_workers=0``).
"""

from __future__ import annotations

from camsim.pairs import PairBatch, PairBatches, PairSource

_CLASSES: dict = {}


def to_torch(array):
    """A numpy or CuPy array as a torch tensor sharing its memory (``from_numpy``, or DLPack for CuPy)."""
    import numpy as np
    import torch

    if isinstance(array, np.ndarray):
        return torch.from_numpy(array)
    return torch.from_dlpack(array)


def batch_tensors(batch: PairBatch) -> dict:
    """A :class:`~camsim.pairs.PairBatch` as a dict of tensors: ``noisy``, ``clean`` (float32, DN), ``digital``
    (the raw numbers as float32, exact below 2²⁴; None without quantisation), ``params`` (list of dict) and
    ``index``."""
    digital = None
    if batch.digital is not None:
        digital = to_torch(batch.digital.astype(batch.noisy.dtype))
    return {"noisy": to_torch(batch.noisy), "clean": to_torch(batch.clean), "digital": digital,
            "params": batch.params, "index": batch.index}


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


def pair_dataset(source: PairSource, start: int = 0, stop: int | None = None):
    """A ``torch.utils.data.IterableDataset`` of the batches ``start`` … ``stop − 1`` of ``source`` (without end
    for None), each a dict of tensors (:func:`batch_tensors`)."""
    return _dataset_class()(source, start, stop)


__all__ = ["batch_tensors", "pair_dataset", "to_torch"]
