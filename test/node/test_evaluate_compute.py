"""The query computation process (evaluate_compute): its policy, answers and failures."""

from __future__ import annotations

import os
import subprocess
import sys

from awp_ros_msgs.msg import ContactState, FeasibilityReport
from awp_ros_msgs.srv import Evaluate
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from awp_ros.errors import ProcessError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.node.evaluate_compute import Computation
from awp_ros.node.evaluate_service import evaluate_request
from awp_ros.robot.config import load_config, RobotConfig
from awp_ros.robot.parameters import PipelineParams


@pytest.fixture(scope='module')
def computation():
    comp = Computation()
    yield comp
    comp.close()


def _request(config: RobotConfig, offsets) -> Evaluate.Request:
    names = sorted(config.standing_posture)
    request = Evaluate.Request()
    for k, dq in enumerate(offsets):
        js = JointState(name=names)
        js.header.stamp.sec = k
        js.position = [config.standing_posture[n] + dq for n in names]
        request.joint_states.append(js)
        request.contacts.append(ContactState(names=list(config.feet),
                                             in_contact=[True] * len(config.feet)))
    return request


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='SCHED_IDLE is Linux')
def test_the_process_evaluates_at_sched_idle(computation):
    assert computation.policy == 'SCHED_IDLE'
    assert os.sched_getscheduler(computation.pid) == os.SCHED_IDLE
    assert os.sched_getscheduler(0) != os.SCHED_IDLE


def test_its_responses_equal_the_request_evaluated_here(computation):
    config = load_config('hyq')
    params = PipelineParams()
    assert computation.configure(config, params, '') == ''
    request = _request(config, [0.0, 0.05, -0.08])
    got = deserialize_message(computation.evaluate(serialize_message(request)),
                              Evaluate.Response)
    evaluator = FeasibilityEvaluator(config)
    evaluator.hull_tol = max(params.hull_tolerance, evaluator.feasibility_tol)
    want = evaluate_request(evaluator, params, request)
    assert len(got.reports) == 3
    for a, b in zip(got.reports, want.reports):
        assert a.status == b.status == FeasibilityReport.STATUS_OK, (a.status_message,
                                                                     b.status_message)
        for name in ('fwp_margin', 'fws_margin', 'awp_margin', 'mass'):
            assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-9, abs=1e-9)
        assert np.allclose([a.com.x, a.com.y, a.com.z], [b.com.x, b.com.y, b.com.z])


def test_without_a_model_every_report_gives_the_reason(computation):
    config = load_config('hyq')
    assert computation.configure(None, PipelineParams(), 'bad urdf') == 'bad urdf'
    got = deserialize_message(computation.evaluate(serialize_message(_request(config, [0.0]))),
                              Evaluate.Response)
    assert got.reports[0].status == FeasibilityReport.STATUS_ERROR
    assert 'bad urdf' in got.reports[0].status_message


def test_a_dead_process_is_a_process_error():
    comp = Computation()
    comp._process.kill()
    comp._process.wait(5)
    with pytest.raises(ProcessError, match='ended'):
        comp.evaluate(b'')
    comp.close()


def test_a_gate_closed_before_the_process_is_up_ends_it_quietly(tmp_path):
    # A node stopped right after starting unlinks its gate before the process attaches.
    gone = tmp_path / 'awp_gate_gone'
    proc = subprocess.run([sys.executable, '-m', 'awp_ros.node.evaluate_compute', '--gate',
                           str(gone)], stdin=subprocess.DEVNULL, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert 'Traceback' not in proc.stderr
    assert 'closed its gate' in proc.stderr
