"""Tests of awp_ros.robot.config: YAML / ROS-parameter loading and validation."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from awp_ros.errors import ConfigError
from awp_ros.robot.config import available_configs, config_dirs, load_config, RobotConfig

REPO = Path(__file__).resolve().parents[2]
SHIPPED = ['anymal_c', 'go2', 'hyq', 'solo12']

BASE = {
    'robot_name': 'toy',
    'urdf': '/nonexistent.urdf',
    'feet': ['a_foot', 'b_foot'],
}


def test_shipped_configs_are_found_by_name():
    assert set(SHIPPED) <= set(available_configs())
    for name in SHIPPED:
        cfg = load_config(name)
        assert cfg.robot_name == name
        assert len(cfg.feet) == 4
        assert cfg.urdf.startswith('example-robot-data://')


def test_shipped_configs_are_ros_parameter_files_without_empty_containers():
    def walk(node, where):
        assert not (isinstance(node, (dict, list)) and len(node) == 0), where
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f'{where}.{k}')
        elif isinstance(node, list):
            assert len({type(x) for x in node}) == 1, where   # ROS arrays are homogeneous
    for name in SHIPPED:
        data = yaml.safe_load((REPO / 'config' / f'{name}.yaml').read_text())
        assert list(data) == ['/**']
        assert list(data['/**']) == ['ros__parameters']
        walk(data['/**']['ros__parameters'], name)


def test_default_is_hyq_and_solo12_overrides_its_placeholder_effort():
    assert load_config().robot_name == 'hyq'
    solo = load_config('solo12')
    assert set(solo.torque_limits.values()) == {(-2.7, 2.7)}
    assert len(solo.torque_limits) == 12


def test_nested_and_dotted_keys_give_the_same_config():
    nested = dict(BASE, leg_joints={'a_foot': ['j1', 'j2']},
                  torque_limits={'j1': 5.0, 'j2': [-1.0, 3.0]},
                  standing_posture={'j1': 0.1, 'j2': -0.2})
    dotted = dict(BASE, **{'leg_joints.a_foot': ['j1', 'j2'], 'torque_limits.j1': 5.0,
                           'torque_limits.j2': [-1.0, 3.0], 'standing_posture.j1': 0.1,
                           'standing_posture.j2': -0.2})
    wrapped = {'/**': {'ros__parameters': dotted}}
    a = RobotConfig.from_dict(nested)
    assert a == RobotConfig.from_dict(dotted) == RobotConfig.from_dict(wrapped)
    assert a.leg_joints == {'a_foot': ('j1', 'j2')}
    assert a.torque_limits == {'j1': (-5.0, 5.0), 'j2': (-1.0, 3.0)}


def test_unknown_keys_are_ignored_and_sections_merge():
    params = {'/**': {'ros__parameters': dict(BASE, marker_rate_hz=30.0)},
              'awp_node': {'ros__parameters': {'friction_coefficient': 0.4}}}
    cfg = RobotConfig.from_dict(params)
    assert cfg.friction_coefficient == 0.4


def test_yaml_relative_urdf_path_is_relative_to_the_file(tmp_path):
    (tmp_path / 'cfg.yaml').write_text(yaml.safe_dump(dict(BASE, urdf='robot.urdf')))
    cfg = load_config(tmp_path / 'cfg.yaml')
    assert cfg.base_dir == str(tmp_path.resolve())


def test_config_dir_from_environment(tmp_path, monkeypatch):
    (tmp_path / 'mybot.yaml').write_text(yaml.safe_dump({'/**': {'ros__parameters': BASE}}))
    monkeypatch.setenv('AWP_ROS_CONFIG_DIR', str(tmp_path))
    assert config_dirs()[0] == tmp_path
    assert load_config('mybot').robot_name == 'toy'


@pytest.mark.parametrize(('change', 'match'), [
    ({'feet': []}, 'feet'),
    ({'feet': ['a', 'a']}, 'duplicates'),
    ({'friction_coefficient': 0.0}, 'friction_coefficient'),
    ({'friction_coefficient': float('nan')}, 'friction_coefficient'),
    ({'contact_normal': [0.0, 0.0, 0.0]}, 'contact_normal'),
    ({'contact_normal': [0.0, 1.0]}, 'contact_normal'),
    ({'pyramid_sides': 2}, 'pyramid_sides'),
    ({'pyramid_sides': 4.5}, 'pyramid_sides'),
    ({'torque_limits': {'j1': -3.0}}, 'torque_limits.j1'),
    ({'torque_limits': {'j1': [2.0, 1.0]}}, 'torque_limits.j1'),
    ({'torque_limits': {'j1': 'big'}}, 'torque_limits.j1'),
    ({'leg_joints': {'c_foot': ['j1']}}, "unknown foot 'c_foot'"),
    ({'standing_posture': {'j1': float('inf')}}, 'standing_posture.j1'),
])
def test_bad_values_raise_config_error_naming_them(change, match):
    with pytest.raises(ConfigError, match=match):
        RobotConfig.from_dict(dict(BASE, **change))


def test_missing_keys_and_unknown_names_raise():
    with pytest.raises(ConfigError, match='urdf'):
        RobotConfig.from_dict({'robot_name': 'x', 'feet': ['a']})
    with pytest.raises(ConfigError, match="unknown robot 'nosuchbot'"):
        load_config('nosuchbot')
    with pytest.raises(ConfigError, match='does not exist'):
        load_config('/nonexistent/dir/bot.yaml')


def test_bad_yaml_file(tmp_path):
    path = tmp_path / 'bad.yaml'
    path.write_text('a: [1, 2\n')
    with pytest.raises(ConfigError, match='not valid YAML'):
        load_config(path)
    path.write_text('- 1\n- 2\n')
    with pytest.raises(ConfigError, match='mapping'):
        load_config(path)


def test_rclpy_style_flat_parameters_with_array_values():
    import array
    flat = {'robot_name': 'toy', 'urdf': '/x.urdf', 'feet': ['a_foot'],
            'contact_normal': array.array('d', [0.0, 0.0, 2.0]), 'pyramid_sides': 6,
            'leg_joints.a_foot': ['j1', 'j2', 'j3'],
            'torque_limits.j1': array.array('d', [-1.0, 2.0]), 'torque_limits.j2': 3.0}
    cfg = RobotConfig.from_dict(flat)
    assert cfg.unit_normal == (0.0, 0.0, 1.0) and cfg.pyramid_sides == 6
    assert cfg.torque_limits == {'j1': (-1.0, 2.0), 'j2': (-3.0, 3.0)}
    assert cfg.leg_joints == {'a_foot': ('j1', 'j2', 'j3')}


def test_shipped_configs_parse_as_ros_parameter_files_to_the_same_config():
    rclpy_parameter = pytest.importorskip('rclpy.parameter')
    for name in SHIPPED:
        msgs = rclpy_parameter.parameter_dict_from_yaml_file(
            str(REPO / 'config' / f'{name}.yaml'), use_wildcard=True)
        flat = {k: rclpy_parameter.Parameter.from_parameter_msg(v).value
                for k, v in msgs.items()}
        cfg, ref = RobotConfig.from_dict(flat), load_config(name)
        assert (cfg.feet, cfg.leg_joints, cfg.torque_limits, cfg.standing_posture,
                cfg.contact_normal, cfg.friction_coefficient, cfg.pyramid_sides, cfg.urdf) \
            == (ref.feet, ref.leg_joints, ref.torque_limits, ref.standing_posture,
                ref.contact_normal, ref.friction_coefficient, ref.pyramid_sides, ref.urdf)
