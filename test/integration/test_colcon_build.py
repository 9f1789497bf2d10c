"""
The documented system-ROS build: colcon builds awp_ros_msgs and awp_ros from a workspace.

colcon stops descending at a package, and the repository root is the awp_ros package, so the
README names both package paths. This test runs exactly that on a copy of the repository.
"""

from __future__ import annotations

import os
from pathlib import Path
import shutil
import subprocess
import sys

IGNORED = shutil.ignore_patterns('.venv', 'build', 'install', 'log', '.git', '__pycache__',
                                 '*.egg-info', '.pytest_cache', '.hypothesis', 'out')


def test_colcon_builds_both_packages(repo, tmp_path, ros_env):
    src = tmp_path / 'ws' / 'src' / 'awp_ros'
    shutil.copytree(repo, src, ignore=IGNORED)
    venv = Path(sys.prefix)
    env = dict(ros_env, AMENT_PREFIX_PATH=str(venv), CMAKE_PREFIX_PATH=str(venv),
               PATH=f'{venv / "bin"}{os.pathsep}{ros_env["PATH"]}')
    ws = tmp_path / 'ws'
    result = subprocess.run(
        [str(venv / 'bin' / 'colcon'), 'build', '--paths', 'src/awp_ros', 'src/awp_ros/msg_defs',
         '--cmake-args', '-DBUILD_TESTING=OFF'],
        cwd=ws, env=env, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert 'Summary: 2 packages finished' in result.stdout
    for exe in ('awp_node', 'awp_replay', 'awp_eval', 'awp_bench'):
        assert (ws / 'install/awp_ros/lib/awp_ros' / exe).is_file(), exe
    generated = list((ws / 'install/awp_ros_msgs').rglob(
        'awp_ros_msgs/msg/_feasibility_report.py'))
    assert generated, 'generated Python message module missing'
    assert list((ws / 'install/awp_ros/share/awp_ros/config').glob('*.yaml')) or \
        not list((repo / 'config').glob('*.yaml'))
    # The node's Fast DDS profile (awp_ros.node.dds) is installed beside its module.
    assert list((ws / 'install/awp_ros').rglob('awp_ros/node/fastdds_profile.xml'))
    # The generated module imports and round-trips with the workspace's own build.
    site = generated[0].parents[2]
    check = subprocess.run(
        [sys.executable, '-c',
         'import sys; sys.path.insert(0, sys.argv[1]);'
         'import awp_ros_msgs.msg as m; print(m.__file__)', str(site)],
        env=dict(env, LD_LIBRARY_PATH=f'{ws / "install/awp_ros_msgs/lib"}{os.pathsep}'
                 + env.get('LD_LIBRARY_PATH', '')),
        capture_output=True, text=True, timeout=120)
    assert check.returncode == 0, check.stderr
    assert str(ws) in check.stdout
