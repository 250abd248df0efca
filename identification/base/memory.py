"""Large arrays handed back to the operating system when they are freed (glibc's malloc).

glibc serves a request above its mmap threshold (128 KiB at start) with mmap and unmaps it when
it is freed, but each time such a block is freed it raises the threshold to that block's size,
up to 32 MiB on 64-bit systems (mallopt(3), M_MMAP_THRESHOLD).  From then on arrays of up to that
size come from the heap, where a freed block stays resident while anything allocated after it
lives.  A doctor run allocates and frees arrays of one to a few tens of MiB by the thousand
(every replay's pressures, every hypothesis's regressors), so its resident memory ratchets up:
measured 2026-12-06 on a humanoid38 case of 60 s + 30 s (a supply droop, seed 534539611, the
doctor of `3aa672b` in a process of its own, sampled every 0.25 s), the resident set climbed
from 3.0 GiB after the pneumatic search to 4822 MiB at the end under glibc's default, against
a peak of 2548 MiB with the threshold fixed at 1 MiB, the same finding named.  Fixing the
threshold (which also stops glibc from moving it) keeps every block of 1 MiB or more out of the
heap, at the price of a page-mapping system call per such array.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import platform

#: mallopt's parameter number of the mmap threshold (glibc's malloc.h)
M_MMAP_THRESHOLD = -3
#: requests of this many bytes or more are mapped, and unmapped when freed
MMAP_THRESHOLD_BYTES = 1 << 20


def return_freed_arrays(threshold_bytes: int = MMAP_THRESHOLD_BYTES) -> bool:
    """Fix glibc's mmap threshold at ``threshold_bytes`` for this process, so that arrays of that
    size or more go back to the operating system when freed; returns whether it was set (False
    where the C library is not glibc: macOS, Windows, musl, which manage their memory otherwise).
    Process-wide and idempotent; it changes no result, only where the memory comes from."""
    if platform.libc_ver()[0] != "glibc":
        return False
    try:
        mallopt = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, int(threshold_bytes)))
