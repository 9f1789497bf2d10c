"""The query worker's processes: their session, groups and CPU policies (evaluate_service)."""

import os
from pathlib import Path
import sys
import threading

import pytest

from awp_ros.node.evaluate_service import EvaluateService, lower_thread_priority
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
        # The kernel prints '/autogroup-<id> nice <n>' for a task in an autogroup and nothing
        # for one whose CPU cgroup is not the root (a container): both cases must match ours.
        group = Path('/proc/self/autogroup')
        if group.exists():
            assert Path(f'/proc/{pid}/autogroup').read_text() == group.read_text()
        wait_until(lambda: any('ready' in line for line in lines), 60.0, 'the worker')
        # Its DDS threads at the normal policy; the evaluation in a child process (the query
        # computation, evaluate_compute) at SCHED_IDLE, in the same session.
        policies = {os.sched_getscheduler(int(task)) for task in os.listdir(f'/proc/{pid}/task')}
        assert policies == {os.SCHED_OTHER}, lines
        children = Path(f'/proc/{pid}/task/{pid}/children').read_text().split()
        assert len(children) == 1, children
        child = int(children[0])
        assert os.sched_getscheduler(child) == os.SCHED_IDLE
        assert os.getsid(child) == os.getsid(0)
    finally:
        service.close()
