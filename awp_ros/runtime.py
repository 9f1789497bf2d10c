"""
Process-wide tuning for the per-cycle hot path, called once by each executable's main().

Three settings matter for a loop that evaluates small numpy problems at 1 kHz:

- BLAS threads: the products here are small, and a second OpenBLAS thread on a 2-core
  machine shared with DDS threads costs more than it gains (measured 2x slower for the FWS).
- glibc's allocator: numpy temporaries above the mmap threshold (128 kB by default) are
  returned to the kernel when freed and come back as fresh zeroed pages the next cycle, which
  costs as much as the arithmetic. Raising the trim and mmap thresholds keeps them in the heap.
- the cyclic garbage collector: every full collection traverses every tracked object, most of
  them created at startup (Pinocchio model, rclpy, numpy, message classes) and alive for
  good; :func:`freeze_startup_objects` moves them out of its sight once the process is set up.

Library code never calls this: it changes the whole process.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc

__all__ = ['freeze_startup_objects', 'keep_freed_memory', 'limit_blas_threads', 'tune_process']

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3


def tune_process(blas_threads: int = 1, heap_bytes: int = 64 << 20) -> None:
    """Limit BLAS to ``blas_threads`` threads and keep up to ``heap_bytes`` [B] in the heap."""
    limit_blas_threads(blas_threads)
    keep_freed_memory(heap_bytes)


def limit_blas_threads(n: int):
    """
    Limit the BLAS thread pools of this process to ``n`` threads; 0 leaves them as they are.

    OpenBLAS threads busy-wait between calls; on a machine whose cores are shared with the
    DDS threads, the message publisher and other processes they stalled single FWS
    evaluations for ~300 ms (measured on 2 cores); with 1 thread the same took ~10 ms.

    :return: threadpoolctl's limiter (keep it alive), None when ``n`` is 0 or threadpoolctl
        is not installed.
    """
    if n <= 0:
        return None
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: without it BLAS keeps its default thread count
        return None
    return threadpool_limits(limits=n, user_api='blas')


def freeze_startup_objects() -> None:
    """
    Collect once, then exclude every object alive now from later collections (gc.freeze).

    Call when the process is set up (model built, node created): a full collection then
    only traverses what the loop created, not the hundreds of thousands of startup objects.
    """
    gc.collect()
    gc.freeze()


def keep_freed_memory(heap_bytes: int = 64 << 20) -> None:
    """Keep up to ``heap_bytes`` [B] of freed memory in the heap (glibc ``mallopt``)."""
    name = ctypes.util.find_library('c')
    if name is None:
        return
    try:
        libc = ctypes.CDLL(name)
        libc.mallopt(_M_TRIM_THRESHOLD, heap_bytes)
        libc.mallopt(_M_MMAP_THRESHOLD, heap_bytes)
    except (OSError, AttributeError):  # not glibc (musl, macOS): nothing to tune
        pass
