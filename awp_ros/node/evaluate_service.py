"""
The query service ``~/evaluate`` of ``awp_node`` (``awp_ros_msgs/srv/Evaluate``), off the stream.

A planner sends candidate states (joint states, contacts, IMU readings, optionally the wrenches
it intends) and gets one ``FeasibilityReport`` per joint state, and with ``include_polytopes``
the FWP and FWS of each. The answer must not delay the live stream (one report per joint
state at up to 1 kHz), and it would if the node evaluated the request: 100 states cost
~1 s (the FWS of each, ~10 ms), and a Python thread of the node doing it would hold the GIL
against the joint-state loop (a thread that waits for the GIL waits up to the switch
interval, 5 ms). So the service is served by a **worker process** (``python -m
awp_ros.node.evaluate_service``: a fresh interpreter, its own DDS participant, a hidden
node ``_<node>_evaluate`` in the node's namespace) that advertises the node's resolved
service name (``/awp_node/evaluate`` by default; remapped and namespaced like the node's
``~/evaluate``). The node process does nothing per query: it only sends the worker its
robot config and pipeline parameters at startup and after every accepted parameter change
(length-prefixed pickles over the worker's stdin). The worker does not evaluate either: it
hands each request, serialized, to its own child process, the query computation
(:mod:`awp_ros.node.evaluate_compute`), which evaluates at the ``SCHED_IDLE`` policy (Linux;
else ``nice`` +:data:`NICE`, :func:`lower_thread_priority`) and holds no DDS participant, so
that the node can stop it while it answers joint states (``evaluate_yield``,
:mod:`awp_ros.node.yield_gate`): a query then never competes with the stream for the cores and
caches, it waits while the node is busy. The worker's own DDS threads and the executor thread
that receives the request and sends the response keep the normal policy: with the whole
worker at ``SCHED_IDLE`` (as before commit 5a65fdb) its DDS threads starved while the node and
the stream kept the cores busy, and the node's reports were late by ~300 ms (p50) for as long
as a query ran. The worker shares the node's *session* (in a process group of its own):
Linux's autogroup scheduling makes each session a task group with a fair share of the CPU
against the others, whatever the policies of its threads, so a worker in a session of its own
took a core from the node like a normal process (reports during a query +50-70 ms late at the
median, against +0.6-1.2 ms in the node's session; README, *Beside the live stream*).

Semantics of a request (:func:`evaluate_request`), the live pipeline's for each state with
these differences: every state stands alone (no stamps are compared, no history: the motion
of a state is what its own messages give), and it is strict about joint names:

- ``joint_states[i]``: ``name`` and ``position`` of every joint of the model [rad],
  ``velocity`` [rad/s] (used when ``use_joint_velocities``), ``effort`` [N.m] (measured
  contact forces, when ``use_joint_efforts``); a name the model does not have is an error
  (``STATUS_INVALID_INPUT`` naming it), not ignored as in the live stream (an arm's joints);
- ``contacts``: ``contacts[i]`` (one per joint state) or ``contacts[0]`` for all; stance from
  ``in_contact``, normals (world-aligned axes) and friction coefficients as in the stream
  (empty = the configured ``contact_normal`` / ``friction_coefficient``); no contacts at
  all: with ``contact_source`` ``effort`` the feet whose measured normal force (from the joint
  state's efforts) is above ``contact_force_on_n`` (a query has no past: every foot starts in
  swing), else every foot, each with the configured normal and coefficient;
- ``imu``: ``imu[i]`` or ``imu[0]`` for all, empty = none: the base orientation (through the
  IMU's mounting, frame ``header.frame_id``, '' = the root link) whenever given, and with
  ``motion`` measured (:attr:`PipelineParams.measured_motion`) its angular velocity and
  specific force (classical base acceleration). Derivatives that need a history (joint and
  base angular accelerations) are zero: a query has no past;
- ``wrenches``: ``wrenches[i]`` or ``wrenches[0]`` for all [N, N.m] (force, moment about the
  CoM, world-aligned axes): the margins are those of this wrench instead of the state's;
- the reports are the live ones (``header.stamp`` = the joint state's, ``frame_id``
  ``wrench_frame_id``, ``fws_stamp`` = the joint state's stamp): the FWS is computed for
  every state; the node's ``hull_tolerance`` applies;
- an array whose length is neither 0, 1 nor ``len(joint_states)`` makes every report
  ``STATUS_INVALID_INPUT`` with the reason; without a robot model every report is
  ``STATUS_ERROR`` with the node's reason;
- with ``include_polytopes``, ``fwp[i]`` and ``fws[i]`` answer ``joint_states[i]``
  (``WrenchPolytope``, CoM-centred world-aligned axes, ``reference_point`` the CoM in the
  base frame [m]); for a state that was not evaluated both are the empty set (dimension -1).

Queries are answered one at a time, in arrival order. A worker that dies is restarted (at
most :data:`MAX_RESTARTS` times, each logged and counted as an output failure of the node).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
import os
import pickle
import select
import signal
import subprocess
import sys
import threading
import time

from awp_ros_msgs.msg import FeasibilityReport, WrenchPolytope
from awp_ros_msgs.srv import Evaluate
import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header

from awp_ros.errors import AwpError, ConfigError, InputError, ProcessError
from awp_ros.estimation.motion import fill_motion, MotionEstimator
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.geometry.linalg import quaternion_matrix
from awp_ros.geometry.polytope import Polytope
from awp_ros.node.evaluate_compute import Computation
from awp_ros.node.marker_worker import _LENGTH, _read, _write, end_process, NICE
from awp_ros.robot.config import RobotConfig
from awp_ros.robot.parameters import PipelineParams
from awp_ros.ros.contact_source import EffortContacts
from awp_ros.ros.conversions import (report_msg, robot_state_from_msgs, stamp_to_ns,
                                     wrench_polytope_msg)
from awp_ros.ros.pipeline import shorten_reason, unevaluated_report
from awp_ros.runtime import tune_process

__all__ = ['EvaluateService', 'MAX_RESTARTS', 'NICE', 'evaluate_request', 'lower_thread_priority',
           'main']

_S = FeasibilityReport

#: Times a worker that ended unexpectedly is restarted.
MAX_RESTARTS = 3
#: Popen arguments of the worker: its own process group in the node's session (Python 3.11+;
#: before, its own session, which autogroup scheduling puts in a group of its own).
_OWN_GROUP = {'process_group': 0} if sys.version_info >= (3, 11) else \
    {'start_new_session': True}


# -- the request ---------------------------------------------------------------------------


def evaluate_request(evaluator: FeasibilityEvaluator | None, params: PipelineParams,
                     request: Evaluate.Request, *, error: str = '') -> Evaluate.Response:
    """
    Return the response to one ``Evaluate`` request (module docstring); never raises.

    :param evaluator: the evaluator of the node's robot config (its ``hull_tol`` set from
        ``params``), None when the node has no robot model.
    :param params: the node's pipeline parameters.
    :param error: why there is no evaluator (the reason of every ``STATUS_ERROR`` report).
    """
    response = Evaluate.Response()
    joints = list(request.joint_states)
    n = len(joints)
    frame = params.wrench_frame_id
    lists = {'contacts': list(request.contacts), 'imu': list(request.imu),
             'wrenches': list(request.wrenches)}
    problems = [f'{name} has {len(items)} entries for {n} joint states (give 0, 1 for all, '
                f'or {n}: one per joint state)'
                for name, items in lists.items() if len(items) not in (0, 1, n)]
    status, reason = (_S.STATUS_INVALID_INPUT, 'request not evaluated: ' + '; '.join(problems)) \
        if problems else (_S.STATUS_ERROR, error or 'no robot model')
    include = bool(request.include_polytopes)
    reports, fwp, fws = [], [], []
    for i, js in enumerate(joints):
        if problems or evaluator is None:
            report, polytopes = unevaluated_report(js, frame, status, reason), None
        else:
            pick = {name: (items[i] if len(items) == n else items[0]) if items else None
                    for name, items in lists.items()}
            report, polytopes = _evaluate_one(evaluator, params, js, pick['contacts'],
                                              pick['imu'], pick['wrenches'], include)
        reports.append(report)
        if include:
            if polytopes is None:
                header = Header(stamp=js.header.stamp, frame_id=frame)
                polytopes = (_empty_polytope(header, 'fwp'), _empty_polytope(header, 'fws'))
            fwp.append(polytopes[0])
            fws.append(polytopes[1])
    response.reports = reports
    response.fwp = fwp
    response.fws = fws
    return response


def _evaluate_one(evaluator: FeasibilityEvaluator, p: PipelineParams, js, contacts, imu,
                  wrench, include: bool) -> tuple[FeasibilityReport, tuple | None]:
    """Return the report of one state and, with ``include``, its FWP and FWS messages."""
    t0 = time.perf_counter()
    header = Header(stamp=js.header.stamp, frame_id=p.wrench_frame_id)
    polytopes = None
    try:
        by_effort = contacts is None and p.contact_source == 'effort'
        state = robot_state_from_msgs(js, contacts, imu, feet=evaluator.feet,
                                      use_velocities=p.use_joint_velocities,
                                      use_efforts=p.use_joint_efforts or by_effort)
        if imu is not None or p.measured_motion:
            _add_motion(evaluator, p, state, stamp_to_ns(js.header.stamp), imu)
        if by_effort:       # a query has no past: each foot starts in swing (touch-down)
            state.stance = EffortContacts(evaluator, on_n=p.contact_force_on_n,
                                          off_n=p.contact_force_off_n).update(state)
            if not p.use_joint_efforts:
                state.joint_efforts = None
        elif contacts is None:
            state.stance = list(evaluator.feet)
        w = None
        if wrench is not None:
            f, t = wrench.force, wrench.torque
            w = np.array([f.x, f.y, f.z, t.x, t.y, t.z], dtype=float)
        # No odometry in a query: a measured twist's linear part is a placeholder zero.
        result = evaluator.evaluate(state, fws=True, wrench=w, base_velocity_known=False)
        warnings = list(result.warnings)
        if not result.stance:
            warnings.append('no foot in contact: every wrench set is {0}, no wrench but zero '
                            'is feasible')
        report = report_msg(header, result, compute_time=0.0, fws_stamp=js.header.stamp,
                            status=_S.STATUS_WARNING if warnings else _S.STATUS_OK,
                            status_message='; '.join(warnings))
        if include:
            R = quaternion_matrix(np.asarray(state.base_orientation, dtype=float))
            ref = R.T @ result.com
            polytopes = tuple(wrench_polytope_msg(header, kind, result.stance, ref,
                                                  getattr(result, kind).polytope)
                              for kind in ('fwp', 'fws'))
    except (InputError, ConfigError) as exc:       # a bad state, e.g. an unknown IMU frame
        report = unevaluated_report(js, p.wrench_frame_id, _S.STATUS_INVALID_INPUT, str(exc))
    except AwpError as exc:
        report = unevaluated_report(js, p.wrench_frame_id, _S.STATUS_ERROR,
                                    f'{type(exc).__name__}: {exc}')
    except Exception as exc:  # noqa: BLE001 -- every state gets its report
        report = unevaluated_report(js, p.wrench_frame_id, _S.STATUS_ERROR,
                                    f'internal error {type(exc).__name__}: {exc}')
    report.status_message = shorten_reason(report.status_message)
    report.compute_time = time.perf_counter() - t0
    return report, polytopes


def _add_motion(evaluator: FeasibilityEvaluator, p: PipelineParams, state, ns: int,
                imu) -> None:
    """
    Fill the orientation (and, measured, the motion) of one state from its own messages.

    A fresh estimator per state, fed the IMU reading and the joint state at the same stamp:
    the derivatives that need a history start at zero. A state lacking joints is left to
    the evaluator, which names them.
    """
    model = evaluator.model
    est = MotionEstimator(model, cutoff_hz=p.acceleration_cutoff_hz)
    if imu is not None:
        est.set_imu_frame(imu.header.frame_id or model.root_link)
        o, w, f = imu.orientation, imu.angular_velocity, imu.linear_acceleration
        est.add_imu(ns, (o.x, o.y, o.z, o.w), (w.x, w.y, w.z), (f.x, f.y, f.z))
    fill_motion(est, ns, state, measured=p.measured_motion)


def _empty_polytope(header: Header, kind: str) -> WrenchPolytope:
    """Return the WrenchPolytope of a state that was not evaluated: the empty set."""
    return wrench_polytope_msg(header, kind, (), np.zeros(3), Polytope.empty(6))


# -- the node's side -----------------------------------------------------------------------


class EvaluateService:
    """
    Serve ``~/evaluate`` from a worker process (module docstring).

    :param service_name: the fully qualified service name (the node's resolved
        ``~/evaluate``).
    :param node_name: the node's name (the worker's hidden node is ``_<node_name>_evaluate``).
    :param namespace: the node's namespace.
    :param on_error: called with the reason when the worker fails (any thread).
    :param on_info: called with a line to log when the worker serves (any thread).
    :param gate: the path of the node's :class:`~awp_ros.node.yield_gate.YieldGate` page by
        which it pauses the query computation while it handles a joint state ('' = none).
    """

    def __init__(self, service_name: str, node_name: str, namespace: str,
                 on_error: Callable[[str], None],
                 on_info: Callable[[str], None] = lambda line: None, *,
                 gate: str = '') -> None:
        self.service_name = service_name
        self._command = [sys.executable, '-m', 'awp_ros.node.evaluate_service', '--service',
                         service_name, '--node-name', f'_{node_name}_evaluate', '--namespace',
                         namespace or '/', '--gate', gate]
        self._on_error, self._on_info = on_error, on_info
        self._lock = threading.Lock()
        self._closed = False
        self._update: tuple | None = None
        self.restarts = 0
        self._process: subprocess.Popen | None = None
        self._start()

    @property
    def alive(self) -> bool:
        """Return whether the worker process runs."""
        return self._process is not None and self._process.poll() is None

    @property
    def pid(self) -> int | None:
        """Return the worker's process id (None when it could not be started)."""
        return None if self._process is None else self._process.pid

    def update(self, config: RobotConfig | None, params: PipelineParams,
               error: str = '') -> None:
        """Send the worker the robot config (None: no model, ``error`` why) and parameters."""
        with self._lock:
            self._update = ('config', config, params, error)
            self._send(self._update)

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the worker (after the query it is on)."""
        with self._lock:
            self._closed = True
            proc = self._process
        if proc is not None:
            end_process(proc, timeout_s)

    def _start(self) -> None:
        """Start a worker and the thread reading it (called with the lock held or at init)."""
        try:
            # A process group of its own (a Ctrl-C or a signal to the node's group is the
            # node's; the worker ends when the node closes its stdin or exits) in the node's
            # session: not a session of its own, since Linux's autogroup scheduling
            # (kernel.sched_autogroup_enabled) makes each session a task group that gets a
            # fair share of the CPU against the node's whatever its tasks' policies:
            # ``SCHED_IDLE`` only ranks threads inside a group (module docstring).
            self._process = subprocess.Popen(self._command, stdin=subprocess.PIPE,
                                             stdout=subprocess.PIPE, **_OWN_GROUP)
        except OSError as exc:
            self._process = None
            self._on_error(f'~/evaluate: could not start its worker: {exc}')
            return
        if self._update is not None:
            self._send(self._update)
        threading.Thread(target=self._read, args=(self._process,), daemon=True,
                         name='awp_evaluate_reader').start()

    def _send(self, message: tuple) -> None:
        proc = self._process
        if proc is None or proc.poll() is not None:
            return
        try:
            _write(proc.stdin, message)
        except (BrokenPipeError, OSError, ValueError):     # gone: the reader restarts it
            pass

    def _read(self, proc: subprocess.Popen) -> None:
        while True:
            try:
                kind, text = _read(proc.stdout)
            except (EOFError, OSError, ValueError, TypeError, pickle.UnpicklingError):
                break
            (self._on_info if kind == 'info' else self._on_error)(text)
        code = proc.wait()
        with self._lock:
            if self._closed or proc is not self._process:
                return
            if self.restarts >= MAX_RESTARTS:
                self._on_error(f'~/evaluate: its worker ended (exit {code}) after '
                               f'{self.restarts} restarts; the service is gone')
                return
            self.restarts += 1
            self._on_error(f'~/evaluate: its worker ended (exit {code}); restarting it '
                           f'({self.restarts}/{MAX_RESTARTS})')
            self._start()


# -- the worker process --------------------------------------------------------------------


class _Worker:
    """
    The worker's state: the computation process and the latest config sent to it.

    An update the node wrote before a query arrives is applied before that query is
    answered: the node writes it to the pipe before it answers the parameter change, so a
    client that changes a parameter and then calls the service gets the new values.
    """

    def __init__(self, fd: int, gate: str = '') -> None:
        self.latest: tuple = (None, PipelineParams(), 'no robot config received yet')
        self.stop = threading.Event()
        self._fd = fd
        self._cond = threading.Condition()
        self._busy = False
        self._gate = gate
        self._computation = Computation(gate)
        self.priority = self._computation.policy     # the policy queries run at

    def configure(self, config: RobotConfig | None, params: PipelineParams, error: str) -> None:
        self.latest = (config, params, error)
        self._computation.configure(config, params, error)

    def serve(self, request: Evaluate.Request, response: Evaluate.Response
              ) -> Evaluate.Response:
        with self._cond:        # updates written before this query: applied first
            while not self.stop.is_set() and (self._busy or _readable(self._fd)):
                self._cond.wait(0.05)
            computation = self._computation
        try:
            return deserialize_message(computation.evaluate(serialize_message(request)),
                                       Evaluate.Response)
        except ProcessError as exc:     # the process died: a new one for the next query
            with self._cond:
                if computation is self._computation:
                    computation.close(0.5)
                    self._computation = Computation(self._gate)
                    self._computation.configure(*self.latest)
            _, params, _ = self.latest
            return evaluate_request(None, params, request, error=f'~/evaluate: {exc}; '
                                    'restarted it for the next query')

    def read_updates(self, out) -> None:
        """Apply every update from the node until its end of the pipe, then stop."""
        try:
            while True:
                select.select([self._fd], [], [])
                with self._cond:
                    self._busy = True
                try:
                    message = pickle.loads(_read_fd(self._fd))
                    _, config, params, error = message
                    self.configure(config, params, error)
                except EOFError:
                    break
                except Exception as exc:  # noqa: BLE001 -- reported to the node
                    _report(out, 'error', f'~/evaluate: bad update: {type(exc).__name__}: '
                            f'{exc}')
                finally:
                    with self._cond:
                        self._busy = False
                        self._cond.notify_all()
        except OSError:
            pass
        self.stop.set()
        self._computation.close()
        with self._cond:
            self._cond.notify_all()


def lower_thread_priority() -> str:
    """
    Give the calling thread the lowest CPU priority: ``SCHED_IDLE`` (Linux), else +NICE.

    Linux applies both to the calling thread only (``sched_setscheduler`` and ``nice`` act
    on a thread id). :return: the policy set (``'SCHED_IDLE'``, ``'nice +10'`` or ``''``).
    """
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        return 'SCHED_IDLE'
    except (AttributeError, OSError):
        try:
            os.nice(NICE)
            return f'nice +{NICE}'
        except OSError:
            return ''


def _readable(fd: int) -> bool:
    """Return whether ``fd`` has data (or its end) to read now."""
    return bool(select.select([fd], [], [], 0.0)[0])


def _read_fd(fd: int) -> bytes:
    """Read one length-prefixed frame from a raw file descriptor; EOFError at its end."""
    head = _read_exact(fd, _LENGTH.size)
    return _read_exact(fd, _LENGTH.unpack(head)[0])


def _read_exact(fd: int, size: int) -> bytes:
    chunks, left = [], size
    while left:
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:
            raise EOFError
        chunks.append(chunk)
        left -= len(chunk)
    return b''.join(chunks)


def _report(out, kind: str, text: str) -> None:
    try:
        _write(out, (kind, text))
    except (BrokenPipeError, OSError, ValueError):
        pass


def main(argv: list[str] | None = None) -> int:
    """Worker process: serve the service until the node closes its stdin."""
    parser = argparse.ArgumentParser(prog='python -m awp_ros.node.evaluate_service')
    parser.add_argument('--service', required=True, help='fully qualified service name')
    parser.add_argument('--node-name', default='_awp_node_evaluate')
    parser.add_argument('--namespace', default='/')
    parser.add_argument('--gate', default='', help="the node's YieldGate page ('' = none)")
    args = parser.parse_args(argv)
    signal.signal(signal.SIGINT, signal.SIG_IGN)       # Ctrl-C is the node's; it closes us
    tune_process()      # one BLAS thread: idle OpenBLAS threads spin on the node's cores
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from awp_ros.node.lifecycle import run_node
    # The answers to the node go through a copy of fd 1; fd 1 itself (and sys.stdout) go to
    # stderr, so that nothing a library prints can corrupt the frames.
    stdout = os.fdopen(os.dup(1), 'wb')
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    worker = _Worker(sys.stdin.fileno(), args.gate)
    reader = threading.Thread(target=worker.read_updates, args=(stdout,), daemon=True)
    reader.start()

    def build():
        node = rclpy.create_node(args.node_name, namespace=args.namespace,
                                 start_parameter_services=False)
        node.create_service(Evaluate, args.service, worker.serve)
        return node

    def spin(node) -> int:
        try:
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            _report(stdout, 'info', f'{args.service} ready (worker pid {os.getpid()}, '
                    f'evaluating at {worker.priority or "the normal priority"})')
            while rclpy.ok() and not worker.stop.is_set():
                executor.spin_once(timeout_sec=0.2)
        except Exception as exc:  # noqa: BLE001 -- reported to the node, which restarts us
            _report(stdout, 'error', f'~/evaluate worker failed: {type(exc).__name__}: {exc}')
            return 1
        return 0

    try:
        return run_node([], build, spin)
    except Exception as exc:  # noqa: BLE001 -- building the node failed: reported likewise
        _report(stdout, 'error', f'~/evaluate worker failed: {type(exc).__name__}: {exc}')
        return 1


if __name__ == '__main__':
    sys.exit(main())
