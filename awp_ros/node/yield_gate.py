"""
A gate by which the node stops a worker's computation while it answers joint states.

Work at the lowest CPU priority (``SCHED_IDLE``) on the other core still delays the node on a
2-core machine: it shares the caches and memory bus with the joint-state loop, and the
threads the loop wakes (DDS receive threads, the driver, the subscribers) compete with it for
the core. So the query service's computation runs in a process that holds nothing the node
could wait for (no DDS participant, no lock shared with the node:
:mod:`awp_ros.node.evaluate_compute`), and the node stops it (``SIGSTOP``) when it takes a
joint state and continues it (``SIGCONT``) when its input queue is empty again: one stop per
busy stretch of the node, so that a node working through a backlog does not pay a
stop/continue per joint state (per joint state, ~50 us each and the node at 500 Hz near
saturation on this machine, the queries took 8-35 s and the stream fell behind). Only while the
process is busy: it raises a flag in a page shared with the node when it starts a piece of
work and lowers it when done, so an idle worker costs the node one memory read per joint
state.

The page is a file of :data:`SIZE` bytes (in ``/dev/shm`` where it exists) created by the
node (:meth:`YieldGate.create`) and mapped by the worker (:meth:`YieldGate.attach`): int32
slots ``[pid, busy]``. A stop is always followed by a continue (the node's handler continues
in a ``finally``), and a process stopped by the gate is continued by :meth:`close`.
"""

from __future__ import annotations

from contextlib import contextmanager
import mmap
import os
import signal
import tempfile

__all__ = ['SIZE', 'YieldGate']

#: Bytes of the shared page: int32 ``pid`` and ``busy``.
SIZE = 8


class YieldGate:
    """
    The shared page of one worker computation (module docstring).

    :param path: the page's file.
    :param owner: True in the node (it unlinks the file on :meth:`close`).
    """

    def __init__(self, path: str, *, owner: bool = False) -> None:
        self.path = path
        self._owner = owner
        fd = os.open(path, os.O_RDWR)
        try:
            self._map = mmap.mmap(fd, SIZE)
        finally:
            os.close(fd)
        self._slots = memoryview(self._map).cast('i')
        self._stopped = 0
        #: Stops made (busy stretches of the node that met a busy worker).
        self.pauses = 0

    @classmethod
    def create(cls) -> YieldGate:
        """Create a page (the node's side): no process, not busy."""
        folder = '/dev/shm' if os.path.isdir('/dev/shm') else None
        fd, path = tempfile.mkstemp(prefix='awp_gate_', dir=folder)
        try:
            os.write(fd, bytes(SIZE))
        finally:
            os.close(fd)
        return cls(path, owner=True)

    @classmethod
    def attach(cls, path: str) -> YieldGate:
        """Map the node's page (the worker's side) and register the calling process."""
        gate = cls(path)
        gate._slots[0] = os.getpid()
        return gate

    # -- the worker's side ------------------------------------------------------------------

    @contextmanager
    def busy(self):
        """Mark the calling process busy for the block: the node pauses it meanwhile."""
        self._slots[1] = 1
        try:
            yield
        finally:
            self._slots[1] = 0

    # -- the node's side --------------------------------------------------------------------

    def pause(self) -> None:
        """Stop the worker's process if it is busy and not stopped already (else a no-op)."""
        if self._slots[1] and not self._stopped:
            pid = self._slots[0]
            if pid > 0:
                try:
                    os.kill(pid, signal.SIGSTOP)
                except OSError:         # gone (the service restarts it)
                    return
                self._stopped = pid
                self.pauses += 1

    def resume(self) -> None:
        """Continue the process :meth:`pause` stopped."""
        pid, self._stopped = self._stopped, 0
        if pid:
            try:
                os.kill(pid, signal.SIGCONT)
            except OSError:
                pass

    def close(self) -> None:
        """Continue a stopped worker, unmap the page; the node also removes its file."""
        self.resume()
        self._slots.release()
        self._map.close()
        if self._owner:
            try:
                os.unlink(self.path)
            except OSError:
                pass
