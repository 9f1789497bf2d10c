"""The query worker evaluates at the lowest priority in one thread only (evaluate_service)."""

import os
from pathlib import Path
import sys
import threading

import pytest

from awp_ros.node.evaluate_service import _idle_executor, EvaluateService, lower_thread_priority
from awp_ros.soak.probe import wait_until

linux_only = pytest.mark.skipif(not sys.platform.startswith('linux'),
                                reason='per-thread scheduling policies are Linux')


@linux_only
def test_lower_thread_priority_changes_the_calling_thread_only():
    seen = {}

    def run():
        seen['policy'] = lower_thread_priority()
        seen['own'] = os.sched_getscheduler(0)

    before = os.sched_getscheduler(0)
    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    assert seen['policy'] == 'SCHED_IDLE' and seen['own'] == os.SCHED_IDLE
    assert os.sched_getscheduler(0) == before != os.SCHED_IDLE


@linux_only
def test_the_idle_thread_runs_calls_at_sched_idle_and_hands_back_values_and_errors():
    idle, policy = _idle_executor()
    assert policy == 'SCHED_IDLE'
    assert idle.submit(lambda: os.sched_getscheduler(0)).result() == os.SCHED_IDLE
    assert idle.submit(divmod, 7, 2).result() == (3, 1)
    with pytest.raises(ZeroDivisionError):
        idle.submit(divmod, 1, 0).result()
    assert os.sched_getscheduler(0) != os.SCHED_IDLE
    idle.shutdown()


@linux_only
def test_the_worker_runs_in_the_nodes_session_in_a_process_group_of_its_own(ros_env,
                                                                            monkeypatch):
    # Autogroup scheduling makes each session a task group with a fair share of the CPU
    # against the node's, whatever the policies of its threads: a worker in a session of its
    # own competed with the node as if it were not at SCHED_IDLE.
    for name in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_DOMAIN_ID'):
        monkeypatch.setenv(name, ros_env[name])
    lines = []
    service = EvaluateService('/awp_priority_test/evaluate', 'awp_priority_test', '/',
                              lines.append, lines.append)
    try:
        pid = service.pid
        assert os.getsid(pid) == os.getsid(0)
        assert os.getpgid(pid) == pid != os.getpgid(0)
        group = Path('/proc/self/autogroup')
        if group.exists():
            assert Path(f'/proc/{pid}/autogroup').read_text().split()[0] == \
                group.read_text().split()[0]
        wait_until(lambda: any('ready' in line for line in lines), 60.0, 'the worker')
        policies = {os.sched_getscheduler(int(task)) for task in os.listdir(f'/proc/{pid}/task')}
        assert os.SCHED_IDLE in policies and os.SCHED_OTHER in policies, lines
    finally:
        service.close()
