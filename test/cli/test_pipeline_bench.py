"""
pipeline_bench: what it measures over a bag, checked against the bag and the clock.

The counts are checked against the gait the bag was written from (joint states, stance
sizes) and against the FWS schedule documented in :mod:`awp_ros.ros.pipeline`, computed here
from the stamps and stance changes alone; the timings are checked for what a measurement
must satisfy (non-negative, nested stages within the wall time that contains them), never
for a value: the machine is shared.
"""

from __future__ import annotations

from collections import Counter
import json
import subprocess
import sys

import pytest

from awp_ros.cli.pipeline_bench import time_pipeline
from awp_ros.evaluation.evaluator import STAGES
from awp_ros.gait.bag import DEFAULT_START_NS, write_gait_bag
from awp_ros.gait.generator import generate_gait
from awp_ros.gait.params import GaitParams
from awp_ros.robot.config import load_config, load_parameters
from awp_ros.robot.parameters import PipelineParams


@pytest.fixture(scope='module')
def trot(tmp_path_factory):
    gait = generate_gait(load_config('hyq'), GaitParams(
        sequence=('trot',), trot_cycles=1, stand_s=0.2, trot_ramp_s=0.2))
    return gait, write_gait_bag(gait, tmp_path_factory.mktemp('bags') / 'trot.mcap')


def due_fws(stamps, stances, rate_hz: float) -> list[int]:
    """
    Return the stamps at which the FWS is due, by the documented schedule.

    Due at the first joint state, when a period has passed since the schedule's last due
    time (the schedule then moves on by whole periods, or restarts after a gap of more than
    one), and whenever the stance set differs from the one of the latest FWS (which restarts
    the schedule: the next one a period later). Rate 0: every joint state.
    """
    if rate_hz == 0.0:
        return list(stamps)
    period = int(round(1e9 / rate_hz))
    out, next_due, fws_stance = [], None, None
    for ns, stance in zip(stamps, stances):
        if next_due is None or ns >= next_due:
            out.append(ns)
            on_grid = next_due is not None and ns < next_due + period
            next_due = next_due + period if on_grid else ns + period
            fws_stance = stance
        elif stance != fws_stance:
            out.append(ns)
            next_due = ns + period
            fws_stance = stance
    return out


def test_due_fws_schedule_by_hand():
    ms = 10**6
    stamps = [i * 10 * ms for i in range(25)]             # 100 Hz for 240 ms
    stances = ['a'] * 12 + ['b'] * 13                     # a change at 120 ms
    # 10 Hz: 0, 100; the change at 120 restarts: 220.
    assert due_fws(stamps, stances, 10.0) == [0, 100 * ms, 120 * ms, 220 * ms]
    assert due_fws(stamps, stances, 0.0) == stamps


def test_counts_match_the_bag_and_timings_nest_within_the_wall_time(trot):
    gait, bag = trot
    out = time_pipeline(str(bag), 'hyq', repeat=1)
    n = len(gait)
    stamps = [DEFAULT_START_NS + int(round(float(t) * 1e9)) for t in gait.t]
    stances = [tuple(bool(x) for x in row) for row in gait.stance]
    legs = Counter(sum(s) for s in stances)
    params, _ = load_parameters('hyq')
    rate = PipelineParams.from_dict(params).fws_rate_hz
    assert rate > 0.0 and len(set(stances)) >= 3          # the schedule is exercised
    # Every joint state of the bag is timed once; the FWS exactly when due.
    assert out['joint_states'] == n
    expected = due_fws(stamps, stances, rate)
    assert len(set(stances)) - 1 < len(expected) < n
    assert out['fws_computed'] == len(expected)
    # Every four-leg FWS searched its pattern (2, 1, 1, 1) once, by certificates or the kernel.
    stance_at = dict(zip(stamps, stances))
    four = sum(1 for ns in expected if sum(stance_at[ns]) == 4)
    from awp_ros.geometry import kernels
    assert out['fws_search_certified'] + out['fws_search_kernel'] == \
        (four if kernels.ENABLED else 0)
    assert four > 0
    assert 0.0 <= out['fws_search_tested_share'] <= 1.0
    # Stance sizes are those of the gait, and the means by stance size are means of a
    # partition of the joint states with the gait's counts.
    assert set(out['mean_ms_by_stance_legs']) == set(legs) == {2, 4}
    weighted = sum(legs[k] * v for k, v in out['mean_ms_by_stance_legs'].items()) / n
    assert weighted == pytest.approx(out['mean_ms'], rel=1e-9)
    # Timings: each stage is a measured duration inside on_joint_state, so every stage
    # mean is >= 0 and their sum (with the FWS) cannot exceed the wall time containing it.
    stage_means = [out[f'{s}_ms'] for s in STAGES]
    assert all(v >= 0.0 for v in stage_means)
    for s in ('model', 'sets', 'margins', 'regions'):
        assert out[f'{s}_ms'] > 0.0, s                   # real work in every cycle
    assert out['fws_amortised_ms'] > 0.0
    assert sum(stage_means) + out['fws_amortised_ms'] <= out['mean_ms']
    assert 0.0 <= out['rest_ms'] <= out['mean_ms']
    assert 0.0 < out['p50_ms'] and min(out['mean_ms_by_stance_legs'].values()) > 0.0
    # The contact wrench cone of every 4-leg state came from the kernels: searched the first
    # time, then reused or searched again (2-leg cones are 5D: the numpy code, not counted).
    from awp_ros.geometry import kernels
    if kernels.ENABLED:
        assert out['cwc_reused'] + out['cwc_searched'] == legs[4]
        assert out['cwc_searched'] >= 1


def test_cli_prints_a_table_and_one_json_line(trot):
    gait, bag = trot
    proc = subprocess.run([sys.executable, '-m', 'awp_ros.cli.pipeline_bench', str(bag),
                           '--repeat', '2'], capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    out = json.loads(lines[-1])
    assert lines[0].startswith(f'{len(gait)} joint states: ') and 'ms mean' in lines[0]
    assert f'FWS computed {out["fws_computed"]} times' in lines[0]
    # The timed (last) pass starts after a stamp that went back: its schedule is the same.
    assert out['joint_states'] == len(gait)
    stamps = [DEFAULT_START_NS + int(round(float(t) * 1e9)) for t in gait.t]
    stances = [tuple(bool(x) for x in row) for row in gait.stance]
    rate = PipelineParams.from_dict(load_parameters('hyq')[0]).fws_rate_hz
    assert out['fws_computed'] == len(due_fws(stamps, stances, rate))
    for s in STAGES:
        assert any(line.split()[0] == s for line in lines[1:-1]), s


def test_a_parameter_override_computes_the_fws_every_cycle(trot):
    """``-p fws_rate_hz=0``: the FWS of every joint state, amortised over the bag."""
    gait, bag = trot
    every = time_pipeline(str(bag), 'hyq', repeat=1, overrides={'fws_rate_hz': 0.0})
    assert every['fws_computed'] == every['joint_states'] == len(gait)
    # The FWS's median by stance size, for each stance size of the bag; each FWS is part of
    # its joint state's time, so no median exceeds the largest mean by stance size.
    assert set(every['fws_ms_by_stance_legs']) == set(every['mean_ms_by_stance_legs'])
    assert all(0.0 < v for v in every['fws_ms_by_stance_legs'].values())
    assert max(every['fws_ms_by_stance_legs'].values()) <= 2 * max(
        every['mean_ms_by_stance_legs'].values())
    default = time_pipeline(str(bag), 'hyq', repeat=1)
    assert default['fws_computed'] < every['fws_computed']


def test_cli_rejects_an_unknown_parameter_with_its_name(trot):
    _, bag = trot
    proc = subprocess.run([sys.executable, '-m', 'awp_ros.cli.pipeline_bench', str(bag),
                           '--repeat', '1', '-p', 'fws_rate_hzz=0'], capture_output=True,
                          text=True, timeout=180)
    assert proc.returncode == 2
    assert 'fws_rate_hzz' in proc.stderr and 'Traceback' not in proc.stderr


def test_with_the_imu_it_times_the_fws_distance_of_the_lurch():
    """
    ``-p use_imu=true`` feeds the bag's IMU: the default bag's lurch leaves the FWS.

    The joint states whose per-cycle FWS distance was timed are those ``pipeline_cycles`` (the
    replay's feeding) finds outside the FWS with three or more legs.
    """
    from awp_ros.bags.replay import pipeline_cycles
    from awp_ros.gait.bag import default_bag_path
    from awp_ros.ros.pipeline import Pipeline
    out = time_pipeline(str(default_bag_path()), 'hyq', repeat=1, overrides={'use_imu': True})
    params, base_dir = load_parameters('hyq', {'use_imu': True})
    outside = sum(c.result.fws_margin_per_cycle is not None for c in pipeline_cycles(
        Pipeline.from_parameters(params, base_dir=base_dir), default_bag_path()))
    assert out['fws_distance_outside'] == outside >= 90
    assert 0.0 < out['fws_distance_outside_p50_ms'] < out['mean_ms_by_stance_legs'][3]
    assert out['fws_distance_ms'] == pytest.approx(
        out['fws_distance_outside_p50_ms'] * outside / out['joint_states'], rel=1.0)
