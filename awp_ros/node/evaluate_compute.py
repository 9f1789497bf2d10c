"""
The computation of ``~/evaluate`` queries: a process the node pauses while it works.

The query worker (:mod:`awp_ros.node.evaluate_service`) receives a request over DDS and hands
it, serialized, to this process (``python -m awp_ros.node.evaluate_compute``, started by the
worker), which evaluates it (:func:`~awp_ros.node.evaluate_service.evaluate_request`) at the
lowest CPU priority (``SCHED_IDLE``, else ``nice`` +10) and returns the serialized response.
It has no DDS participant and shares no lock with the node, so the node can stop it for as
long as it handles a joint state (:class:`~awp_ros.node.yield_gate.YieldGate`, whose page
``--gate`` names): while a query is evaluated the node's joint-state loop runs with the
other core free for the threads it wakes, as if no query ran.

Jobs (length-prefixed pickles on stdin, answers likewise on a copy of stdout, see
:func:`awp_ros.node.marker_worker.serve`): ``('policy',)`` (answer: the CPU policy it runs
at); ``('config', RobotConfig | None, PipelineParams,
error)`` builds the evaluator (answer: the error, '' when built); ``('request', bytes)``
evaluates a serialized ``Evaluate.Request`` (answer: the serialized ``Evaluate.Response``).
"""

from __future__ import annotations

import argparse
from contextlib import nullcontext
import os
import signal
import subprocess
import sys
import threading

from awp_ros.errors import AwpError, ProcessError
from awp_ros.node.marker_worker import _read, _write, end_process, serve
from awp_ros.robot.config import RobotConfig
from awp_ros.robot.parameters import PipelineParams

__all__ = ['Computation', 'main']


class Computation:
    """
    The worker's handle on its computation process (module docstring).

    :param gate: the path of the node's :class:`~awp_ros.node.yield_gate.YieldGate` page,
        '' for none (the process is then never paused).
    """

    def __init__(self, gate: str = '') -> None:
        command = [sys.executable, '-m', 'awp_ros.node.evaluate_compute']
        if gate:
            command += ['--gate', gate]
        self._process = subprocess.Popen(command, stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE)
        self._lock = threading.Lock()
        #: The CPU policy the process evaluates at (``'SCHED_IDLE'``, ``'nice +10'``, '').
        self.policy = self._call(('policy',))

    @property
    def pid(self) -> int:
        """Return the process id."""
        return self._process.pid

    def _call(self, job: tuple):
        try:
            with self._lock:        # one job at a time, answered in order
                _write(self._process.stdin, job)
                ok, answer = _read(self._process.stdout)
        except (EOFError, OSError, ValueError) as exc:
            code = self._process.poll()
            raise ProcessError(f'the query computation process ended (exit {code}): '
                               f'{type(exc).__name__}: {exc}') from exc
        if not ok:
            raise ProcessError(answer)
        return answer

    def configure(self, config: RobotConfig | None, params: PipelineParams,
                  error: str) -> str:
        """Build the evaluator of ``config`` there; return why there is none ('' if built)."""
        return self._call(('config', config, params, error))

    def evaluate(self, request: bytes) -> bytes:
        """Return the serialized response to a serialized ``Evaluate.Request``."""
        return self._call(('request', request))

    def close(self, timeout_s: float = 2.0) -> None:
        """End the process (it ends at the end of its stdin)."""
        end_process(self._process, timeout_s)


class _Evaluator:
    """The process's side: the evaluator of the latest config and the answer to each job."""

    def __init__(self, gate, policy: str) -> None:
        self._gate, self._policy = gate, policy
        self._current: tuple = (None, PipelineParams(), 'no robot config received yet')

    def answer(self, job: tuple):
        if job[0] == 'policy':
            return self._policy
        if job[0] == 'config':
            _, config, params, error = job
            evaluator = None
            if config is not None:
                from awp_ros.evaluation.evaluator import FeasibilityEvaluator
                try:
                    evaluator = FeasibilityEvaluator(config)
                    evaluator.hull_tol = max(params.hull_tolerance, evaluator.feasibility_tol)
                    error = ''
                except (AwpError, ValueError) as exc:
                    evaluator, error = None, f'no robot model: {exc}'
            self._current = (evaluator, params, error)
            return error
        from awp_ros_msgs.srv import Evaluate
        from rclpy.serialization import deserialize_message, serialize_message

        from awp_ros.node.evaluate_service import evaluate_request
        evaluator, params, error = self._current
        with self._gate.busy() if self._gate is not None else nullcontext():
            request = deserialize_message(job[1], Evaluate.Request)
            return serialize_message(evaluate_request(evaluator, params, request,
                                                      error=error))


def main(argv: list[str] | None = None) -> int:
    """Run the computation process: answer jobs until stdin ends."""
    parser = argparse.ArgumentParser(prog='python -m awp_ros.node.evaluate_compute')
    parser.add_argument('--gate', default='', help="the node's YieldGate page ('' = none)")
    args = parser.parse_args(argv)
    signal.signal(signal.SIGINT, signal.SIG_IGN)       # Ctrl-C is the node's
    from awp_ros.node.evaluate_service import lower_thread_priority
    from awp_ros.node.yield_gate import YieldGate
    from awp_ros.runtime import tune_process
    tune_process()      # one BLAS thread
    policy = lower_thread_priority()   # the process has one thread: all of it
    try:
        gate = YieldGate.attach(args.gate) if args.gate else None
    except FileNotFoundError:
        # The node closes (unlinks) its page when it stops: stopped before this process
        # was up, it has no job for it.
        print(f'~/evaluate: the node closed its gate {args.gate}: exiting', file=sys.stderr)
        return 0
    # Answers go through a copy of fd 1; what a library prints goes to stderr.
    out = os.fdopen(os.dup(1), 'wb')
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    return serve(_Evaluator(gate, policy).answer, '~/evaluate: ', stdout=out)


if __name__ == '__main__':
    sys.exit(main())
