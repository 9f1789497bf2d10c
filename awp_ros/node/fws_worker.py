"""
Compute the node's FWS in a worker process, off the joint-state loop (``fws_lag_s`` > 0).

The FWS costs ~4 ms here (its H-rep, directional and Euclidean margins; ``awp_bench``
``fws_ms`` + ``fws_directional_ms`` + ``fws_margin_step_ms``), more on slower machines:
computed in the loop it stalls the stream by that much at every FWS. With ``fws_lag_s`` > 0
the pipeline (:class:`awp_ros.ros.pipeline.Pipeline`) hands each FWS job (the arguments of
:func:`awp_ros.evaluation.evaluator.compute_fws`: feet [m], friction-bounded force polytopes
[N], the wrench [N, N.m], tolerances) to :class:`FwsWorker`, which pickles it to a process of
its own (``python -m awp_ros.node.fws_worker``, a fresh interpreter with one BLAS thread, no
fork of a process running DDS threads) and returns a handle; the pipeline asks the handle for
the answer ``fws_lag_s`` of stamps later and waits there if the worker is late. The answer is
the same as computed in the node (same function, same arguments, floats pickled exactly), so
the reports depend on stamps only and equal the replay's.

A worker that died or failed a job is reported through ``on_error`` and that job computed in
the node instead (:meth:`FwsHandle.result`); later jobs are then computed in the node. A worker
still starting (~1 s: imports and its warm-up, before its first answer) is not waited for: a
job due then is computed in the node, with the same numbers; it is sent one job meanwhile, and
at most :data:`MAX_IN_FLIGHT` unanswered ones later, so that sending never blocks the node.
Nor is a worker that is late: the pipeline gives it ``fws_lag_s`` of wall time from the
submission plus :data:`awp_ros.ros.pipeline.FWS_LATE_GRACE_S`, then computes the job in the
node (same numbers; counted in :attr:`FwsWorker.late`, not an error). The worker runs at a
lower priority than the node and, with ``main_thread_cpu``, on the other CPUs, where the
processes feeding the node run too: waiting for it without a bound would leave the node's own
CPU idle while the worker is not scheduled.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, TimeoutError as FutureTimeout
import pickle
import signal
import subprocess
import sys
import threading

from awp_ros.evaluation.evaluator import compute_fws, warm_up
from awp_ros.node.marker_worker import _read, _write, end_process, serve, yield_to_node

__all__ = ['FwsHandle', 'FwsRunner', 'FwsWorker', 'MAX_IN_FLIGHT']

#: Longest wait for one answer [s] before it is computed in the node (when the caller gives
#: no deadline; the pipeline gives one: :data:`awp_ros.ros.pipeline.FWS_LATE_GRACE_S`).
ANSWER_TIMEOUT_S = 10.0

#: Jobs sent to the worker and not yet answered, at most; one while it has answered none (it
#: is starting). A job beyond is computed in the node (:meth:`FwsHandle.result`, the same
#: numbers). A job is a few kB pickled, so these never fill the pipe to the worker (64 kB on
#: Linux), whose write would block the joint-state thread until the worker reads: the 17th
#: job sent at once to a worker still starting waited ~1 s in its write.
MAX_IN_FLIGHT = 8


class FwsHandle:
    """One submitted job: :meth:`result` returns its answer (from the worker, else computed)."""

    def __init__(self, job: tuple, future: Future | None,
                 on_error: Callable[[str], None],
                 ready: Callable[[], bool] = lambda: True,
                 on_late: Callable[[], None] = lambda: None) -> None:
        self._job, self._future, self._on_error = job, future, on_error
        self._ready, self._on_late = ready, on_late
        self._part = None

    def cancel(self) -> None:
        """Forget the job (its answer, when it comes, is dropped)."""
        self._job = self._future = None

    def result(self, timeout: float | None = None) -> tuple:
        """
        Return ``compute_fws(*job)``: the worker's answer, or computed here.

        Computed here when the worker failed, when it is still starting (it has answered
        no job yet: ~1 s after it was started) and this answer is not in, and when the answer
        is not in within ``timeout`` [s] (None: :data:`ANSWER_TIMEOUT_S`, then a failure):
        the same numbers, sooner than the worker.
        """
        if self._part is not None:
            return self._part
        if self._future is not None and (self._future.done() or self._ready()):
            try:
                self._part = self._future.result(ANSWER_TIMEOUT_S if timeout is None
                                                 else max(timeout, 0.0))
                return self._part
            except FutureTimeout:
                if timeout is None:
                    self._on_error(f'FWS worker: no answer in {ANSWER_TIMEOUT_S:g} s; '
                                   'computed in the node')
                else:           # late, not failed: its answer, when it comes, is dropped
                    self._on_late()
            except Exception as exc:  # noqa: BLE001 -- any failure: compute it here
                self._on_error(f'FWS worker: {type(exc).__name__}: {exc}; computed in the '
                               'node')
        self._part = compute_fws(*self._job)
        return self._part


class FwsWorker:
    """
    A process computing FWS jobs in order, and the thread reading its answers.

    :param on_error: called with the reason of a failed job or a dead worker.
    """

    def __init__(self, on_error: Callable[[str], None]) -> None:
        self._process = subprocess.Popen([sys.executable, '-m', 'awp_ros.node.fws_worker'],
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        yield_to_node(self._process.pid)
        self._on_error = on_error
        self._lock = threading.Lock()
        self._futures: deque[Future] = deque()
        self._broken = False
        self._answered = 0
        #: Jobs whose answer was late (not in by the caller's deadline): computed in the node.
        self.late = 0
        self._reader = threading.Thread(target=self._read, name='awp_fws_reader', daemon=True)
        self._reader.start()

    @property
    def alive(self) -> bool:
        """Return whether the worker process runs and answers."""
        return not self._broken and self._process.poll() is None

    @property
    def pid(self) -> int:
        """Return the worker's process id."""
        return self._process.pid

    def submit(self, job: tuple) -> FwsHandle:
        """Send ``job`` to the worker; the handle computes it here if the worker cannot."""
        if not self.alive:
            return FwsHandle(job, None, self._on_error)
        future: Future = Future()
        with self._lock:
            if len(self._futures) >= (MAX_IN_FLIGHT if self._answered else 1):
                return FwsHandle(job, None, self._on_error)       # computed in the node
            try:
                self._futures.append(future)
                _write(self._process.stdin, job)
            except (BrokenPipeError, OSError, ValueError, pickle.PicklingError) as exc:
                self._futures.remove(future)
                self._fail(f'FWS worker: sending a job failed ({type(exc).__name__}: {exc})')
                return FwsHandle(job, None, self._on_error)
        return FwsHandle(job, future, self._on_error, lambda: self._answered > 0,
                         self._count_late)

    def _count_late(self) -> None:
        self.late += 1

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the worker (after the job it is on) and the reader."""
        with self._lock:
            self._broken = True
        end_process(self._process, timeout_s)
        self._reader.join(timeout_s)

    def _fail(self, reason: str) -> None:
        """Mark the worker broken and fail the jobs it still owes (they compute here)."""
        if not self._broken:
            self._broken = True
            self._on_error(reason)
        while self._futures:
            self._futures.popleft().set_exception(RuntimeError(reason))

    def _read(self) -> None:
        while True:
            try:
                ok, payload = _read(self._process.stdout)
            except (EOFError, OSError, pickle.UnpicklingError):     # the worker is gone
                with self._lock:
                    if self._futures or not self._broken:
                        self._fail(f'FWS worker process ended (exit code '
                                   f'{self._process.poll()}); computing the FWS in the node')
                return
            with self._lock:
                future = self._futures.popleft() if self._futures else None
            self._answered += 1
            if future is None:
                continue
            if ok:
                future.set_result(payload)
            else:
                future.set_exception(RuntimeError(payload))


class FwsRunner:
    """
    The node's :attr:`~awp_ros.ros.pipeline.Pipeline.fws_runner`: a worker started on first use.

    A worker that died is not restarted (its jobs and later ones are computed in the node;
    the reason went to ``on_error`` and ``/diagnostics``).

    :param on_error: called with the reason of a failed job or a dead worker.
    """

    def __init__(self, on_error: Callable[[str], None]) -> None:
        self._on_error = on_error
        self.worker: FwsWorker | None = None

    def start(self) -> None:
        """Start the worker unless it runs."""
        if self.worker is None:
            self.worker = FwsWorker(self._on_error)

    def submit(self, job: tuple) -> FwsHandle:
        """Send ``job`` to the worker (started now if it is the first)."""
        self.start()
        return self.worker.submit(job)

    def close(self) -> None:
        """Stop the worker, if one was started."""
        if self.worker is not None:
            self.worker.close()


def main() -> int:
    """Worker process: answer each job with ``(True, compute_fws(*job))`` until stdin ends."""
    from awp_ros.runtime import tune_process
    signal.signal(signal.SIGINT, signal.SIG_IGN)     # Ctrl-C is the node's; it closes us
    tune_process()      # one BLAS thread: idle OpenBLAS threads spin on the node's cores
    warm_up('hyq')      # the kernels (robot-independent), loaded before the first job
    return serve(lambda job: compute_fws(*job))


if __name__ == '__main__':
    sys.exit(main())
