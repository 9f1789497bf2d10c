"""CPU time and resident memory of a process, sampled from ``/proc`` (Linux)."""

from __future__ import annotations

import os
import threading
import time

import numpy as np

from awp_ros.runtime import children

__all__ = ['children', 'ProcessMonitor', 'proc_usage']

_CLK_TCK = os.sysconf('SC_CLK_TCK')


def proc_usage(pid: int) -> tuple[float, int]:
    """
    Return a process's CPU time (user + system) [s] and resident set size [B].

    From ``/proc/<pid>/stat`` (fields 14 and 15, in clock ticks) and the ``VmRSS`` line of
    ``/proc/<pid>/status`` [kB].
    """
    with open(f'/proc/{pid}/stat') as f:
        stat = f.read()
    rest = stat[stat.rindex(')') + 2:].split()   # fields from 3 (state) on
    cpu = (int(rest[11]) + int(rest[12])) / _CLK_TCK
    rss = 0
    with open(f'/proc/{pid}/status') as f:
        for line in f:
            if line.startswith('VmRSS:'):
                rss = int(line.split()[1]) * 1024
                break
    return cpu, rss


class ProcessMonitor:
    """
    Sample a process's CPU time and RSS every ``period_s`` in a background thread.

    ``samples`` rows: (wall time [s, time.monotonic], CPU time [s], RSS [B]).
    ``child_samples``: for each child process (its workers), name -> rows (wall time [s],
    CPU time [s]); a child that ends keeps its rows.
    """

    def __init__(self, pid: int, period_s: float = 1.0) -> None:
        self.pid = pid
        self.period_s = period_s
        self.samples: list[tuple[float, float, int]] = []
        self.child_samples: dict[str, list[tuple[float, float]]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                cpu, rss = proc_usage(self.pid)
            except (OSError, ValueError, IndexError):     # the process ended
                return
            now = time.monotonic()
            self.samples.append((now, cpu, rss))
            for child, name in children(self.pid).items():
                try:
                    child_cpu = proc_usage(child)[0]
                except (OSError, ValueError, IndexError):
                    continue
                self.child_samples.setdefault(f'{name} (pid {child})', []).append(
                    (now, child_cpu))
            self._stop.wait(self.period_s)

    def stop(self) -> None:
        """Stop sampling."""
        self._stop.set()
        self._thread.join(timeout=5)

    def array(self) -> np.ndarray:
        """Return the samples as an (n, 3) array."""
        return np.array(self.samples, dtype=float).reshape(-1, 3)
