"""The memory allocator's state for block-wise kernels: the first call as fast as the later ones.

The vectorized kernels (:func:`pmaccuracy.accuracy.bounds.bounds_kernel` and the maps built on it) work on
blocks of a few thousand poses, and each block creates and frees a few hundred temporaries of 64-320 kB.
With the C library's defaults on Linux (glibc) the first calls of a process pay for that twice over: a
temporary of 128 kB or more gets its own ``mmap`` (fresh pages, a page fault per 4 kB on first write), and
whenever more than 128 kB lie free at the top of the heap they go back to the system, to be faulted in again
by the next block. glibc adjusts both limits by itself once a process frees a large block it had mapped
(``mallopt(3)``, "dynamic mmap threshold": the mapping threshold rises to that block's size and the trim
threshold to twice that), which is why the second or third call of a map ran two to three times faster
than the first (issue 35).

:func:`settle_allocator` makes that adjustment happen before the first block rather than after the first
call: it allocates one 16 MiB array, never writes to it (no page is touched) and frees it. It costs a few
microseconds once per process, changes no result, and leaves the allocator as any numpy program leaves it
after freeing its first large array. On other C libraries it is an allocation and a free, nothing more.
"""

from __future__ import annotations

import numpy as np

#: Size of the array allocated and freed once (bytes): glibc's dynamic thresholds follow the largest mapped
#: block freed, up to 32 MiB; 16 MiB keeps every block temporary (well below 1 MiB) on the heap.
SETTLE_BYTES = 16 << 20

_settled = False


def settle_allocator() -> None:
    """Once per process: allocate and free an untouched 16 MiB array, so that the allocator keeps the
    kernels' per-block temporaries on its heap from the first block on (module docstring)."""
    global _settled
    if _settled:
        return
    _settled = True
    np.empty(SETTLE_BYTES // 8)   # mapped, never written (no page faulted in) and released at once
