"""The query worker evaluates at the lowest priority in one thread only (evaluate_service)."""

import os
import sys
import threading

import pytest

from awp_ros.node.evaluate_service import _idle_executor, lower_thread_priority

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
