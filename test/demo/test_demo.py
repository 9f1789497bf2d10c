"""awp_demo: node process + default bag + live table, then an output bag and a margins PNG."""

from __future__ import annotations

from pathlib import Path
import re
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from rclpy.serialization import deserialize_message

from awp_ros.bags.message_types import message_class
from awp_ros.bags.reader import bag_info, read_bag
from awp_ros.demo.plot import (MarginSeries, MEASURED_COLOUR, plot_margins,
                               QUASI_STATIC_COLOUR, STANCE_COLOURS, WINDOW_COLOUR)
from awp_ros.demo.table import (comparison_lines, format_row, intended_windows, QuasiStatic,
                                TABLE_HEADER)
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.gait.bag import default_bag_path
from awp_ros.gait.generator import generate_gait
from awp_ros.gait.params import GaitParams
from awp_ros.robot.config import find_parameters_file, load_config
from awp_ros.robot.state import RobotState

BIN = Path(sys.executable).parent
FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')


def _colour_fraction(image: np.ndarray, hex_colour: str, tol: float = 0.02) -> float:
    rgb = np.array([int(hex_colour[i:i + 2], 16) / 255 for i in (1, 3, 5)])
    return float((np.abs(image[..., :3] - rgb).max(axis=-1) < tol).mean())


def _stamp(t_ms: int) -> SimpleNamespace:
    return SimpleNamespace(sec=100 + t_ms // 1000, nanosec=(t_ms % 1000) * 10**6)


def _report(t_ms: int, stance, fwp: float, *, residual=0.0, status=0, fws_now=True,
            fws_at_ms: int | None = None):
    # fws_now: the FWS computed for this report; else the one of fws_at_ms (None: none).
    stamp = _stamp(t_ms)
    return SimpleNamespace(
        header=SimpleNamespace(stamp=stamp), stance_feet=list(stance), status=status,
        status_message='' if status <= 1 else 'no contacts message received yet',
        awp_margin=3.0 * fwp, fwp_margin=fwp, fws_margin=0.9 * fwp,
        fwp_affine_residual=residual, fwp_feasible=residual == 0.0 and fwp >= 0,
        feasible=residual == 0.0 and fwp >= 0,
        fws_stamp=stamp if fws_now else SimpleNamespace(sec=0, nanosec=0) if fws_at_ms is None
        else _stamp(fws_at_ms))


def _ns(t_ms: int) -> int:
    return 100 * 10**9 + t_ms * 10**6


def test_table_rows_show_time_stance_margin_and_feasibility():
    assert TABLE_HEADER.split()[:2] == ['t', '[s]'] and 'FWP margin' in TABLE_HEADER
    assert 'quasi-static' in TABLE_HEADER
    row = format_row(_report(1500, FEET[:2] + FEET[3:], 41.8), FEET, 100 * 10**9)
    assert row.split() == ['1.50', 'LF', 'RF', '--', 'RH', '41.80', 'yes', '0.00', 'yes',
                           '-', '-']
    row = format_row(_report(5600, ['rf_foot', 'lh_foot'], 184.0, residual=26.1), FEET,
                     100 * 10**9)
    assert row.split()[1:5] == ['--', 'RF', 'LH', '--']
    assert row.split()[6:9] == ['no', '26.10', 'no']
    row = format_row(_report(0, [], 0.0, status=3), FEET, 100 * 10**9)
    assert 'not evaluated: no contacts message received yet' in row
    # Beside the measured wrench's verdict, the quasi-static one; the window is named.
    measured = _report(6400, FEET[1:], -12.5)
    row = format_row(measured, FEET, 100 * 10**9, _report(6400, FEET[1:], 48.25),
                     [('lurch', _ns(6300), _ns(6500))])
    assert row.split()[:11] == ['6.40', '--', 'RF', 'LH', 'RH', '-12.50', 'no', '0.00', 'no',
                                '48.25', 'yes']
    assert row.endswith('<- intended infeasible: lurch')
    row = format_row(measured, FEET, 100 * 10**9, None, [('lurch', _ns(6500), _ns(6600))])
    assert row.split()[-2:] == ['-', '-'] and 'intended' not in row


def test_comparison_counts_infeasible_states_inside_and_outside_the_window():
    windows = [('lurch', _ns(100), _ns(200))]
    reports, quasi = [], QuasiStatic()
    for i in range(300):                     # 1 ms apart, window = i in [100, 200)
        stance = FEET if i < 250 else FEET[1:3]
        reports.append(_report(i, stance, -5.0 if 120 <= i < 180 else 50.0))
        quasi.reports[_ns(i)] = _report(i, stance, -3.0 if i >= 240 else 20.0)
    reports[-1] = _report(299, FEET, 0.0, status=3)      # not evaluated: not counted
    lines = comparison_lines(reports, quasi, windows, 100 * 10**9)
    assert lines[0] == 'intended infeasible window: lurch 0.10-0.20 s'
    assert lines[1] == ('measured wrench (the node): 60 of 300 joint states infeasible; 60 of '
                        'the 100 in the window, 0 elsewhere')
    assert lines[2].endswith('60 of 300 joint states infeasible; 0 of the 100 in the window, '
                             '60 elsewhere (10 with 4 feet down, 50 with 2 feet down)')
    assert comparison_lines(reports, None, (), 0) == [
        'measured wrench (the node): 60 of 300 joint states infeasible']


def test_intended_window_of_the_default_bag_is_the_gait_generators():
    bag = default_bag_path()
    gait = generate_gait(load_config('hyq'), GaitParams())
    (name, t0, t1), = gait.infeasible
    info = bag_info(bag)
    first = min(m.timestamp for m in read_bag(bag, topics=['/joint_states']))
    assert intended_windows(bag) == ((name, first + round(t0 * 1e9), first + round(t1 * 1e9)),)
    assert name == 'lurch' and (t0, t1) == pytest.approx((6.3, 6.5))
    assert info.topics['/joint_states'].count == len(gait)
    assert intended_windows(Path(__file__)) == ()


def test_quasi_static_reference_is_the_evaluation_of_the_bags_states():
    # The offline pass pairs each joint state with the contacts and IMU of its stamp; its
    # margins are the evaluator's on the state rebuilt from those messages (orientation
    # from the IMU, joint velocities, no accelerations).
    bag = default_bag_path()
    quasi = QuasiStatic.from_bag(bag, find_parameters_file('hyq'),
                                 overrides={'use_imu': True}, duration_s=1.3)
    assert len(quasi.reports) == 650 and quasi.wall_s > 0.0      # 1.3 s at 500 Hz
    evaluator = FeasibilityEvaluator('hyq', hull_tol=3.0)
    stop = bag_info(bag).start_ns + int(1.3e9)
    contacts = imu = None
    stances = set()
    for msg in read_bag(bag, topics=['/joint_states', '/contacts', '/imu']):
        if msg.timestamp >= stop:
            break
        obj = deserialize_message(msg.data, message_class(msg.msgtype))
        if msg.topic == '/contacts':
            contacts = obj
            continue
        if msg.topic == '/imu':
            imu = obj
            continue
        rep = quasi.get(obj.header.stamp.sec * 10**9 + obj.header.stamp.nanosec)
        assert rep.status <= 1, rep.status_message
        o = imu.orientation
        state = RobotState(joint_positions=dict(zip(obj.name, obj.position.tolist())),
                           joint_velocities=dict(zip(obj.name, obj.velocity.tolist())),
                           base_orientation=[o.x, o.y, o.z, o.w],
                           stance=[f for f, c in zip(contacts.names, contacts.in_contact) if c])
        ref = evaluator.evaluate(state, fws=False)
        assert list(rep.stance_feet) == list(ref.stance)
        assert rep.fwp_margin == pytest.approx(ref.fwp.margin, rel=1e-9, abs=1e-9)
        assert rep.awp_margin == pytest.approx(ref.awp.margin, rel=1e-9, abs=1e-9)
        stances.add(len(ref.stance))
    assert stances == {3, 4}                 # standing, then the crawl's first swing


def test_plot_shades_stance_phases_and_draws_the_margins(tmp_path):
    import matplotlib.image

    reports = [_report(2 * i, FEET if (i // 100) % 2 == 0 else FEET[1:], 150.0 - 100 *
                       ((i // 100) % 2), fws_now=i % 50 == 0, fws_at_ms=2 * (i - i % 50))
               for i in range(400)]
    reports += [_report(800 + 2 * i, ['lf_foot', 'rh_foot'], 180.0, residual=20.0)
                for i in range(100)]
    series = MarginSeries.from_reports(reports, FEET)
    assert np.isfinite(series.fws).sum() == 8 + 100     # every 50th, then every one
    path = plot_margins(series, tmp_path / 'm.png', title='test')
    image = matplotlib.image.imread(path)
    assert image.shape[0] > 600 and image.shape[1] > 1000
    for count in (4, 3, 2):                      # every stance count is shaded
        assert _colour_fraction(image, STANCE_COLOURS[count]) > 0.01, count
    assert _colour_fraction(image, '#1f77b4') > 0.0005   # AWP line
    assert _colour_fraction(image, '#d95f02') > 0.0005   # FWP line
    assert _colour_fraction(image, '#d62728') > 0.001    # outside-FWP bars


def test_plot_shows_the_quasi_static_verdicts_and_the_intended_window(tmp_path):
    import matplotlib.image

    reports = [_report(2 * i, FEET, -20.0 if 200 <= i < 250 else 120.0) for i in range(500)]
    quasi = QuasiStatic({_ns(2 * i): _report(2 * i, FEET, -15.0 if i >= 350 else 140.0)
                         for i in range(500)})
    series = MarginSeries.from_reports(reports, FEET, quasi, [('lurch', _ns(400), _ns(500))])
    assert series.windows == (('lurch', pytest.approx(0.4), pytest.approx(0.5)),)
    assert (~series.feasible).sum() == 50 and (~series.qs_feasible).sum() == 150
    np.testing.assert_array_equal(series.qs_fwp[[0, 349, 350]], [140.0, 140.0, -15.0])
    image = matplotlib.image.imread(plot_margins(series, tmp_path / 'q.png'))
    plain = matplotlib.image.imread(plot_margins(MarginSeries.from_reports(reports, FEET),
                                                 tmp_path / 'p.png'))
    more = {c: _colour_fraction(image, c) - _colour_fraction(plain, c)
            for c in (QUASI_STATIC_COLOUR, WINDOW_COLOUR)}
    assert more[QUASI_STATIC_COLOUR] > 0.002             # its infeasible bars
    assert more[WINDOW_COLOUR] > 0.0005                  # the hatched window
    assert _colour_fraction(image, MEASURED_COLOUR) > 0.001  # its own infeasible bars


def test_demo_judges_the_measured_wrench_feasible_but_in_the_intended_window(tmp_path, ros_env):
    # The whole default bag: crawl, lurch, trot. The node's measured wrench is infeasible
    # exactly in the lurch window; the quasi-static wrench misses it and flags the trot.
    import matplotlib.image

    out = tmp_path / 'out'
    proc = subprocess.run([str(BIN / 'awp_demo'), '-o', str(out)],
                          env=ros_env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert any(line.split()[:3] == ['t', '[s]', 'stance'] for line in lines)
    assert 'quasi-static reference: 5801 joint states' in proc.stdout
    rows = [line for line in lines if re.match(r' *\d+\.\d\d  (LF|--) ', line)]
    assert len(rows) == 59                   # a row every 0.2 s of bag time, 0 to 11.6 s
    lurch = [row for row in rows if row.endswith('<- intended infeasible: lurch')]
    assert [row.split()[0] for row in lurch] == ['6.40']
    assert lurch[0].split()[6:11:2] == ['no', 'no', 'yes']   # in FWP, feasible, quasi-static
    assert ('measured wrench (the node): 100 of 5801 joint states infeasible; 100 of the 100 '
            'in the window, 0 elsewhere') in proc.stdout, proc.stdout[-3000:]
    quasi = next(line for line in lines if line.startswith('quasi-static wrench'))
    hits, window, elsewhere = map(int, re.search(
        r'; (\d+) of the (\d+) in the window, (\d+) elsewhere', quasi).groups())
    assert window == 100 and hits < 50 and elsewhere > 200, quasi   # the trot flagged
    assert f'output bag: {out / "awp_demo.mcap"}' in proc.stdout
    assert f'margin plot: {out / "awp_demo_margins.png"}' in proc.stdout
    info = bag_info(out / 'awp_demo.mcap')
    assert info.topics['/awp_node/report'].count == 5801
    assert info.topics['/joint_states'].count == 5801
    assert {'/contacts', '/imu', '/awp_node/markers', '/awp_node/fws'} <= set(info.topics)
    image = matplotlib.image.imread(out / 'awp_demo_margins.png')
    for count in (4, 3, 2):
        assert _colour_fraction(image, STANCE_COLOURS[count]) > 0.01, count
    assert _colour_fraction(image, QUASI_STATIC_COLOUR) > 0.001
    assert _colour_fraction(image, WINDOW_COLOUR) > 0.0003
    assert 'reports: 5801' in proc.stdout and 'valid: 5801' in proc.stdout


def test_demo_rejects_a_bad_bag_before_starting_the_node(tmp_path, ros_env):
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(b'\x89MCAP0\r\n' + b'\x00' * 50)
    proc = subprocess.run([str(BIN / 'awp_demo'), '--bag', str(bad), '-o', str(tmp_path)],
                          env=ros_env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert 'awp_demo: error:' in proc.stderr and 'truncated or corrupt' in proc.stderr
