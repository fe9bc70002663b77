"""Give a Dask worker back glibc's own memory thresholds before it computes a cell.

Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536`` so that freed memory goes back to the system. Any
malloc threshold set that way also freezes glibc's mmap threshold at 128 KiB, so every array above it (a frame, a
batch of contact levels) becomes a fresh mapping whose pages the kernel faults in and zeroes on first use. A
paper-sized cell then took 2.4x as long, more than half of it in the kernel (BENCHMARKS.md, explore). A worker
sets the thresholds to the ceiling glibc's dynamic rule reaches by itself on 64-bit (mmap 32 MiB, trim twice
that), once per process, and only where the environment froze them; elsewhere, and off glibc, nothing changes.
"""
from __future__ import annotations

import ctypes
import functools
import os
import sys

M_TRIM_THRESHOLD = -1  # glibc's mallopt parameters (malloc.h)
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD_BYTES = 32 << 20
TRIM_THRESHOLD_BYTES = 2 * MMAP_THRESHOLD_BYTES
FREEZING_VARIABLES = ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TOP_PAD_")


@functools.cache
def relax_frozen_malloc_thresholds() -> bool:
    """True if this process's thresholds were frozen by its environment and have been reset."""
    if not sys.platform.startswith("linux") or not any(v in os.environ for v in FREEZING_VARIABLES):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc (e.g. musl has no mallopt)
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
