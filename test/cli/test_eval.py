"""Tests of the awp_eval and awp_bench command-line tools."""

from __future__ import annotations

import io
import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from awp_ros.cli import bench as bench_cli, eval as eval_cli
from awp_ros.evaluation.evaluator import FeasibilityEvaluator

REPO = Path(__file__).resolve().parents[2]


def run_module(module, args, stdin=''):
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(REPO), env.get('PYTHONPATH', '')])
    return subprocess.run([sys.executable, '-m', module, *args], input=stdin, text=True,
                          capture_output=True, cwd=REPO, env=env, timeout=120)


def run_main(monkeypatch, capsys, doc, *args):
    """Run eval_cli.main in-process with ``doc`` on stdin; return (code, stdout, stderr)."""
    text = doc if isinstance(doc, str) else json.dumps(doc)
    monkeypatch.setattr(sys, 'stdin', io.StringIO(text))
    code = eval_cli.main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_subprocess_standing_state_from_stdin_matches_the_library():
    proc = run_module('awp_ros.cli.eval', ['--no-halfspaces'],
                      stdin=json.dumps({'posture': 'standing',
                                        'stance': ['lf_foot', 'rf_foot', 'lh_foot']}))
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    ev = FeasibilityEvaluator('hyq')
    r = ev.evaluate(ev.standing_state(stance=['lf_foot', 'rf_foot', 'lh_foot']))
    for name in ('awp', 'fwp', 'fws'):
        assert d[name]['margin'] == pytest.approx(getattr(r, name).margin, rel=1e-9)
        assert d[name]['dimension'] == 6
    assert d['mass'] == pytest.approx(r.mass)
    assert list(d['legs']) == ['lf_foot', 'rf_foot', 'lh_foot']
    assert len(d['legs']['lf_foot']['force_polytope']['vertices']) == 8
    # The directional margins' values (checked against LPs in test_evaluator.py).
    assert set(d['fws']['directional']) == set(r.fws.directional)
    for axis, (plus, minus) in r.fws.directional.items():
        assert d['fws']['directional'][axis]['plus'] == pytest.approx(plus, rel=1e-9)
        assert d['fws']['directional'][axis]['minus'] == pytest.approx(minus, rel=1e-9)


def test_subprocess_bad_input_exits_2_with_one_line(tmp_path):
    path = tmp_path / 'state.json'
    path.write_text('{"posture": "standing", "joint_positions": {"lf_haa_joint": NaN}}')
    proc = run_module('awp_ros.cli.eval', [str(path)])
    assert proc.returncode == 2 and proc.stdout == ''
    assert proc.stderr.count('\n') == 1
    assert "joint_positions['lf_haa_joint'] is not finite" in proc.stderr
    assert run_module('awp_ros.cli.eval', ['--help']).returncode == 0


def test_explicit_joint_positions_file_and_robot_key(tmp_path, monkeypatch, capsys):
    ev = FeasibilityEvaluator('solo12')
    joints = ev.standing_state().joint_positions
    path = tmp_path / 'solo.json'
    path.write_text(json.dumps({'robot': 'solo12', 'joint_positions': joints,
                                'friction_coefficient': 0.5,
                                'normals': {'FL_FOOT': [0.0, 0.0, 1.0]}}))
    monkeypatch.setattr(sys, 'stdin', io.StringIO(''))
    assert eval_cli.main([str(path), '--no-fws', '--indent', '1']) == 0
    d = json.loads(capsys.readouterr().out)
    assert d['robot'] == 'solo12' and d['fws'] is None
    assert d['legs']['FR_FOOT']['friction_coefficient'] == 0.5
    assert all(len(row) == 7 for row in d['fwp']['halfspaces'])


@pytest.mark.parametrize(('doc', 'needle'), [
    ({'posture': 'standing', 'joint_positions': {'nope_joint': 0.0}}, "['nope_joint']"),
    ({'joint_positions': {'lf_haa_joint': 0.0}}, 'lacks joints'),
    ({}, 'joint_positions is required'),
    ({'posture': 'standing', 'stance': ['lf_foot', 'xx_foot']}, "['xx_foot']"),
    ({'posture': 'standing', 'friction_coefficient': -1}, 'friction_coefficient'),
    ({'posture': 'standing', 'normals': {'lf_foot': [0, 0, 0]}}, "normals['lf_foot']"),
    ({'posture': 'sitting'}, 'posture'),
    ({'posture': 'standing', 'stnace': []}, "['stnace']"),
    ({'robot': 'nosuchbot', 'posture': 'standing'}, "unknown robot 'nosuchbot'"),
    ({'robot': 7, 'posture': 'standing'}, 'robot must be'),
    ('{"posture": ', 'not valid JSON'),
    ('[1, 2]', 'must be a JSON object'),
])
def test_bad_input_exit_code_and_message(monkeypatch, capsys, doc, needle):
    code, out, err = run_main(monkeypatch, capsys, doc)
    assert code == 2 and out == ''
    assert err.startswith('awp_eval: error: ') and err.count('\n') == 1
    assert needle in err


def test_missing_state_file(capsys):
    assert eval_cli.main(['/nonexistent/state.json']) == 2
    assert 'cannot read state file' in capsys.readouterr().err


def test_bench_prints_a_table_and_a_json_line_of_medians(capsys):
    assert bench_cli.main(['-n', '3', '--warmup', '1', '--seed', '1', '--qhull-samples', '0']) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[1].split()[:2] == ['stage', 'median']
    rows = {line.split()[0]: float(line.split()[1]) for line in lines[2:-1]}
    summary = json.loads(lines[-1])
    for key in ('total_ms', 'fws_margin_ms', 'fws_query_lp_ms', 'validate_ms', 'model_ms',
                'sets_ms', 'margins_ms', 'regions_stage_ms', 'fws_ms', 'fws_directional_ms',
                'fws_margin_step_ms'):
        assert summary[key] > 0, key
    assert summary['samples'] == 3 and summary['robot'] == 'hyq'
    assert 'no_fws_ms' not in summary and 'fws_query_lp' in rows
    # total is the per-cycle evaluation: every per-cycle stage, none of the FWS ones.
    per_cycle = sum(rows[s] for s in ('validate', 'model', 'sets', 'margins', 'regions'))
    assert 0.5 * per_cycle <= rows['total'] < per_cycle + rows['fws']
    assert summary['fws_margin_ms'] >= summary['fws_ms']
    assert bench_cli.main(['-n', '2', '--warmup', '0', '--no-fws', '--json-only']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert 'fws_ms' not in summary and 'fws_margin_ms' not in summary
    assert summary['total_ms'] > 0 and summary['sets_ms'] > 0
    assert bench_cli.main(['-n', '0']) == 2
    assert bench_cli.main(['--robot', 'nosuchbot', '-n', '1']) == 2


def test_eval_json_has_the_com_regions(monkeypatch, capsys):
    doc = {'posture': 'standing', 'stance': ['lf_foot', 'rf_foot', 'lh_foot'],
           'base_twist': [0.2, 0.0, 0.0, 0.0, 0.0, 0.0]}
    code, out, err = run_main(monkeypatch, capsys, doc, '--no-halfspaces')
    assert code == 0, err
    got = json.loads(out)
    ev = FeasibilityEvaluator('hyq')
    from awp_ros.cli.eval import state_from_json
    ref = ev.evaluate(state_from_json(doc, ev))
    for name in ('feasible_region', 'support_region', 'fwp_region'):
        region = getattr(ref, name)
        assert got[name]['dimension'] == region.dimension == 2
        assert got[name]['vertices'] == region.vertices.tolist()
        assert got[name]['margin'] == region.margin
    assert got['capture_point_margin'] == ref.capture_point_margin
    assert 'regions' in got['timings_ms'] and 'feasible_region' in got['timings_ms']
    code, out, _ = run_main(monkeypatch, capsys, {'posture': 'standing', 'stance': []},
                            '--no-fws')
    got = json.loads(out)
    assert got['feasible_region'] is None                         # not computed
    assert got['support_region']['vertices'] == [] and got['support_region']['margin'] is None


def test_bench_times_the_regions_and_their_baseline(capsys):
    assert bench_cli.main(['-n', '2', '--warmup', '0', '--baseline-samples', '1',
                           '--qhull-samples', '0']) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    rows = {line.split()[0]: float(line.split()[1]) for line in lines[2:-1]}
    summary = json.loads(lines[-1])
    for key in ('regions_ms', 'regions_baseline_ms', 'regions_stage_ms', 'regions_speedup'):
        assert summary[key] > 0, key
    assert summary['regions_speedup'] == rows['regions_speedup']
    assert summary['regions_speedup'] == pytest.approx(
        rows['regions_baseline'] / rows['com_regions'], rel=0.01)
    times = bench_cli.run_benchmark(FeasibilityEvaluator('hyq'), 3, warmup=0,
                                    baseline_samples=2)
    assert times['com_regions'].shape == (3,) and times['regions_baseline'].shape == (2,)
    # the two CoM regions are part of the per-cycle regions stage, itself part of the total
    assert np.all(times['com_regions'] <= times['regions']) \
        and np.all(times['regions'] <= times['total'])


def test_bench_stream_qhull_ratios_and_kernels(capsys):
    three = ['--stance', 'lf_foot', 'rf_foot', 'lh_foot']       # 512 / ~1300 vertex sums
    assert bench_cli.main(['-n', '3', '--warmup', '0', '--qhull-samples', '1', '--kernels']
                          + three) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    rows = {line.split()[0]: float(line.split()[1]) for line in lines[2:-1]
            if not line.startswith(('kernel ', 'evaluate_many'))}
    summary = json.loads(lines[-1])
    for key in ('total_stream_ms', 'fws_per_cycle_ms', 'awp_qhull_ms', 'fws_qhull_ms'):
        assert summary[key] > 0, key
    assert summary['total_vs_qhull'] == pytest.approx(rows['awp_qhull'] / rows['total'],
                                                      rel=0.01)
    assert summary['fws_vs_qhull'] == pytest.approx(rows['fws_qhull'] / rows['stream_fws'],
                                                    rel=0.01)
    assert set(summary['kernel_ratios']) == {'force parallelepipeds', 'AWP zonotope',
                                             'CWC, new feet every call', 'CWC along a stream',
                                             'support + FWP regions', 'per-cycle evaluation',
                                             'per-cycle evaluation, stream', 'FWS facet search',
                                             'friction-bounded polytopes', 'FWS leg faces',
                                             'FWS directional margins', 'FWS with margins',
                                             'two-leg FWS verdict (LP)',
                                             'FWS directional margins (LPs)'}
    assert all(r > 0 for r in summary['kernel_ratios'].values())
    times = bench_cli.stream_times(FeasibilityEvaluator('hyq'), 4, fws=False)
    assert set(times) == {'stream_total'} and times['stream_total'].shape == (4,)
