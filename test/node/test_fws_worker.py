"""
``fws_lag_s``: the FWS off the joint-state loop, in a real worker process or in steps.

Checked over the default bag against the FWS computed in the loop (``fws_lag_s: 0``): a
lagged report carries exactly the in-loop FWS of the latest due stamp at least ``fws_lag_s``
earlier within its stance, or none (then ``feasible`` is the FWP's verdict); the worker's
answers equal those computed in the process, also after the worker was killed; and so do
the answers computed in steps between joint states (``fws_worker: false``).
"""

from __future__ import annotations

from dataclasses import replace
import math
import os
import signal
import time

from awp_ros_msgs.msg import ContactState
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from awp_ros.bags.reader import read_bag
from awp_ros.node.fws_worker import FwsRunner, FwsWorker, MAX_IN_FLIGHT
from awp_ros.robot.config import load_parameters
from awp_ros.ros.conversions import stamp_to_ns
from awp_ros.ros.pipeline import InlineFws, Pipeline

LAG_S = 0.02
FWS_FIELDS = ('fws_margin', 'fws_margin_in_hull', 'fws_normal', 'fws_dimension',
              'fws_affine_residual', 'fws_feasible', 'fws_directional_plus',
              'fws_directional_minus')


@pytest.fixture(scope='module')
def bag_msgs(repo):
    types = {'/joint_states': JointState, '/contacts': ContactState}
    return [(m.topic, deserialize_message(m.data, types[m.topic]))
            for m in read_bag(str(repo / 'config' / 'hyq_gait.mcap'), topics=list(types))]


def _run(msgs, lag_s: float, runner=None, *, kill_after: int | None = None,
         steps: int = 0):
    """
    Return the reports and the ``~/fws`` messages of the bag through a pipeline.

    ``steps``: after each joint state, this many steps of the pending FWS jobs, as the node
    does with ``fws_worker: false`` (one after each report, more while it is idle).
    """
    params, base_dir = load_parameters('hyq')
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    pipeline.set_params(replace(pipeline.params, fws_lag_s=lag_s))
    if runner is not None:
        pipeline.fws_runner = runner
    reports, fws = [], []
    for topic, msg in msgs:
        if topic == '/contacts':
            pipeline.on_contacts(msg)
            continue
        if kill_after is not None and len(reports) == kill_after:
            os.kill(runner.worker.pid, signal.SIGKILL)
        cycle = pipeline.on_joint_state(msg)
        reports.append(cycle.report)
        fws.append(cycle.fws())
        for _ in range(steps):
            pipeline.step_fws()
    return reports, fws


def _same(u, v) -> bool:
    """Field-wise equality of messages, NaN equal to NaN."""
    if hasattr(u, 'get_fields_and_field_types'):
        return all(_same(getattr(u, f), getattr(v, f)) for f in u.get_fields_and_field_types())
    if isinstance(u, (str, bool, int)):
        return u == v
    if isinstance(u, float):
        return u == v or (math.isnan(u) and math.isnan(v))
    if isinstance(u, (list, tuple)) and u and hasattr(u[0], 'get_fields_and_field_types'):
        return len(u) == len(v) and all(_same(a, b) for a, b in zip(u, v))
    U, V = np.asarray(u), np.asarray(v)
    if U.dtype.kind in 'fc':
        return U.shape == V.shape and np.array_equal(U, V, equal_nan=True)
    return list(u) == list(v)


@pytest.fixture(scope='module')
def in_loop(bag_msgs):
    return _run(bag_msgs, 0.0)


@pytest.fixture(scope='module')
def lagged(bag_msgs):
    return _run(bag_msgs, LAG_S)


def test_a_lagged_report_carries_the_in_loop_fws_of_its_stamp_minus_the_lag(in_loop, lagged):
    base, _ = in_loop
    reports, fws_msgs = lagged
    lag_ns = int(LAG_S * 1e9)
    stamps = [stamp_to_ns(r.header.stamp) for r in base]
    due = {s: r for s, r in zip(stamps, base) if stamp_to_ns(r.fws_stamp) == s}
    assert len(due) > 100
    stance_start, previous, without, with_fws = None, None, 0, 0
    for s, r0, r in zip(stamps, base, reports):
        if list(r0.stance_feet) != previous:
            stance_start, previous = s, list(r0.stance_feet)
        # Every field but the FWS's (and those derived from it) is the in-loop report's.
        for name in ('awp_margin', 'fwp_margin', 'fwp_feasible', 'support_region_margin',
                     'feasible_region_margin', 'status', 'stance_feet'):
            assert _same(getattr(r, name), getattr(r0, name)), (s, name)
        expected = [t for t in due if stance_start <= t <= s - lag_ns]
        # This cycle's verdict (three or more legs: the CoM in its feasible region; two: the
        # legs' one-dimensional LP), as in the in-loop report; with three or more legs this
        # cycle's directional margins too.
        this_cycle = len(r0.stance_feet) >= 2
        directional = ('fws_directional_plus', 'fws_directional_minus')
        if len(r0.stance_feet) >= 3:
            for name in directional:
                assert _same(getattr(r, name), getattr(r0, name)), (s, name)
        if not expected:
            without += 1
            assert math.isnan(r.fws_margin) and not r.fws_feasible, s
            assert r.feasible == (r0.feasible if this_cycle else r0.fwp_feasible), s
            continue
        with_fws += 1
        t = max(expected)
        assert stamp_to_ns(r.fws_stamp) == t, (s, t)
        for name in FWS_FIELDS:
            if name not in directional or len(r0.stance_feet) < 3:
                assert _same(getattr(r, name), getattr(due[t], name)), (s, name)
        assert r.feasible == (r0.feasible if this_cycle
                              else r0.fwp_feasible and due[t].fws_feasible), s
    assert without > 50 and with_fws > 4000, (without, with_fws)
    # Each FWS is published once, in the cycle it is released, stamped with its own stamp.
    released = [stamp_to_ns(m.header.stamp) for m in fws_msgs if m is not None]
    assert released == sorted(released) and len(released) == len(set(released))
    assert set(released) <= set(due)


def test_the_worker_process_answers_as_the_node_would_also_after_it_is_killed(
        bag_msgs, lagged):
    reports, fws_msgs = lagged
    errors: list[str] = []
    runner = FwsRunner(errors.append)
    try:
        runner.start()
        got, got_fws = _run(bag_msgs, LAG_S, runner, kill_after=3000)
    finally:
        runner.close()
    assert len(got) == len(reports)
    for a, b in zip(got, reports):
        a.compute_time = b.compute_time = 0.0
        assert _same(a, b), a.header.stamp
    assert [m is None for m in got_fws] == [m is None for m in fws_msgs]
    assert all(_same(a, b) for a, b in zip(got_fws, fws_msgs) if a is not None)
    assert errors and 'FWS worker process ended' in errors[0], errors
    assert not runner.worker.alive


def test_a_worker_still_starting_is_not_waited_for_and_gives_the_same_numbers():
    from awp_ros.evaluation.evaluator import compute_fws, FeasibilityEvaluator
    ev = FeasibilityEvaluator('hyq')
    jobs = [ev.fws_job(ev.evaluate(ev.standing_state(stance=list(ev.feet)[:n]), fws=False))
            for n in (4, 3, 2)]
    errors: list[str] = []
    runner = FwsRunner(errors.append)
    try:
        early = [runner.submit(job) for job in jobs]      # the worker is still importing
        parts = [h.result() for h in early]                # computed here, not waited for
        # One job went to the worker while it starts; the others stay here (no full pipe).
        assert [h._future is not None for h in early] == [True, False, False]
        early[0]._future.result(60.0)                      # the worker has answered now
        late = [runner.submit(job) for job in jobs]
        late[-1]._future.result(60.0)                      # the worker has answered now
        for job, a, h in zip(jobs, parts, late):
            b, ref = h.result(), compute_fws(*job)
            for x in (a, b):
                assert np.array_equal(x[0].A, ref[0].A) and np.array_equal(x[0].b, ref[0].b)
                assert x[1].margin == ref[1].margin and x[1].feasible == ref[1].feasible
                assert np.array_equal(x[1].normal, ref[1].normal)
                assert all(u is v is None or np.array_equal(u, v, equal_nan=True)
                           for u, v in zip(x[2:4], ref[2:4]))
        assert runner.worker.alive and not errors
    finally:
        runner.close()


class _CountingRunner(InlineFws):
    """In-process steps; counts the jobs whose answer was in before it was asked for."""

    def __init__(self) -> None:
        self.handles: list = []
        self.asked = self.ready_when_asked = 0

    def submit(self, job: tuple) -> InlineFws.Handle:
        handle = super().submit(job)
        result, runner = handle.result, self

        def asked(timeout=None):
            runner.asked += 1
            runner.ready_when_asked += handle._part is not None
            return result(timeout)
        handle.result = asked
        self.handles.append(handle)
        return handle


def test_the_fws_in_steps_between_joint_states_answers_as_in_one_piece(bag_msgs, lagged):
    reports, fws_msgs = lagged            # the default runner: computed whole on release
    runner = _CountingRunner()
    got, got_fws = _run(bag_msgs, LAG_S, runner, steps=2)
    assert len(got) == len(reports)
    for a, b in zip(got, reports):
        a.compute_time = b.compute_time = 0.0
        assert _same(a, b), a.header.stamp
    assert [m is None for m in got_fws] == [m is None for m in fws_msgs]
    # Two steps per joint state finished nearly every job before its release, 10 joint
    # states (20 ms of the 500 Hz bag) later: four legs take 11 steps of 0.1-0.4 ms.
    assert len(runner.handles) > 100 and runner.asked > 100
    assert runner.ready_when_asked > 0.9 * runner.asked, (runner.ready_when_asked,
                                                          runner.asked)


@pytest.fixture(scope='module')
def standing_job():
    """Return the FWS job of HyQ standing on four legs and its answer computed here."""
    from awp_ros.evaluation.evaluator import compute_fws, FeasibilityEvaluator
    ev = FeasibilityEvaluator('hyq')
    job = ev.fws_job(ev.evaluate(ev.standing_state(), fws=False))
    return job, compute_fws(*job)


@pytest.fixture
def worker():
    """Yield a new FWS worker process and the list its errors go to; close it after."""
    errors: list[str] = []
    started = FwsWorker(errors.append)
    yield started, errors
    started.close()


def test_jobs_sent_faster_than_the_worker_answers_never_block_and_give_the_same_numbers(
        standing_job, worker):
    # 60 jobs at once (~4 kB each, 240 kB) into a worker that is starting: before the limit
    # the 17th write filled the 64 kB pipe and blocked the caller (the node's joint-state
    # thread) ~1 s until the worker read. Now it holds one job while starting and at most
    # MAX_IN_FLIGHT later; every other job is computed by the caller, with the same numbers.
    (job, ref), (worker, errors) = standing_job, worker
    starting = [worker.submit(job) for _ in range(60)]
    sent = sum(h._future is not None for h in starting)
    assert sent == 1 or worker._answered > 0 and sent <= MAX_IN_FLIGHT + 1, sent
    starting[0]._future.result(60.0)
    ready = [worker.submit(job) for _ in range(60)]
    in_flight = sum(h._future is not None for h in ready)
    assert 1 <= in_flight < 30, in_flight   # the limit, plus slots freed by answers meanwhile
    for h in starting + ready:
        part = h.result()
        assert np.array_equal(part[0].A, ref[0].A) and part[1].margin == ref[1].margin
    assert worker.alive and not errors


def test_a_late_worker_is_not_waited_for_beyond_the_deadline_and_gives_the_same_numbers(
        standing_job, worker):
    # A worker that has answered once, then is not scheduled (stopped here with SIGSTOP, as
    # when it runs at its lower priority on a CPU busy with the processes feeding the node):
    # the caller's deadline passes, the job is computed by the caller with the same numbers
    # and counted late, not as an error. Without a deadline the caller waited up to 10 s.
    (job, ref), (worker, errors) = standing_job, worker
    worker.submit(job)._future.result(60.0)            # started and answering
    os.kill(worker.pid, signal.SIGSTOP)
    try:
        handle = worker.submit(job)
        assert handle._future is not None              # sent to the stopped worker
        t0 = time.monotonic()
        part = handle.result(timeout=0.05)
        waited = time.monotonic() - t0
    finally:
        os.kill(worker.pid, signal.SIGCONT)
    assert 0.05 <= waited < 5.0, waited                # the deadline, then one FWS here
    assert np.array_equal(part[0].A, ref[0].A) and part[1].margin == ref[1].margin
    assert worker.late == 1 and not errors, errors
    # Resumed, the worker answers the late job (dropped) and then the next ones.
    again = worker.submit(job)
    again._future.result(60.0)
    assert again.result(timeout=0.0)[1].margin == ref[1].margin
    assert worker.late == 1 and worker.alive and not errors


def test_the_pipeline_does_not_wait_for_a_stopped_worker(bag_msgs, lagged):
    # The bag through a pipeline whose worker is stopped after 1500 joint states: every
    # joint state is answered without waiting for it beyond fws_lag_s + FWS_LATE_GRACE_S of
    # wall time per job, and the reports are those with the FWS computed in the process.
    from awp_ros.ros.pipeline import FWS_LATE_GRACE_S
    reports, _ = lagged
    errors: list[str] = []
    runner = FwsRunner(errors.append)
    params, base_dir = load_parameters('hyq')
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    pipeline.set_params(replace(pipeline.params, fws_lag_s=LAG_S))
    pipeline.fws_runner = runner
    got, longest, stopped = [], 0.0, False
    try:
        runner.start()
        ev = pipeline.evaluator                             # wait until it answers
        runner.submit(ev.fws_job(ev.evaluate(ev.standing_state(), fws=False)))._future.result(
            60.0)
        for topic, msg in bag_msgs[:4000]:
            if topic == '/contacts':
                pipeline.on_contacts(msg)
                continue
            if len(got) == 1500:
                assert runner.worker._answered > 0          # it was answering
                os.kill(runner.worker.pid, signal.SIGSTOP)
                stopped = True
            t0 = time.monotonic()
            got.append(pipeline.on_joint_state(msg).report)
            longest = max(longest, time.monotonic() - t0)
    finally:
        if stopped:
            os.kill(runner.worker.pid, signal.SIGCONT)
        runner.close()
    for a, b in zip(got, reports):
        a.compute_time = b.compute_time = 0.0
        assert _same(a, b), a.header.stamp
    # Each due job waited at most LAG_S + FWS_LATE_GRACE_S (the bag is replayed faster than
    # its stamps), then was computed here (a few ms; generous for a shared machine).
    assert runner.worker.late > 5 and not errors, (runner.worker.late, errors)
    assert longest < LAG_S + FWS_LATE_GRACE_S + 1.0, longest
