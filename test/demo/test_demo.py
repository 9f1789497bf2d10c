"""awp_demo: node process + default bag + live table, then an output bag and a margins PNG."""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys
from types import SimpleNamespace

import numpy as np

from awp_ros.bags.reader import bag_info
from awp_ros.demo.plot import MarginSeries, plot_margins, STANCE_COLOURS
from awp_ros.demo.table import format_row, TABLE_HEADER

BIN = Path(sys.executable).parent
FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')


def _colour_fraction(image: np.ndarray, hex_colour: str, tol: float = 0.02) -> float:
    rgb = np.array([int(hex_colour[i:i + 2], 16) / 255 for i in (1, 3, 5)])
    return float((np.abs(image[..., :3] - rgb).max(axis=-1) < tol).mean())


def _report(t_ms: int, stance, fwp: float, *, residual=0.0, status=0, fws_now=True):
    stamp = SimpleNamespace(sec=100 + t_ms // 1000, nanosec=(t_ms % 1000) * 10**6)
    return SimpleNamespace(
        header=SimpleNamespace(stamp=stamp), stance_feet=list(stance), status=status,
        status_message='' if status <= 1 else 'no contacts message received yet',
        awp_margin=3.0 * fwp, fwp_margin=fwp, fws_margin=0.9 * fwp,
        fwp_affine_residual=residual, fwp_feasible=residual == 0.0 and fwp >= 0,
        feasible=residual == 0.0 and fwp >= 0,
        fws_stamp=stamp if fws_now else SimpleNamespace(sec=0, nanosec=0))


def test_table_rows_show_time_stance_margin_and_feasibility():
    assert TABLE_HEADER.split()[:2] == ['t', '[s]'] and 'FWP margin' in TABLE_HEADER
    row = format_row(_report(1500, FEET[:2] + FEET[3:], 41.8), FEET, 100 * 10**9)
    assert row.split() == ['1.50', 'LF', 'RF', '--', 'RH', '41.80', 'yes', '0.00', 'yes']
    row = format_row(_report(5600, ['rf_foot', 'lh_foot'], 184.0, residual=26.1), FEET,
                     100 * 10**9)
    assert row.split()[1:5] == ['--', 'RF', 'LH', '--']
    assert row.split()[6:] == ['no', '26.10', 'no']
    row = format_row(_report(0, [], 0.0, status=3), FEET, 100 * 10**9)
    assert 'not evaluated: no contacts message received yet' in row


def test_plot_shades_stance_phases_and_draws_the_margins(tmp_path):
    import matplotlib.image

    reports = [_report(2 * i, FEET if (i // 100) % 2 == 0 else FEET[1:], 150.0 - 100 *
                       ((i // 100) % 2), fws_now=i % 50 == 0) for i in range(400)]
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


def test_demo_runs_the_node_on_the_default_bag_and_writes_bag_and_png(tmp_path, ros_env):
    import matplotlib.image

    out = tmp_path / 'out'
    proc = subprocess.run([str(BIN / 'awp_demo'), '--duration', '1.5', '-o', str(out)],
                          env=ros_env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert any(line.split()[:3] == ['t', '[s]', 'stance'] for line in lines)
    rows = [line for line in lines if line.strip()[:1].isdigit() and 'LF' in line]
    assert len(rows) >= 5                    # a row every 0.2 s of bag time
    assert f'output bag: {out / "awp_demo.mcap"}' in proc.stdout
    assert f'margin plot: {out / "awp_demo_margins.png"}' in proc.stdout
    info = bag_info(out / 'awp_demo.mcap')
    assert info.topics['/awp_node/report'].count == 750          # 1.5 s at 500 Hz
    assert info.topics['/joint_states'].count == 750
    assert {'/contacts', '/imu', '/awp_node/markers', '/awp_node/fws'} <= set(info.topics)
    image = matplotlib.image.imread(out / 'awp_demo_margins.png')
    assert _colour_fraction(image, STANCE_COLOURS[4]) > 0.01
    assert _colour_fraction(image, STANCE_COLOURS[3]) > 0.01      # the crawl's first swing
    assert 'reports: 750' in proc.stdout and 'valid: 750' in proc.stdout


def test_demo_rejects_a_bad_bag_before_starting_the_node(tmp_path, ros_env):
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(b'\x89MCAP0\r\n' + b'\x00' * 50)
    proc = subprocess.run([str(BIN / 'awp_demo'), '--bag', str(bad), '-o', str(tmp_path)],
                          env=ros_env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert 'awp_demo: error:' in proc.stderr and 'truncated or corrupt' in proc.stderr
