"""What a frame costs in memory, and what this process may still use: the limit that goes with
:data:`camsim.core.pixel_limit.MAX_PIXELS`.

:data:`~camsim.core.pixel_limit.MAX_PIXELS` (200 megapixels) is camsim's absolute cap. Under it a frame can still need
more memory than the machine has: a 14 000 × 14 000 PNG (196 megapixels, 24 kB on disk) takes about 9 GB to render
by the figures below. Under a 6 GB address-space limit such a render decodes for half a minute before it fails with
"out of memory"; where the kernel's out-of-memory killer acts first, it ends the process with no message at all. So
the memory a frame needs is estimated from its size, which the file's header gives before a pixel is decoded, and
compared with the memory free now (:func:`free_memory`); a frame that does not fit is refused on one line, which says
how to allow it anyway (``--max-megapixels``).

The figures are measured: ``camsim render`` of a scene at three or more sizes, one frame each (``-F 1``, one
illuminant, ``--workers 2``), the peak of the process's resident memory (``VmHWM``, and ``/usr/bin/time -v``'s maximum
resident set size) and of its address space (``VmPeak``) read from ``/proc/self/status`` at the end, and the slope
fitted between the sizes (the intercept, some 0.4 GB resident and 0.8 GB of address space, is Python and its
libraries, already counted by what is free). On the x86-64 Linux machine of the measurement (numpy 2.4, OpenImageIO
3.2):

=========================================================  =======================  ======================
scene                                                      sizes (megapixels)       slope (bytes a pixel)
=========================================================  =======================  ======================
ColorChecker chart, 24 spectra                             4, 16, 36                42
photograph (8-bit PNG, about 10⁵ colours)                  1, 4, 9, 16, 36          45
8-bit PNG of random colours (one colour per 1.6 pixels)    1, 4, 9, 16              127 resident, 141 address
16-bit PNG of random colours (a colour per pixel)          2.25, 6.25               209 resident, 230 address
slanted edge through a lens (``[optics]``: FFTs)           1, 4, 9                  98
31-band float32 ``.npy`` cube (a spectrum per pixel)       1, 2.25, 4               156 resident, 290 address
photograph resampled to 400 × 400 (``[image] size``)       4, 16 (the file's)       48 per file pixel
=========================================================  =======================  ======================

A frame's pixel costs about :data:`FRAME_BYTES_PER_PIXEL`; each distinct colour of an image costs
:data:`COLOUR_BYTES` more (the random images' excess over the photograph, divided by their colours: 150 to 185
bytes); the cube's address-space figure is its file's 124 bytes a pixel (mapped) plus :data:`CUBE_BYTES_PER_PIXEL`.
The header does not say how many colours an image has, so the estimate takes the most its codes can make, at most one
per pixel (:func:`camsim.scene.sources.image.image_colour_limit`: 2²⁴ for 8-bit RGB): an upper bound, three times
the photograph's need at 36 megapixels and 1.5 times the 8-bit noise's at 16, within 5 % of the 16-bit noise's.
"""

from __future__ import annotations

import math
import os
import resource
from dataclasses import dataclass

from camsim.core.errors import CamsimError
from camsim.core.input_files import size_text

#: Memory of one pixel of a rendered frame of few spectra (a chart, a target, a photograph's ~10⁵ colours): the
#: label map, the expected and noisy layers, the digital numbers and the files' buffers (module docstring). Unit: bytes.
FRAME_BYTES_PER_PIXEL = 45
#: The same through a lens (``[optics]``): the per-channel FFTs of the expected electrons. Unit: bytes.
OPTICS_BYTES_PER_PIXEL = 100
#: Memory of one distinct colour of an image, beyond its pixels: its linear RGB, its spectrum's coefficients, its
#: expected values per channel and the sort that finds it (module docstring). Unit: bytes.
COLOUR_BYTES = 185
#: Memory of one pixel of a cube's frame, whose every pixel is its own spectrum, besides the file's data (mapped, or
#: loaded whole for a ``.mat``). Unit: bytes.
CUBE_BYTES_PER_PIXEL = 170
#: Memory of one pixel of an image file resampled by ``[image] size``: its codes, its linear RGB and the
#: anti-aliasing filter's output, in float64. Unit: bytes.
RESIZE_BYTES_PER_SOURCE_PIXEL = 50


@dataclass(frozen=True)
class FrameNeed:
    """The memory a frame needs (:mod:`camsim.render.frame_memory` estimates it from a scene).

    Attributes
    ----------
    what : str
        What has the size, for the message (``"image /data/x.png"``, ``"frame"``).
    width, height : int
        The frame's size. Unit: pixels.
    resident : int
        Memory written to (the kernel must find it). Unit: bytes.
    mapped : int
        Address space of files mapped and read through (a cube's data), besides ``resident``. Unit: bytes.
    """

    what: str
    width: int
    height: int
    resident: int
    mapped: int = 0

    @property
    def megapixels(self) -> float:
        """width × height / 10⁶. Unit: megapixels."""
        return self.width * self.height / 1e6


@dataclass(frozen=True)
class FreeMemory:
    """Memory this process may still use, and what bounds it.

    Attributes
    ----------
    resident : int or None
        Memory available to write to: the smaller of the system's ``MemAvailable`` and the room left under the
        process's control group's limit (``memory.max``); None where neither is known. Unit: bytes.
    resident_where : str
        What bounds ``resident``, for the message.
    address_space : int or None
        Address space left under ``RLIMIT_AS`` (``ulimit -v``): its soft limit less the process's size now; None
        where there is no limit. Unit: bytes.
    """

    resident: int | None
    resident_where: str
    address_space: int | None


def _proc_field_bytes(path: str, field: str) -> int | None:
    """The ``FIELD:  N kB`` line of a /proc file (``/proc/meminfo``, ``/proc/self/status``) in bytes; None where the
    file or the line is missing or malformed (not Linux)."""
    try:
        with open(path, encoding="ascii") as handle:
            for line in handle:
                if line.startswith(f"{field}:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _meminfo_available() -> int | None:
    available = _proc_field_bytes("/proc/meminfo", "MemAvailable")
    if available is not None:
        return available
    try:  # not Linux: the free pages
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return None


def _read_number(path: str) -> int | None:
    try:
        with open(path, encoding="ascii") as handle:
            text = handle.read().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None  # "max": no limit


def _inactive_file(path: str, key: str) -> int:
    """The page cache a control group's usage counts that the kernel drops before it kills (``memory.stat``)."""
    try:
        with open(path, encoding="ascii") as handle:
            for line in handle:
                name, _, value = line.partition(" ")
                if name == key:
                    return int(value)
    except (OSError, ValueError):
        pass
    return 0


def _cgroup_room() -> int | None:
    """Room left under this process's control group's memory limit (v2 ``memory.max``, v1
    ``memory.limit_in_bytes``), less what the group uses; None where there is no limit (or no control group)."""
    try:
        with open("/proc/self/cgroup", encoding="ascii") as handle:
            lines = handle.read().splitlines()
    except OSError:
        return None
    for line in lines:
        _, controllers, group = line.split(":", 2) if line.count(":") >= 2 else ("", "", "")
        if controllers == "":  # v2
            candidates = [(f"/sys/fs/cgroup{group}", "memory.max", "memory.current", "inactive_file"),
                          ("/sys/fs/cgroup", "memory.max", "memory.current", "inactive_file")]
        elif "memory" in controllers.split(","):  # v1
            candidates = [(f"/sys/fs/cgroup/memory{group}", "memory.limit_in_bytes", "memory.usage_in_bytes",
                           "total_inactive_file"),
                          ("/sys/fs/cgroup/memory", "memory.limit_in_bytes", "memory.usage_in_bytes",
                           "total_inactive_file")]
        else:
            continue
        for folder, limit_name, usage_name, inactive in candidates:
            limit = _read_number(f"{folder}/{limit_name}")
            usage = _read_number(f"{folder}/{usage_name}")
            if limit is None or usage is None:
                continue
            if limit >= 2**60:  # v1's "no limit" is the largest page-aligned int64
                break
            return max(0, limit - usage + _inactive_file(f"{folder}/memory.stat", inactive))
    return None


def _own_address_space() -> int:
    """The process's size now (``VmSize``; 0 where unknown). Unit: bytes."""
    return _proc_field_bytes("/proc/self/status", "VmSize") or 0


def free_memory() -> FreeMemory:
    """The memory this process may still use: physical memory (``MemAvailable``, and its control group's limit) and
    address space (``RLIMIT_AS``). Read each time: it changes as other programs run."""
    available, cgroup = _meminfo_available(), _cgroup_room()
    if cgroup is not None and (available is None or cgroup < available):
        resident, where = cgroup, "free under this process's control group's memory limit"
    else:
        resident, where = available, "this machine has free"
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    space = None if soft == resource.RLIM_INFINITY else max(0, soft - _own_address_space())
    return FreeMemory(resident, where, space)


def _allowing(megapixels: float) -> str:
    """The ``--max-megapixels`` value that lets a frame of ``megapixels`` through (rounded up, to 0.1)."""
    return f"{math.ceil(megapixels * 10) / 10:g}"


def check_frame_memory(need: FrameNeed, max_megapixels: float | None = None, free: FreeMemory | None = None) -> None:
    """Refuse a frame that does not fit: over ``max_megapixels`` where it is given, else over the memory free.

    Parameters
    ----------
    need : FrameNeed
        The frame's size and the memory it needs.
    max_megapixels : float, optional
        The user's limit (``--max-megapixels``), in place of the memory check: a frame within it is rendered
        whatever the memory free. Unit: megapixels.
    free : FreeMemory, optional
        The memory free (default: :func:`free_memory`, now).

    Raises
    ------
    CamsimError
        One line: the frame's size, the memory it needs and the memory free (or the limit given), and the
        ``--max-megapixels`` that allows it.
    """
    size = f"{need.what} is {need.width} × {need.height} pixels ({need.megapixels:.3g} MP)"
    if max_megapixels is not None:
        if need.megapixels > max_megapixels:
            raise CamsimError(f"{size}, over --max-megapixels {max_megapixels:g} (--max-megapixels "
                              f"{_allowing(need.megapixels)} allows it)")
        return
    free = free_memory() if free is None else free
    budgets = ((need.resident, free.resident, free.resident_where),
               (need.resident + need.mapped, free.address_space,
                "free under this process's address-space limit (ulimit -v)"))
    for needed, room, where in budgets:
        if room is not None and needed > room:
            raise CamsimError(f"{size}; rendering it needs about {size_text(needed)} of memory, over the "
                              f"{size_text(room)} {where} (--max-megapixels {_allowing(need.megapixels)} allows it)")


__all__ = ["COLOUR_BYTES", "CUBE_BYTES_PER_PIXEL", "FRAME_BYTES_PER_PIXEL", "FrameNeed",
           "FreeMemory", "OPTICS_BYTES_PER_PIXEL", "RESIZE_BYTES_PER_SOURCE_PIXEL", "check_frame_memory",
           "free_memory"]
