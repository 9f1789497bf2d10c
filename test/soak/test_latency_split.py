"""The soak's latency split (awp_ros.soak.result.fill_latency_split), on hand-made times."""

import numpy as np
import pytest

from awp_ros.soak.result import fill_latency_split, SoakResult

MS = 1_000_000      # ns


def _times(n: int, rate_hz: float = 1000.0):
    """Return stamps [ns] of n joint states sent every period from t0."""
    t0 = 1_700_000_000 * 10**9
    return t0 + (np.arange(n) * (1e9 / rate_hz)).astype(np.int64)


def test_a_report_held_in_dds_is_placed_in_transport_not_in_the_node():
    sent = _times(1000)
    published = sent + 300_000                          # the node answers in 0.3 ms
    received = published + 50_000                       # DDS takes 0.05 ms ...
    received[400] = published[400] + 250 * MS           # ... but holds one report 250 ms
    callback = received + 20_000
    r = SoakResult('hyq', 1000.0, 1.0, 2000)
    fill_latency_split(r, sent, published, received, (callback - sent) * 1e-6, sent)
    assert r.node_publish_ms['p50'] == pytest.approx(0.3)
    assert r.node_publish_ms['max'] == pytest.approx(0.3)
    assert r.report_transport_ms['p50'] == pytest.approx(0.05)
    assert r.report_transport_ms['max'] == pytest.approx(250.0)
    assert r.driver_gaps == {'count': 0, 'max_ms': 0.0, 'threshold_ms': 10.0}
    w = r.worst_report
    assert w['at_s'] == pytest.approx(0.4) and w['latency_ms'] == pytest.approx(250.32)
    assert w['node_publish_ms'] == pytest.approx(0.3) and w['transport_ms'] == pytest.approx(250)
    assert w['driver_gap_ms'] == pytest.approx(1.0)     # the ordinary period, no pause


def test_a_driver_pause_is_found_and_named_beside_the_report_it_delayed():
    # The driver sends 100 joint states, stops 300 ms, then sends the rest: the joint state
    # sent just before the pause reaches the node only when the driver runs again.
    sent = _times(1000, 1000.0)
    sent[100:] += 300 * MS
    published = sent + 400_000
    published[99] = sent[100] + 400_000
    received = published + 60_000
    r = SoakResult('hyq', 1000.0, 1.3, 2000)
    fill_latency_split(r, sent, published, received, (received - sent) * 1e-6, sent)
    assert r.driver_gaps == {'count': 1, 'max_ms': pytest.approx(301.0), 'threshold_ms': 10.0}
    w = r.worst_report
    assert w['at_s'] == pytest.approx(0.099)
    assert w['node_publish_ms'] == pytest.approx(301.4)
    assert w['transport_ms'] == pytest.approx(0.06)
    assert w['driver_gap_ms'] == pytest.approx(301.0)
    # A pause far from the slowest report is counted but not named beside it.
    far = _times(5000, 1000.0)
    far[4000:] += 50 * MS
    pub = far + 400_000
    pub[10] += 5 * MS
    r2 = SoakResult('hyq', 1000.0, 5.0, 6000)
    fill_latency_split(r2, far, pub, pub + 1, (pub + 1 - far) * 1e-6, far)
    assert r2.driver_gaps['count'] == 1 and r2.worst_report['at_s'] == pytest.approx(0.010)
    assert r2.worst_report['driver_gap_ms'] == pytest.approx(1.0)


def test_the_pause_threshold_is_ten_periods_at_low_rates_and_unknown_times_are_left_out():
    sent = _times(200, 50.0)                            # 20 ms apart
    sent[100:] += 150 * MS                              # a 170 ms gap: below 10 periods
    sent[150:] += 230 * MS                              # a 250 ms gap: a pause
    published = sent + 2 * MS
    received = published + 100_000
    published[:50] = 0                                  # no source timestamp ...
    received[:50] = sent[:50] + 900 * MS                # ... so this does not count either
    r = SoakResult('hyq', 50.0, 4.0, 300)
    fill_latency_split(r, sent, published, received, (received - sent) * 1e-6, sent)
    assert r.driver_gaps == {'count': 1, 'max_ms': pytest.approx(250.0), 'threshold_ms': 200.0}
    assert r.node_publish_ms['max'] == pytest.approx(2.0)
    assert r.report_transport_ms['max'] == pytest.approx(0.1)
    w = r.worst_report                                  # the slowest has no split
    assert w['latency_ms'] == pytest.approx(900.0) and np.isnan(w['node_publish_ms'])
    assert np.isnan(w['transport_ms'])


def test_the_node_queue_counts_falling_behind_with_or_without_the_transport_delay():
    """A period says 'falling behind' whether or not the node reports its transport delay."""
    from threading import Lock

    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    from awp_ros.soak.result import fill_node_diagnostics

    def period(queue_ms: str, transport_ms: str | None, message: str) -> DiagnosticArray:
        values = [KeyValue(key='input queue delay max [ms]', value=queue_ms)]
        if transport_ms is not None:
            values.append(KeyValue(key='input transport delay max [ms]', value=transport_ms))
        return DiagnosticArray(status=[DiagnosticStatus(name='awp_node: evaluation',
                                                        message=message, values=values)])
    behind = 'falling behind: joint states waited 35.2 ms (p50)'
    for transport in (None, 'nan', '2.5'):
        r = SoakResult('hyq', 1000.0, 2.0, 3000)
        fill_node_diagnostics(r, [period('40.0', transport, behind),
                                  period('3.0', transport, '1000 reports')], Lock())
        assert r.node_queue['periods'] == 2 and r.node_queue['falling_behind'] == 1
        assert r.node_queue['last_falling_behind_message'] == behind
        assert r.node_queue['queue_delay_max_ms'] == 40.0
        if transport == '2.5':
            assert r.node_queue['transport_delay_max_ms'] == 2.5
        else:
            assert np.isnan(r.node_queue['transport_delay_max_ms'])
