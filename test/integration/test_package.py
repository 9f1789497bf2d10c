"""The package manifests: package.xml validates and declares what the code imports."""

from __future__ import annotations

import ast
import re
import subprocess
import sys

from catkin_pkg.package import parse_package
import pytest

# Python module imported by the code -> rosdep key that must be in package.xml.
ROSDEP_KEYS = {
    'rclpy': 'rclpy',
    'numpy': 'python3-numpy',
    'scipy': 'python3-scipy',
    'yaml': 'python3-yaml',
    'pinocchio': 'pinocchio',
    'rosbags': 'python3-rosbags-pip',
    'matplotlib': 'python3-matplotlib',
    'awp_ros_msgs': 'awp_ros_msgs',
    'std_msgs': 'std_msgs',
    'geometry_msgs': 'geometry_msgs',
    'sensor_msgs': 'sensor_msgs',
    'visualization_msgs': 'visualization_msgs',
    'diagnostic_msgs': 'diagnostic_msgs',
    'builtin_interfaces': 'builtin_interfaces',
    'rcl_interfaces': 'rcl_interfaces',
    'threadpoolctl': 'python3-threadpoolctl',
    'nav_msgs': 'nav_msgs',
    'ament_index_python': 'ament_index_python',
}


def _imported_top_modules(paths) -> set[str]:
    names = set()
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names.update(alias.name.split('.')[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split('.')[0])
    return names


def test_package_xml_validates_and_lists_every_run_dependency(repo):
    package = parse_package(str(repo / 'package.xml'))
    package.validate()
    assert package.name == 'awp_ros'
    assert package.package_format == 3
    assert package.get_build_type() == 'ament_python'
    run_keys = {d.name for d in package.exec_depends + package.build_export_depends}
    imported = _imported_top_modules((repo / 'awp_ros').rglob('*.py'))
    assert {'rclpy', 'numpy', 'pinocchio', 'awp_ros_msgs'} <= imported     # it reads them all
    missing = sorted(ROSDEP_KEYS[m] for m in imported if m in ROSDEP_KEYS
                     and ROSDEP_KEYS[m] not in run_keys)
    assert not missing, f'package.xml lacks exec_depend on {missing}'


def test_msgs_package_xml_is_an_interface_package(repo):
    package = parse_package(str(repo / 'msg_defs' / 'package.xml'))
    package.validate()
    assert package.name == 'awp_ros_msgs'
    assert package.get_build_type() == 'ament_cmake'
    assert 'rosidl_interface_packages' in [g.name for g in package.member_of_groups]


def test_one_version_number(repo):
    xml_version = parse_package(str(repo / 'package.xml')).version
    setup_py = (repo / 'setup.py').read_text()
    assert re.search(rf"version = '{re.escape(xml_version)}'", setup_py)
    import awp_ros
    assert awp_ros.__version__ == xml_version


@pytest.mark.parametrize('exe', ['awp_node', 'awp_replay', 'awp_eval', 'awp_bench', 'awp_demo',
                                 'awp_param'])
def test_console_scripts_answer_help(exe):
    bindir = __import__('pathlib').Path(sys.executable).parent
    result = subprocess.run([str(bindir / exe), '--help'], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
    assert 'usage' in result.stdout.lower()


def test_every_message_field_has_a_comment(repo):
    for msg in sorted((repo / 'msg_defs' / 'msg').glob('*.msg')):
        previous = ''
        for line in msg.read_text().splitlines():
            stripped = line.strip()
            if stripped and not stripped.startswith('#'):
                documented = '#' in stripped or previous.startswith('#')
                assert documented, f'{msg.name}: field {stripped!r} has no comment'
            previous = stripped
