"""pipeline_bench: the per-joint-state timing of the pipeline over a bag adds up."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from awp_ros.cli.pipeline_bench import time_pipeline
from awp_ros.evaluation.evaluator import STAGES
from awp_ros.gait.bag import write_gait_bag
from awp_ros.gait.generator import GaitParams, generate_gait
from awp_ros.robot.config import load_config


@pytest.fixture(scope='module')
def trot_bag(tmp_path_factory):
    gait = generate_gait(load_config('hyq'), GaitParams(
        sequence=('trot',), trot_cycles=1, stand_s=0.2, trot_ramp_s=0.2))
    return write_gait_bag(gait, tmp_path_factory.mktemp('bags') / 'trot.mcap')


def test_timings_add_up_and_count_every_joint_state(trot_bag):
    out = time_pipeline(str(trot_bag), 'hyq', repeat=1)
    assert out['joint_states'] > 100
    parts = sum(out[f'{s}_ms'] for s in STAGES) + out['fws_amortised_ms'] + out['rest_ms']
    assert parts == pytest.approx(out['mean_ms'], rel=1e-9)
    assert all(out[f'{s}_ms'] > 0.0 for s in STAGES) and out['rest_ms'] > 0.0
    # Standing (4 legs) and the trot's 2-leg phases; the FWS at least at every stance change.
    assert set(out['mean_ms_by_stance_legs']) == {2, 4}
    assert out['fws_computed'] >= 3


def test_cli_prints_a_table_and_one_json_line(trot_bag):
    proc = subprocess.run([sys.executable, '-m', 'awp_ros.cli.pipeline_bench', str(trot_bag),
                           '--repeat', '1'], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert 'ms mean' in lines[0] and json.loads(lines[-1])['joint_states'] > 100
