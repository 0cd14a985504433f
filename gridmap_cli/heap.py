"""How the C heap hands memory back: tuned for a build, whose batches allocate and free
grid-sized scratch arrays (a few MiB each) hundreds of times.

glibc serves such blocks with fresh ``mmap`` pages and unmaps them when freed, so every batch
faulted its scratch pages in again: 2 s of system time in the 8 h build (4.6 million readings,
0.2 s with blocks up to 32 MiB kept on the heap), which made it 12x the 1 h build in CPU.
"""

from __future__ import annotations

import ctypes

#: glibc's mallopt parameters (malloc.h).
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
#: Blocks below this come from the heap and are reused (glibc's largest allowed value).
MMAP_THRESHOLD_BYTES = 32 << 20
#: Free memory at the top of the heap kept rather than returned: two of the largest blocks.
TRIM_THRESHOLD_BYTES = 64 << 20


def keep_scratch_memory() -> bool:
    """Ask glibc to keep freed blocks up to :data:`MMAP_THRESHOLD_BYTES` for reuse; False where
    the C library is not glibc (nothing changes there). Whole-process: for commands, not for a
    library call."""
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the process's own symbols: its C library's
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    ok = mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
    return ok and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES) == 1)


def release_free_memory() -> bool:
    """Hand the free pages inside the C heap back (glibc's ``malloc_trim``); False where the C
    library is not glibc. Between a build's bounds pass and its mapping pass: the bounds pass's
    freed temporaries otherwise sit between live blocks, and the mapping pass grew the heap past
    them (the 8 h log's build peaked 4 MiB higher)."""
    try:
        trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError, TypeError):
        return False
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return bool(trim(0))


#: Batches mapped between two :func:`release_free_memory` calls in a build.
TRIM_EVERY_BATCHES = 16


class TrimEvery:
    """Call :func:`release_free_memory` every ``n`` calls: during the mapping pass, the free
    pages that batches' temporaries leave between live blocks are handed back now and then,
    so that later batches do not grow the heap past them. The 8 h error-aware build peaked at
    194 MiB without it, 188 MiB trimming every 16th batch (1.21x -> 1.14x the 1 h build), for
    about 5 % more CPU; trimming after every batch cost 10 %."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.calls = 0

    def __call__(self) -> None:
        self.calls += 1
        if self.calls % self.n == 0:
            release_free_memory()
