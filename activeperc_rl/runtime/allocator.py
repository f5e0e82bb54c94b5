"""The C allocator's settings for a training process.

The learner's batches (hundreds of 80x60 images, their activations and gradients) are tensors of several
megabytes, allocated and freed many times per iteration. glibc's ``malloc`` serves blocks that large with
``mmap`` and returns them to the system on ``free``, so every update pays page faults on fresh memory. Here
freed memory stays in the process for the next allocation instead: the values computed are the same, the
resident memory rises to the peak of an iteration and stays there.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

# mallopt(3) parameters of glibc
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
KEEP_BELOW = 1 << 30
"""Blocks up to this many bytes come from the heap and stay in the process once freed."""


def keep_freed_memory() -> bool:
    """Make glibc's ``malloc`` keep freed blocks below :data:`KEEP_BELOW` bytes for reuse (this whole process).

    Returns whether the setting took effect: ``False`` where the C library is not glibc (macOS, musl),
    which leaves the allocator as it was.
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, KEEP_BELOW)) and bool(mallopt(_M_TRIM_THRESHOLD, KEEP_BELOW))
