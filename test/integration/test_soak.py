"""
The soak script, short: awp_node driven from another process; nothing may be lost.

The full runs (60 s at 1 kHz and at a sustained rate) are in the README, with the command;
here a few seconds at a rate this machine sustains (no timing assertions: the machine is
shared), plus the two overload behaviours: a queue too short for the backlog (every loss
is counted by the node itself) and load shedding (every joint state still answered).
"""

from __future__ import annotations

import os
import resource

import numpy as np
import pytest

from awp_ros.soak.monitor import proc_usage, ProcessMonitor
from awp_ros.soak.soak import run_soak


def test_proc_usage_reads_cpu_time_and_rss_of_a_process():
    cpu0, rss = proc_usage(os.getpid())
    x = np.random.default_rng(0).random((400, 400))
    for _ in range(20):
        x = x @ x / 400.0                       # burn some CPU
    cpu1, _ = proc_usage(os.getpid())
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024   # kB on Linux
    assert 10 * 2**20 < rss <= peak * 1.01
    assert cpu1 > cpu0 > 0.0
    mon = ProcessMonitor(os.getpid(), period_s=0.05)
    try:
        while len(mon.samples) < 3:
            x = x @ x / 400.0
    finally:
        mon.stop()
    s = mon.array()
    assert s.shape[1] == 3 and np.all(np.diff(s[:, 0]) > 0) and np.all(np.diff(s[:, 1]) >= 0)


def test_short_soak_loses_nothing_and_rss_stays_flat(ros_env):
    r = run_soak(150.0, 5.0, env=ros_env, warmup_s=2.0, sample_period_s=0.25)
    print('\n' + r.table())
    assert r.node_alive
    assert r.sent == 750 and r.sent_rate_hz > 140.0
    assert r.reports == r.sent and r.missing == 0 and r.duplicates == 0 and r.unexpected == 0
    assert set(r.status_counts) <= {'ok', 'warning'}, r.status_counts
    assert r.node_missing_from_sequence == 0 and r.node_lost_total == 0
    assert r.rss_growth_percent < 5.0, r.rss_mb
    assert 0.0 < r.cpu_percent['mean'] < 250.0
    assert r.latency_ms['p50'] > 0.0 and len(r.timeline) >= 4


def test_a_queue_too_short_for_the_backlog_loses_joint_states_but_counts_each(ros_env):
    # 2 kHz into a node with a 5-deep input queue: it cannot keep up, DDS replaces the
    # oldest queued joint states, and the node counts every one of them from the gaps in
    # the publisher's sequence numbers (the report after a gap says how many).
    r = run_soak(2000.0, 1.0, env=ros_env, qos_depth=5, warmup_s=0.2, sample_period_s=0.25,
                 stall_timeout_s=2.0)
    assert r.node_alive and r.duplicates == 0 and r.unexpected == 0
    if r.missing == 0:
        pytest.skip('the node kept up with 2 kHz: nothing to count')
    assert r.reports + r.missing == r.sent
    assert r.node_missing_from_sequence == r.missing


def test_load_shedding_answers_every_joint_state_within_the_delay(ros_env):
    r = run_soak(2000.0, 1.5, env=ros_env, warmup_s=0.3, sample_period_s=0.25,
                 params={'max_queue_delay_s': 0.05})
    assert r.node_alive
    assert r.reports == r.sent and r.missing == 0 and r.duplicates == 0
    if 'stale_input' not in r.status_counts:
        pytest.skip('the node kept up with 2 kHz: nothing shed')
    assert r.status_counts.get('ok', 0) + r.status_counts.get('warning', 0) > 0
    # Shed joint states are answered at once: latency stays near the allowed queue delay.
    assert r.latency_after_warmup_ms['p50'] < 500.0
