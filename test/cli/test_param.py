"""``awp_param``: a running awp_node's parameters listed, read and set over real DDS."""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import pytest
import yaml

from awp_ros.node.launcher import start_node, stop_node

AWP_PARAM = Path(sys.executable).parent / 'awp_param'


@pytest.fixture
def node(ros_env):
    proc = start_node(env=ros_env, robot='hyq', params={'marker_worker': False})
    yield ros_env
    log = stop_node(proc)
    assert 'Traceback' not in log, log


def run(env, *args, timeout_s: float = 60.0) -> subprocess.CompletedProcess:
    return subprocess.run([str(AWP_PARAM), '--timeout', '30', *args], env=env,
                          capture_output=True, text=True, timeout=timeout_s)


def test_list_get_set_and_dump_a_running_node(node):
    env = node
    res = run(env, 'list', '/awp_node', 'torque_limits')
    assert res.returncode == 0, res.stderr
    assert 'torque_limits.lf_kfe_joint' in res.stdout.split()
    assert all(n.startswith('torque_limits.') for n in res.stdout.split())
    res = run(env, 'set', '/awp_node', 'friction_coefficient', '0.5', 'fws_rate_hz', '20')
    assert res.returncode == 0, res.stderr
    res = run(env, 'get', 'awp_node', 'friction_coefficient', 'fws_rate_hz', 'feet')
    assert res.returncode == 0, res.stderr
    got = yaml.safe_load(res.stdout)
    assert got == {'friction_coefficient': 0.5, 'fws_rate_hz': 20.0,   # 20 sent as a double
                   'feet': ['lf_foot', 'rf_foot', 'lh_foot', 'rh_foot']}
    res = run(env, 'set', '/awp_node', 'torque_limits.lf_kfe_joint', '[-100, 120]')
    assert res.returncode == 0, res.stderr
    dump = yaml.safe_load(run(env, 'dump', '/awp_node').stdout)
    values = dump['/awp_node']['ros__parameters']
    assert values['torque_limits.lf_kfe_joint'] == [-100.0, 120.0]
    assert values['friction_coefficient'] == 0.5


def test_rejected_values_unknown_names_and_absent_nodes(node):
    env = node
    res = run(env, 'set', '/awp_node', 'friction_coefficient', '-1')
    assert res.returncode == 2
    assert 'friction_coefficient must be finite and > 0' in res.stderr
    res = run(env, 'get', '/awp_node', 'friction_coeficient')
    assert res.returncode == 2
    assert "no parameter 'friction_coeficient' (did you mean 'friction_coefficient'" \
        in res.stderr
    res = run(env, 'set', '/awp_node', 'friction_coefficient')
    assert res.returncode == 2 and 'NAME VALUE pairs' in res.stderr
    res = subprocess.run([str(AWP_PARAM), '--timeout', '1', 'get', '/no_such_node', 'x'],
                         env=env, capture_output=True, text=True, timeout=60)
    assert res.returncode == 1 and 'did not answer' in res.stderr
