"""
Build the node's RViz markers in a worker process, off the joint-state loop.

A MarkerArray costs ~3 ms to build (triangulated leg polytopes, the FWP force slice by a
halfspace intersection, a few hundred ``geometry_msgs/Point`` objects): at 30 Hz a tenth of
the core that must answer 1 kHz joint states. :class:`MarkerWorker` hands the job (the
arguments of :func:`awp_ros.ros.markers.build_markers`, pickled) to a process of its own
(``python -m awp_ros.node.marker_worker``: a fresh interpreter, no fork of a process running DDS
threads, nothing of the parent's ``__main__`` re-run), which builds the same MarkerArray and
returns it serialized, over its stdin and stdout (length-prefixed pickles); a thread of the
node publishes the bytes as they come (``Publisher.publish`` takes serialized messages). The
markers are the same as built in-process (same function, same arguments); only their
publication comes a few ms later.

At most ``max_pending`` jobs wait: a job beyond them is refused (:meth:`submit` returns
False) and the node counts it as skipped. A failed job is passed to ``on_error`` with its
reason; a worker that died makes :attr:`alive` false and the node builds markers itself.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
from typing import BinaryIO

from awp_ros.runtime import worker_cpus

__all__ = ['MarkerJob', 'MarkerWorker', 'NICE', 'serve', 'yield_to_node']

#: ``(function, args, kwargs)``: ``function(*args, **kwargs)`` returns the MarkerArray.
MarkerJob = tuple

_LENGTH = struct.Struct('<Q')

#: Niceness the worker processes add to themselves (:func:`yield_to_node`).
NICE = 10


def yield_to_node(pid: int) -> None:
    """
    Lower a worker process's CPU priority to the node's plus :data:`NICE` (``setpriority``).

    The workers (markers, FWS) run in the node's session, so the scheduler weighs them
    against the node: at +10 a worker busy for a whole FWS (~4 ms), or importing at
    startup, no longer delays joint states queued behind it on two shared cores, and it
    still gets every idle cycle. When the node's main thread is pinned to a CPU
    (``main_thread_cpu``), the worker gets the other CPUs (:func:`~awp_ros.runtime.worker_cpus`),
    not the pinned one it would inherit. Called by the node right after the worker started
    (its threads, created later, inherit both); a no-op where not available or permitted.
    """
    try:
        nice = min(os.getpriority(os.PRIO_PROCESS, 0) + NICE, 19)
        os.setpriority(os.PRIO_PROCESS, pid, nice)
    except (AttributeError, OSError):    # no setpriority, or the worker is gone: as before
        pass
    cpus = worker_cpus()
    if cpus is not None:
        try:
            os.sched_setaffinity(pid, cpus)
        except OSError:                   # the worker is gone
            pass


class MarkerWorker:
    """
    A process building MarkerArrays, and the threads feeding it and publishing them.

    :param publish: called with each serialized MarkerArray (``bytes``), from a thread.
    :param on_error: called with the reason of a job that failed, from a thread.
    :param max_pending: jobs that may wait for the worker.
    :param fallback: called, from a thread, with each job the worker took but will never
        answer because it died (those in its pipe or on its hands, and those queued after):
        the node builds them itself, so that no due marker is lost unseen. None: dropped.
    """

    def __init__(self, publish: Callable[[bytes], None], on_error: Callable[[str], None], *,
                 max_pending: int = 2,
                 fallback: Callable[[MarkerJob], None] | None = None) -> None:
        self._process = subprocess.Popen([sys.executable, '-m', 'awp_ros.node.marker_worker'],
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        yield_to_node(self._process.pid)
        self._pending = threading.BoundedSemaphore(max_pending)
        self._jobs: queue.SimpleQueue = queue.SimpleQueue()
        self._publish, self._on_error, self._fallback = publish, on_error, fallback
        self._in_flight: deque = deque()     # jobs written to the worker, not yet answered
        self._lock = threading.Lock()
        self._broken = False
        self._closed = False
        self._threads = [threading.Thread(target=target, name=name, daemon=True)
                         for target, name in ((self._send, 'awp_marker_sender'),
                                              (self._read, 'awp_marker_reader'))]
        for thread in self._threads:
            thread.start()

    @property
    def alive(self) -> bool:
        """Return whether the worker process runs."""
        return self._process.poll() is None

    @property
    def pid(self) -> int:
        """Return the worker's process id."""
        return self._process.pid

    def submit(self, job: MarkerJob) -> bool:
        """Queue a job; return False (not queued) when ``max_pending`` jobs already wait."""
        if not self._pending.acquire(blocking=False):
            return False
        self._jobs.put(job)
        return True

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the worker (after the job it is on) and the threads."""
        if self._closed:
            return
        self._closed = True
        self._jobs.put(None)
        try:
            self._process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait(timeout_s)
        for thread in self._threads:
            thread.join(timeout_s)

    def _send(self) -> None:
        stream = self._process.stdin
        while True:
            job = self._jobs.get()
            if job is None:
                try:
                    stream.close()
                except (BrokenPipeError, OSError, ValueError):
                    pass
                return
            with self._lock:
                broken = self._broken
                if not broken:
                    self._in_flight.append(job)
            if broken:                               # the worker is gone: built elsewhere
                self._lost([job])
                continue
            try:
                _write(stream, job)
            except (BrokenPipeError, OSError, ValueError):     # the worker is gone
                self._worker_gone()
            except Exception as exc:  # noqa: BLE001 -- a job that cannot be pickled
                with self._lock:
                    self._in_flight.remove(job)
                self._pending.release()
                self._on_error(f'markers: {type(exc).__name__}: {exc}')

    def _worker_gone(self) -> None:
        """Hand every job the dead worker will not answer to the fallback (once)."""
        with self._lock:
            if self._broken:
                return
            self._broken = True
            lost = list(self._in_flight)
            self._in_flight.clear()
        self._lost(lost)

    def _lost(self, jobs: list) -> None:
        for job in jobs:
            self._pending.release()
            if self._fallback is not None:
                try:
                    self._fallback(job)
                except Exception as exc:  # noqa: BLE001 -- reported, the thread goes on
                    self._on_error(f'markers: {type(exc).__name__}: {exc}')

    def _read(self) -> None:
        while True:
            try:
                ok, payload = _read(self._process.stdout)
            except (EOFError, OSError, pickle.UnpicklingError):   # the worker is gone
                self._worker_gone()
                return
            with self._lock:
                if self._in_flight:
                    self._in_flight.popleft()
            self._pending.release()
            try:
                if ok:
                    self._publish(payload)
                else:
                    self._on_error(payload)
            except Exception as exc:  # noqa: BLE001 -- a publish failure must not end the reader
                self._on_error(f'publishing markers failed: {type(exc).__name__}: {exc}')


def end_process(process: subprocess.Popen, timeout_s: float) -> None:
    """End a worker process: close its stdin (its end of input), wait, kill it if it lingers."""
    try:
        process.stdin.close()
    except OSError:
        pass
    try:
        process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(timeout_s)


def _write(stream: BinaryIO, obj) -> None:
    """Write one length-prefixed pickle."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_LENGTH.pack(len(data)) + data)
    stream.flush()


def _read(stream: BinaryIO):
    """Read one length-prefixed pickle; raise EOFError at the end of the stream."""
    return pickle.loads(_read_frame(stream))


def _read_frame(stream: BinaryIO) -> bytes:
    """Read one length-prefixed frame; raise EOFError at the end of the stream."""
    head = stream.read(_LENGTH.size)
    if len(head) < _LENGTH.size:
        raise EOFError
    (size,) = _LENGTH.unpack(head)
    data = stream.read(size)
    if len(data) < size:
        raise EOFError
    return data


def serve(answer: Callable[[object], object], prefix: str = '', *,
          stdout: BinaryIO | None = None) -> int:
    """
    Worker loop: answer each job read from stdin until stdin ends; return the exit code.

    Each job is a length-prefixed pickle; its answer, written to ``stdout`` (default
    ``sys.stdout``) the same way, is ``(True, answer(job))`` or ``(False, prefix + reason)``
    when ``answer`` raised (the worker goes on).
    """
    stdin = sys.stdin.buffer
    stdout = sys.stdout.buffer if stdout is None else stdout
    while True:
        try:
            frame = _read_frame(stdin)
        except EOFError:
            return 0
        try:
            out = (True, answer(pickle.loads(frame)))
        except Exception as exc:  # noqa: BLE001 -- reported to the node, the worker goes on
            out = (False, f'{prefix}{type(exc).__name__}: {exc}')
        try:
            _write(stdout, out)
        except (BrokenPipeError, OSError):
            return 0


def main() -> int:
    """Worker process: build and serialize each job's MarkerArray until stdin ends."""
    from rclpy.serialization import serialize_message
    signal.signal(signal.SIGINT, signal.SIG_IGN)     # Ctrl-C is the node's; it closes us
    return serve(lambda job: serialize_message(job[0](*job[1], **job[2])), 'markers: ')


if __name__ == '__main__':
    sys.exit(main())
