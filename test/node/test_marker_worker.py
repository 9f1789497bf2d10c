"""MarkerWorker: markers built in a real worker process equal those built in-process."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.node.marker_worker import MarkerWorker
from awp_ros.robot.parameters import PipelineParams
from awp_ros.ros.markers import build_markers
from awp_ros.ros.pipeline import Pipeline
from cases import contacts_msg, joints_msg, T0


def _not_importable_there() -> MarkerArray:
    return MarkerArray()


class Sink:
    def __init__(self) -> None:
        self.published: list[bytes] = []
        self.errors: list[str] = []
        self.event = threading.Event()

    def publish(self, data: bytes) -> None:
        self.published.append(data)
        self.event.set()

    def error(self, reason: str) -> None:
        self.errors.append(reason)
        self.event.set()

    def wait(self, n: int, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while len(self.published) + len(self.errors) < n and time.monotonic() < deadline:
            self.event.wait(0.05)
            self.event.clear()
        assert len(self.published) + len(self.errors) >= n, (self.published, self.errors)


@pytest.fixture(scope='module')
def cycles():
    evaluator = FeasibilityEvaluator('hyq')
    pl = Pipeline(evaluator.config, PipelineParams(marker_rate_hz=1000.0))
    pl.on_contacts(contacts_msg(T0))
    out = [pl.on_joint_state(joints_msg(evaluator, T0 + i * 10**6)) for i in range(3)]
    out.append(pl.on_joint_state(joints_msg(evaluator, T0 + 5 * 10**6, dq=float('nan'))))
    return out


def test_worker_builds_the_same_markers_reports_failures_and_refuses_beyond_its_queue(cycles):
    sink = Sink()
    worker = MarkerWorker(sink.publish, sink.error, max_pending=2)
    try:
        # Evaluated cycles and an error cycle (a red text): the bytes deserialize to the
        # MarkerArray the cycle builds in this process (itself through serialization:
        # colours are float32 on the wire).
        for c in cycles:
            assert c.markers_due and worker.submit(c.marker_job())
            sink.wait(len(sink.published) + 1)
        assert not sink.errors
        for c, data in zip(cycles, sink.published):
            got = deserialize_message(data, MarkerArray)
            assert got == deserialize_message(serialize_message(c.markers()), MarkerArray)
            assert len(got.markers) > 1
        assert cycles[-1].result is None and 'not evaluated' in cycles[-1].markers().markers[
            -1].text
        # A failing job is reported with its reason and the worker goes on: a function
        # the worker cannot import, then one that fails.
        assert worker.submit((_not_importable_there, (), {}))
        sink.wait(len(cycles) + 1)
        assert worker.submit((build_markers, (None, Header()), {}))
        sink.wait(len(cycles) + 2)
        assert len(sink.errors) == 2 and 'test_marker_worker' in sink.errors[0]
        assert sink.errors[1].startswith('markers: AttributeError')
        assert worker.submit(cycles[0].marker_job())
        sink.wait(len(cycles) + 3)
        assert len(sink.published) == len(cycles) + 1
        # Two jobs waiting: a third is refused (the node counts it), accepted again after.
        # (time.sleep returns None, which is no message: each reports an error.)
        assert worker.submit((time.sleep, (1.0,), {}))
        assert worker.submit((time.sleep, (0.0,), {}))
        assert not worker.submit((time.sleep, (0.0,), {}))
        sink.wait(len(cycles) + 5)
        assert worker.submit((time.sleep, (0.0,), {}))
        sink.wait(len(cycles) + 6)
        assert len(sink.errors) == 5
        assert worker.alive
    finally:
        worker.close()
    assert not worker.alive


def test_a_killed_worker_is_seen_dead(cycles):
    sink = Sink()
    worker = MarkerWorker(sink.publish, sink.error)
    try:
        assert worker.submit(cycles[0].marker_job())
        sink.wait(1)
        os.kill(worker.pid, signal.SIGKILL)
        deadline = time.monotonic() + 10
        while worker.alive and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not worker.alive
        assert worker.submit(cycles[0].marker_job())      # queued, never answered
        time.sleep(0.5)
        assert len(sink.published) == 1 and not sink.errors
    finally:
        worker.close()


@pytest.mark.parametrize('name', ['markers', 'fws'])
def test_worker_processes_yield_the_cpu_to_the_node(name, cycles):
    # The node lowers each worker's priority by NICE when it starts it, so that a busy worker
    # does not delay the node's joint states on shared cores; the node's is unchanged.
    from awp_ros.node.fws_worker import FwsWorker
    from awp_ros.node.marker_worker import NICE
    sink = Sink()
    worker = MarkerWorker(sink.publish, sink.error) if name == 'markers' else \
        FwsWorker(sink.error)
    ours = os.getpriority(os.PRIO_PROCESS, 0)
    try:
        if name == 'markers':
            assert worker.submit(cycles[0].marker_job())
            sink.wait(1)
        else:
            evaluator = FeasibilityEvaluator('hyq')
            worker.submit(evaluator.fws_job(evaluator.evaluate(evaluator.standing_state(),
                                                               fws=False))).result(30.0)
        assert os.getpriority(os.PRIO_PROCESS, worker.pid) == min(ours + NICE, 19)
        assert os.getpriority(os.PRIO_PROCESS, 0) == ours
    finally:
        worker.close()


def test_jobs_a_dying_worker_took_go_to_the_fallback():
    # A job on the worker's hands when it is killed, and one submitted after: neither is
    # answered, both reach the fallback (the node builds them), each once; none is an error.
    sink = Sink()
    lost: list = []
    worker = MarkerWorker(sink.publish, sink.error, fallback=lost.append)
    try:
        slow = (time.sleep, (30.0,), {})           # still sleeping in the worker when killed
        assert worker.submit(slow)
        time.sleep(1.0)                            # the worker has read it
        os.kill(worker.pid, signal.SIGKILL)
        deadline = time.monotonic() + 10
        while not lost and time.monotonic() < deadline:
            time.sleep(0.02)
        assert lost == [slow]
        later = (time.sleep, (0.0,), {})
        assert worker.submit(later)
        deadline = time.monotonic() + 10
        while len(lost) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert lost == [slow, later] and not sink.published and not sink.errors
    finally:
        worker.close()
