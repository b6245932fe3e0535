"""A ``.npy`` file's header, checked before its data is read: what it claims is input like any other."""

from __future__ import annotations

import math
import os

from camsim.core.errors import CamsimError


def npy_header(path, what: str, check_shape=None) -> tuple | None:
    """(shape, dtype) from the header of the ``.npy`` file ``path``, checked against the file before any data is read.

    ``what`` names the file in messages (``"cube file"``, ``"dark_shading_map"``); ``check_shape(shape)``, where
    given, checks the claimed shape (a size limit) before the file's length is. None where the header cannot be read
    to its end (a truncated file): ``np.load`` then says what is wrong.

    Raises
    ------
    CamsimError
        A path that names no regular file (:func:`camsim.core.input_files.open_input`: missing, a directory, a FIFO,
        a device, a NUL byte), a file without NumPy's magic string (not a ``.npy``), a malformed header, a dimension
        below 1, a format version other than 1.0 and 2.0 (whose header numpy's public readers do not read), or a
        shape whose data the file does not hold (an overflow in numpy's memory map otherwise).
    """
    from numpy.lib import format as npy_format

    from camsim.core.input_files import open_input

    try:
        with open_input(path, what) as file:
            try:
                version = npy_format.read_magic(file)
            except ValueError:
                raise CamsimError(f"cannot read {what} {path}: not a .npy file (no NumPy magic string)") from None
            read = {(1, 0): npy_format.read_array_header_1_0, (2, 0): npy_format.read_array_header_2_0}.get(version)
            if read is None:  # 3.0 is for structured arrays with non-Latin-1 field names, which camsim refuses anyway
                raise CamsimError(f"cannot read {what} {path}: its .npy format version {version[0]}.{version[1]} "
                                  "is not one camsim reads (1.0 and 2.0, what numpy writes for arrays of numbers)")
            shape, _, dtype = read(file)
            data_bytes = os.fstat(file.fileno()).st_size - file.tell()
    except (OSError, EOFError):
        return None  # a truncated header: np.load says what is wrong
    except CamsimError:
        raise
    except Exception as exc:  # numpy's header parser raises ValueError, SyntaxError or tokenize.TokenError
        raise CamsimError(f"cannot read {what} {path}: its .npy header is malformed ({type(exc).__name__})") \
            from None
    if any(not isinstance(n, int) or n < 1 for n in shape):  # a negative length would reach mmap
        raise CamsimError(f"cannot read {what} {path}: its header's shape {tuple(shape)} has a dimension below 1")
    if check_shape is not None:
        check_shape(tuple(shape))
    if math.prod(shape) * dtype.itemsize > data_bytes:  # Python integers: no overflow
        raise CamsimError(f"cannot read {what} {path}: its header's shape {tuple(shape)} of {dtype} needs "
                          f"{math.prod(shape) * dtype.itemsize} bytes, the file holds {data_bytes}")
    return tuple(shape), dtype
