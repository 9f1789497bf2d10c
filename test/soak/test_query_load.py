"""The query-load measurement's window schedule and table (awp_ros.soak.query_load)."""

from awp_ros.soak.query_load import table, window_kind


def test_alternating_windows_cycle_call_control_and_null():
    kinds = [window_kind(i, alternate=True, null=True, control=True) for i in range(7)]
    assert kinds == ['call', 'control', 'null', 'call', 'control', 'null', 'call']
    kinds = [window_kind(i, alternate=True, null=False, control=True) for i in range(4)]
    assert kinds == ['call', 'control', 'call', 'control']


def test_without_alternate_every_window_is_a_call_or_every_one_a_control():
    assert {window_kind(i, alternate=False, null=True, control=False)
            for i in range(5)} == {'call'}
    assert {window_kind(i, alternate=False, null=False, control=True)
            for i in range(5)} == {'control'}


def test_the_table_gives_the_median_and_range_of_each_paired_figure():
    pair = [{'p50': 0.5, 'p99': 4.0, 'max': 9.0}, {'p50': 1.5, 'p99': 2.0, 'max': 3.0},
            {'p50': -0.5, 'p99': 6.0, 'max': 1.0}]
    result = {'sent': 10, 'rate_hz': 500.0, 'reports': 10, 'missing': 0, 'queries': 3,
              'states_per_query': 100, 'query_s': [1.0], 'query_statuses': {'ok': 300},
              'latency_baseline_ms': {'p50': 1.0, 'p99': 2.0, 'max': 3.0},
              'reports_baseline': 7, 'latency_during_queries_ms': {},
              'reports_during_queries': 0, 'delay_attributable_ms': {},
              'paired_difference_ms': pair, 'paired_control_ms': [], 'paired_null_ms': pair[:1]}
    text = table(result)
    call = next(line for line in text.splitlines() if 'each call' in line)
    assert 'before it, 3 windows)' in call
    assert 'p50 difference median 0.500 ms (range -0.500 .. 1.500)' in call
    assert 'p99 difference median 4.000 ms (range 2.000 .. 6.000)' in call
    assert 'max difference median 3.000 ms (range 1.000 .. 9.000)' in call
    null = next(line for line in text.splitlines() if 'each null window' in line)
    assert 'max difference median 9.000 ms' in null
    assert 'each control' not in text
