"""
The package's boundary: ``import awp_ros`` is the ROS-free library.

Checked in a fresh interpreter, so that what other tests imported does not hide an import.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

#: The ROS-free subpackages: importing every module of these must not load ROS.
ROS_FREE = ('awp_ros.geometry', 'awp_ros.wrench', 'awp_ros.robot', 'awp_ros.evaluation',
            'awp_ros.estimation')

_PROBE = r"""
import importlib, json, pkgutil, sys
import awp_ros
names = ['awp_ros']
for pkg in sys.argv[1:]:
    mod = importlib.import_module(pkg)
    names.append(pkg)
    for info in pkgutil.iter_modules(mod.__path__, pkg + '.'):
        importlib.import_module(info.name)
        names.append(info.name)
ros = sorted(m for m in sys.modules
             if m.split('.')[0] in ('rclpy', 'rosidl_runtime_py', 'rosbags')
             or m.split('.')[0].endswith('_msgs') or m.split('.')[0].endswith('_srvs'))
print(json.dumps({'imported': names, 'ros': ros}))
"""


def _probe(*packages: str) -> dict:
    out = subprocess.run([sys.executable, '-c', _PROBE, *packages], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_import_awp_ros_loads_no_ros_package():
    assert _probe()['ros'] == []


@pytest.mark.parametrize('package', ROS_FREE)
def test_every_module_of_the_core_subpackages_is_ros_free(package):
    found = _probe(package)
    assert len(found['imported']) > 2, found      # the subpackage has modules, all imported
    assert found['ros'] == [], f'{package} imports ROS: {found["ros"]}'


def test_the_probe_does_see_ros_when_it_is_imported():
    # The check above can fail: importing the ROS side does load rclpy and messages.
    found = _probe('awp_ros.ros')
    assert any(m.endswith('_msgs') for m in found['ros']), found


def test_the_public_api_is_the_library():
    import awp_ros
    for name in awp_ros.__all__:
        assert hasattr(awp_ros, name), name
    assert {'FeasibilityEvaluator', 'FeasibilityResult', 'RobotConfig', 'RobotModel',
            'RobotState', 'Polytope', 'polytope_margin', 'AwpError',
            '__version__'} <= set(awp_ros.__all__)
