"""The training process keeps freed memory for reuse (glibc's malloc)."""

import ctypes
import subprocess
import sys

import pytest

from activeperc_rl.runtime import allocator
from activeperc_rl.runtime.allocator import keep_freed_memory

PROBE = """
import ctypes, importlib.util, sys
import numpy as np

# the module alone, without the package (whose import would load torch and take seconds)
spec = importlib.util.spec_from_file_location("allocator", sys.argv[2])
allocator = importlib.util.module_from_spec(spec)
spec.loader.exec_module(allocator)

class MallInfo2(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_size_t)
        for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                     "keepcost")
    ]

libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype = MallInfo2
if sys.argv[1] == "keep":
    assert allocator.keep_freed_memory()
block = np.ones(50_000_000 // 8)  # 50 MB: above glibc's default mmap threshold
del block
print(libc.mallinfo2().fordblks)  # free bytes the process holds for reuse
"""


def _free_bytes_after_a_50_mb_block(mode: str) -> int:
    probe = [sys.executable, "-c", PROBE, mode, allocator.__file__]
    out = subprocess.run(probe, capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1])


def _has_mallinfo2() -> bool:
    try:
        return hasattr(ctypes.CDLL("libc.so.6"), "mallinfo2")  # glibc >= 2.33
    except OSError:
        return False


@pytest.mark.skipif(not _has_mallinfo2(), reason="measures glibc's malloc (2.33 or later)")
def test_a_freed_large_block_stays_in_the_process_for_reuse():
    assert _free_bytes_after_a_50_mb_block("default") < 10_000_000  # returned to the system
    assert _free_bytes_after_a_50_mb_block("keep") >= 50_000_000


def test_repeated_calls_are_harmless():
    first, second = keep_freed_memory(), keep_freed_memory()
    assert first == second
    assert first or not _has_mallinfo2()  # glibc takes the setting
