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

And one that a node asks for (its ``main_thread_cpu`` parameter): :func:`pin_thread` keeps
the thread that answers the joint states on one CPU, its caches its own, and
:func:`worker_cpus` gives the processes it starts afterwards the other CPUs.

Library code never calls this: it changes the whole process.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os

__all__ = ['children', 'freeze_startup_objects', 'keep_freed_memory', 'limit_blas_threads',
           'pin_thread', 'tune_process', 'worker_cpus']

#: (the CPU the main thread was pinned to, the CPUs the process had before), once pinned.
_PINNED: tuple[int, frozenset[int]] | None = None

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


def children(pid: int) -> dict[int, str]:
    """
    Return the child processes of ``pid``: process id -> name.

    From ``/proc/<pid>/task/*/children``; the name is the module of a ``python -m <module>``
    child (e.g. ``awp_ros.node.fws_worker``), else its command.
    """
    out = {}
    try:
        tasks = os.listdir(f'/proc/{pid}/task')
    except OSError:
        return out
    for task in tasks:
        try:
            with open(f'/proc/{pid}/task/{task}/children') as f:
                pids = [int(c) for c in f.read().split()]
        except OSError:
            continue
        for child in pids:
            try:
                with open(f'/proc/{child}/cmdline') as f:
                    argv = f.read().split('\0')
            except OSError:
                continue
            out[child] = argv[argv.index('-m') + 1] if '-m' in argv[:-1] else argv[0]
    return out


def pin_thread(cpu: int) -> frozenset[int]:
    """
    Run the calling thread on CPU ``cpu`` only (Linux ``sched_setaffinity`` of the thread).

    Threads it starts afterwards inherit that CPU; threads started before it (Fast DDS's)
    keep every CPU, and the child processes (the workers it started before, and those
    started afterwards through :func:`worker_cpus`) get the others.

    :return: the CPUs the thread could run on before.
    :raises ValueError: ``cpu`` is not one of them.
    :raises OSError: not supported here (not Linux) or not permitted.
    """
    global _PINNED
    if not hasattr(os, 'sched_setaffinity'):
        raise OSError('CPU affinity is not supported on this platform')
    allowed = frozenset(os.sched_getaffinity(0))
    if cpu not in allowed:
        raise ValueError(f'CPU {cpu} is not one this process may run on: '
                         f'{sorted(allowed)}')
    os.sched_setaffinity(0, {cpu})
    _PINNED = (cpu, allowed)
    others = worker_cpus()
    for child in children(os.getpid()):
        try:
            os.sched_setaffinity(child, others)
        except OSError:                   # gone meanwhile
            pass
    return allowed


def worker_cpus() -> frozenset[int] | None:
    """
    Return the CPUs for a worker process started now, None when no thread is pinned.

    Those the process had before :func:`pin_thread` but the pinned one (all of them when it
    had only that one); None: the worker inherits the process's CPUs.
    """
    if _PINNED is None:
        return None
    cpu, allowed = _PINNED
    return allowed - {cpu} or allowed
