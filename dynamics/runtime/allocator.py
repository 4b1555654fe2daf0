"""The C allocator of a command-line run: freed large arrays kept for the next ones.

A diagnosis allocates and frees arrays of megabytes thousands of times (a candidate's columns, the
regressor along a moved motion, the residuals of each fit). glibc's ``malloc`` serves each one above its
mmap threshold by a fresh ``mmap`` and gives it back to the kernel when freed, and it returns the free
top of its heap above 128 KiB: every new array then faults its pages in again, each zeroed by the
kernel. On a 14 000-sample 7-joint ``oed diagnose`` that was 2.0 s of system time in 11.3 s;
with the freed memory kept (:func:`keep_freed_memory`) 1.0 s, and 0.6 s less end to end, the peak
resident memory the same (benchmarks/README.md).

:func:`keep_freed_memory` sets glibc's thresholds (``mallopt``) for the process that calls it: the ``oed``
command line does, the library does not (a program that imports it keeps its own allocator). Memory
freed after the peak stays with the process until it ends. Elsewhere than glibc it does nothing.
"""

from __future__ import annotations

import ctypes
import os

__all__ = ["MMAP_THRESHOLD", "TOP_PAD", "TRIM_THRESHOLD", "keep_freed_memory"]

#: arrays up to this size come from the heap, not from their own ``mmap`` (glibc's largest allowed value)
MMAP_THRESHOLD = 32 * 1024**2
#: free memory at the heap's top kept up to this size instead of returned to the kernel
TRIM_THRESHOLD = 1024**3
#: extra address space asked for each time the heap grows (not resident until used)
TOP_PAD = 256 * 1024**2

# mallopt's parameter numbers (malloc.h)
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3


def _glibc() -> bool:
    """Whether the running C library is glibc (its own answer, not a guess from the platform)."""
    try:
        return (os.confstr("CS_GNU_LIBC_VERSION") or "").startswith("glibc")
    except (ValueError, OSError, AttributeError):
        return False


def keep_freed_memory() -> bool:
    """Keep freed memory in this process's heap for the next allocations (module docstring).

    Returns
    -------
    bool
        Whether every setting was taken (``False`` off glibc, where nothing is changed).
    """
    if not _glibc():
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    taken = [mallopt(parameter, value) for parameter, value in
             ((_M_MMAP_THRESHOLD, MMAP_THRESHOLD), (_M_TRIM_THRESHOLD, TRIM_THRESHOLD), (_M_TOP_PAD, TOP_PAD))]
    return all(flag == 1 for flag in taken)
