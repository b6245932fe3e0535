"""The memory a frame needs against the memory free (camsim.core.memory_limit): the check's verdicts on a stated
need and a stated free memory, and what this machine reports free."""

import resource

import pytest

from camsim.core.errors import CamsimError
from camsim.core.memory_limit import FrameNeed, FreeMemory, check_frame_memory, free_memory

NEED = FrameNeed("image /x.png", 14_000, 14_000, resident=9_000_000_000)


def test_a_frame_over_the_free_memory_is_refused_naming_both_and_the_way_round_it():
    free = FreeMemory(4_000_000_000, "this machine has free", None)
    with pytest.raises(CamsimError) as info:
        check_frame_memory(NEED, free=free)
    assert str(info.value) == ("image /x.png is 14000 × 14000 pixels (196 MP); rendering it needs about 9 GB of "
                               "memory, over the 4 GB this machine has free (--max-megapixels 196 allows it)")


def test_the_address_space_limit_counts_mapped_files_too():
    """A cube's mapped data takes address space, not memory: it counts against ``ulimit -v`` only."""
    need = FrameNeed("cube /c.npy", 2000, 2000, resident=1_000_000_000, mapped=3_000_000_000)
    check_frame_memory(need, free=FreeMemory(2_000_000_000, "this machine has free", None))
    with pytest.raises(CamsimError, match="needs about 4 GB of memory, over the 3.5 GB free under this process's "
                                          r"address-space limit \(ulimit -v\) \(--max-megapixels 4 allows it\)"):
        check_frame_memory(need, free=FreeMemory(2_000_000_000, "this machine has free", 3_500_000_000))


def test_a_frame_that_fits_passes_and_an_unknown_budget_does_not_refuse():
    check_frame_memory(NEED, free=FreeMemory(10_000_000_000, "this machine has free", 10_000_000_000))
    check_frame_memory(NEED, free=FreeMemory(None, "this machine has free", None))


def test_max_megapixels_replaces_the_memory_check():
    tiny = FreeMemory(1, "this machine has free", 1)
    check_frame_memory(NEED, max_megapixels=196, free=tiny)  # the user's word: rendered whatever is free
    with pytest.raises(CamsimError) as info:
        check_frame_memory(NEED, max_megapixels=150.5, free=tiny)
    assert str(info.value) == ("image /x.png is 14000 × 14000 pixels (196 MP), over --max-megapixels 150.5 "
                               "(--max-megapixels 196 allows it)")


def test_the_way_round_rounds_up():
    need = FrameNeed("frame", 1001, 1000, resident=10**12)
    with pytest.raises(CamsimError, match=r"\(--max-megapixels 1.1 allows it\)"):
        check_frame_memory(need, max_megapixels=1)


def test_this_machine_reports_its_free_memory_and_its_address_space_limit():
    free = free_memory()
    assert free.resident is not None and free.resident > 0  # Linux: MemAvailable
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        assert free.address_space is None
    else:
        assert 0 <= free.address_space < soft
