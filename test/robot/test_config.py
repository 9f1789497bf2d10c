"""Tests of awp_ros.robot.config: YAML / ROS-parameter loading and validation."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from awp_ros.errors import ConfigError
from awp_ros.robot.config import (available_configs, check_keys, config_dirs, find_parameters_file,
                                  load_config, read_parameters, RobotConfig, srdf_standing_posture,
                                  urdf_robot_name)
from awp_ros.robot.parameters import ROBOT_KEYS

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


def test_node_keys_are_accepted_and_sections_merge():
    params = {'/**': {'ros__parameters': dict(BASE, marker_rate_hz=30.0, qos_depth=10,
                                              use_sim_time=False)},
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


# -- the schema: minimal configs, unknown keys, limits of unknown joints ---------------------

A1_URDF = 'example-robot-data://a1_description/urdf/a1.urdf'
A1_FEET = ['FL_foot', 'FR_foot', 'RL_foot', 'RR_foot']


def test_a_minimal_config_takes_every_default_of_the_schema(tmp_path):
    path = tmp_path / 'my_a1.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': {'urdf': A1_URDF,
                                                                'feet': A1_FEET}}}))
    cfg = load_config(path)
    # The defaults written here, not read from the schema: what the README promises.
    assert cfg.robot_name == 'a1'                     # the URDF's file name
    assert cfg.friction_coefficient == 0.7 and cfg.contact_normal == (0.0, 0.0, 1.0)
    assert cfg.pyramid_sides == 4 and cfg.leg_joints == {} and cfg.torque_limits == {}
    assert cfg.standing_posture == {}
    defaults = RobotConfig('x', 'y', ('f',))
    for name, spec in ROBOT_KEYS.items():
        if spec.default is not None and name != 'robot_name':
            got = getattr(defaults, name)
            assert (list(got) if isinstance(got, tuple) else got) == spec.default, name
    assert [k for k, spec in ROBOT_KEYS.items() if spec.required] == ['urdf', 'feet']


def test_the_robot_name_defaults_to_the_urdf_name():
    assert urdf_robot_name(A1_URDF) == 'a1'
    assert urdf_robot_name('/some/dir/go1.urdf') == 'go1'
    assert urdf_robot_name('<?xml version="1.0"?>\n<robot name="talos"><link name="a"/>'
                           '</robot>') == 'talos'
    cfg = RobotConfig.from_dict({'urdf': '<robot name="toy"/>', 'feet': ['a']})
    assert cfg.robot_name == 'toy'


@pytest.mark.parametrize(('params', 'match'), [
    ({'friction_coeficient': 0.3}, r"'friction_coeficient' \(did you mean "
                                   r"'friction_coefficient'\?\)"),
    ({'torque_limit': {'j1': 3.0}}, r"'torque_limit' \(did you mean 'torque_limits'\?\)"),
    ({'stale_timout_s': 1.0}, r"did you mean 'stale_timeout_s'"),
    ({'frobnicate': 1}, r"unknown parameter: 'frobnicate'; the known keys"),
    ({'leg_joints': ['a', 'b']}, r'leg_joints must give one value per foot'),
    ({'friction_coefficient.a_foot': 0.5}, r'friction_coefficient is a single value'),
])
def test_unknown_or_misshapen_keys_are_errors_naming_them(params, match):
    with pytest.raises(ConfigError, match=match):
        RobotConfig.from_dict(dict(BASE, **params))


def test_a_typo_in_a_file_names_the_file_and_every_reader_refuses_it(tmp_path):
    path = tmp_path / 'a1.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': {
        'urdf': A1_URDF, 'feet': A1_FEET, 'friction_coeficient': 0.3, 'fws_rate_hx': 3.0}}}))
    with pytest.raises(ConfigError, match=str(path)) as err:
        load_config(path)
    assert "'fws_rate_hx' (did you mean 'fws_rate_hz'" in str(err.value)
    with pytest.raises(ConfigError, match='friction_coeficient'):
        check_keys(read_parameters(path)[0])


def test_torque_limits_of_unknown_or_non_leg_joints_are_errors():
    from awp_ros.robot.model import RobotModel

    base = {'urdf': A1_URDF, 'feet': A1_FEET}
    with pytest.raises(ConfigError, match='torque_limits.FL_calf_jiont: the URDF has no joint '
                                          r".*did you mean 'FL_calf_joint'"):
        RobotModel(RobotConfig.from_dict(dict(base, torque_limits={'FL_calf_jiont': 30.0})))
    # A joint of the URDF that drives no foot (here: every leg but FL is left out).
    with pytest.raises(ConfigError, match=r"torque_limits.RR_calf_joint: joint 'RR_calf_joint' "
                                          'drives no foot'):
        RobotModel(RobotConfig.from_dict(dict(base, feet=['FL_foot'],
                                              torque_limits={'RR_calf_joint': 30.0})))
    model = RobotModel(RobotConfig.from_dict(dict(base, torque_limits={'FL_calf_joint': 30.0})))
    assert list(model.legs['FL_foot'].tau_max) == [33.5, 33.5, 30.0]   # URDF effort 33.5


def test_configs_are_found_by_name_or_path_with_or_without_suffix(tmp_path, monkeypatch):
    path = tmp_path / 'a1.yaml'
    path.write_text(yaml.safe_dump({'urdf': A1_URDF, 'feet': A1_FEET}))
    assert find_parameters_file(str(path)) == path
    assert find_parameters_file(path) == path
    monkeypatch.chdir(tmp_path)
    assert find_parameters_file('a1.yaml') == Path('a1.yaml')       # a relative path
    with pytest.raises(ConfigError, match="unknown robot 'hyk' .*did you mean 'hyq'"):
        find_parameters_file('hyk')
    with pytest.raises(ConfigError, match='does not exist'):
        find_parameters_file(str(tmp_path / 'b1.yaml'))


def test_load_config_overrides_robot_keys_per_item():
    cfg = load_config('hyq', overrides={'friction_coefficient': 0.3,
                                        'torque_limits.lf_kfe_joint': 99.0,
                                        'fws_rate_hz': 3.0})
    ref = load_config('hyq')
    assert cfg.friction_coefficient == 0.3
    assert cfg.torque_limits['lf_kfe_joint'] == (-99.0, 99.0)
    assert {k: v for k, v in cfg.torque_limits.items() if k != 'lf_kfe_joint'} == \
        {k: v for k, v in ref.torque_limits.items() if k != 'lf_kfe_joint'}
    with pytest.raises(ConfigError, match='did you mean'):
        load_config('hyq', overrides={'friction_coeficient': 0.3})


def test_the_srdf_standing_state_beside_a_urdf():
    from awp_ros.robot.model import resolve_urdf, RobotModel

    cfg = RobotConfig.from_dict({'urdf': A1_URDF, 'feet': A1_FEET})
    model = RobotModel(cfg)
    posture, srdf = srdf_standing_posture(resolve_urdf(cfg.urdf)[1], model.joint_names)
    # a1.srdf's <group_state name="standing">, written here by hand.
    expected = {f'{leg}_{j}_joint': v for leg in ('FL', 'FR', 'RL', 'RR')
                for j, v in (('hip', 0.0), ('thigh', 0.8), ('calf', -1.81))}
    assert posture == expected and srdf.name == 'a1.srdf'
    assert srdf_standing_posture(resolve_urdf(cfg.urdf)[1], ['no_such_joint']) is None
