"""
Robot configurations: which frames are feet, which joints drive them, their limits.

One YAML file per robot is at the same time a ROS 2 parameters file, so the node runs
with ``--params-file config/hyq.yaml`` and the library reads the same file::

    /**:
      ros__parameters:
        robot_name: hyq
        urdf: example-robot-data://hyq_description/robots/hyq_no_sensors.urdf
        feet: [lf_foot, rf_foot, lh_foot, rh_foot]
        leg_joints:                       # optional: inferred from the kinematic chain
          lf_foot: [lf_haa_joint, lf_hfe_joint, lf_kfe_joint]
        torque_limits: {lf_haa_joint: 150.0}   # optional overrides [N.m]; default URDF effort
        friction_coefficient: 0.7         # [-]
        contact_normal: [0.0, 0.0, 1.0]   # world frame, normalised on load
        pyramid_sides: 4
        standing_posture: {lf_haa_joint: -0.2}  # [rad]

``urdf`` is an ``example-robot-data://`` URI (relative to that package's ``robots/``
folder), a ``file://`` URI, a path (relative paths are relative to the YAML file), or
the URDF XML itself (as the ``robot_description`` parameter carries it). A torque
limit is a scalar ``L`` (the range ``[-L, L]``) or a pair ``[tau_min, tau_max]``.

Only ``urdf`` and ``feet`` are required; every other key has the default of
:data:`ROBOT_KEYS`. The file also holds the node's parameters; the schema of every key of
such a file (:func:`parameter_schema`: these robot keys, the pipeline's and the node's) is
shared by every reader, so a key none of them knows (a typo: ``friction_coeficient``) is an
error naming it and its close matches (:func:`check_keys`), in the core loader, the replay
and the node alike.
"""

from __future__ import annotations

import array
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
import math
import numbers
import os
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ElementTree

import yaml

from awp_ros.errors import ConfigError
from awp_ros.robot.parameters import (close_matches, parameter_schema, ROBOT_KEYS, ROS_KEYS,
                                      ros_parameters)

__all__ = ['DEFAULT_ROBOT', 'RobotConfig', 'available_configs', 'check_keys', 'config_dirs',
           'find_config_file', 'find_parameters_file', 'load_config', 'load_parameters',
           'read_parameters', 'srdf_standing_posture', 'urdf_robot_name']

DEFAULT_ROBOT = 'hyq'
_ENV_CONFIG_DIR = 'AWP_ROS_CONFIG_DIR'


def check_keys(params: Mapping, *, where: str = '', extra: Collection[str] = ()) -> None:
    """
    Check that every key of a parameters mapping is in :func:`parameter_schema`.

    :param params: a parameters file's mapping, its ``ros__parameters`` or flat parameters
        (dotted keys: ``torque_limits.lf_kfe_joint``).
    :param where: what the keys come from (a file name), for the message.
    :param extra: more accepted top-level keys.
    :raises ConfigError: unknown keys (each named with its close matches), a prefixed key
        given as a single value (``leg_joints: [a, b]``) or a plain key given per item.
    """
    schema = parameter_schema()
    known = set(schema) | set(ROS_KEYS) | set(extra)
    nested = _nest(ros_parameters(params))
    at = f' in {where}' if where else ''
    unknown = [k for k in nested if k not in known]
    if unknown:
        listed = ', '.join(f'{k!r}{close_matches(k, known)}' for k in unknown)
        noun = 'parameter' if len(unknown) == 1 else 'parameters'
        raise ConfigError(f'unknown {noun}{at}: {listed}; the known keys are listed in the '
                          "README's parameter tables")
    for key, value in nested.items():
        spec = schema.get(key)
        if spec is None:
            continue
        if spec.item and not isinstance(value, Mapping):
            raise ConfigError(f'{key}{at} must give one value per {spec.item} ({key}.<'
                              f'{spec.item}>, nested in YAML), got {value!r}')
        if not spec.item and isinstance(value, Mapping):
            sub = next(iter(value), '')
            raise ConfigError(f'unknown parameter{at}: {key}.{sub!s} ({key} is a single '
                              'value, not one per foot or joint)')


@dataclass(frozen=True)
class RobotConfig:
    """
    The static description of a legged robot for the feasibility core.

    Frames: ``contact_normal`` is expressed in the world frame (REP 103, z up).
    Units: torque limits [N.m] (or [N] for prismatic joints), postures [rad].
    """

    robot_name: str
    urdf: str
    feet: tuple[str, ...]
    leg_joints: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    torque_limits: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    friction_coefficient: float = 0.7
    contact_normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    pyramid_sides: int = 4
    standing_posture: Mapping[str, float] = field(default_factory=dict)
    base_dir: str | None = None

    def __post_init__(self) -> None:
        """Validate every field (raise ConfigError naming the bad value)."""
        if not isinstance(self.robot_name, str) or not self.robot_name:
            raise ConfigError(f'robot_name must be a non-empty string, got {self.robot_name!r}')
        if not isinstance(self.urdf, str) or not self.urdf.strip():
            raise ConfigError(f'urdf must be a non-empty string, got {self.urdf!r}')
        if not self.feet:
            raise ConfigError(f'feet must list at least one contact frame, got {self.feet!r}')
        if len(set(self.feet)) != len(self.feet):
            raise ConfigError(f'feet contains duplicates: {list(self.feet)}')
        for foot in self.leg_joints:
            if foot not in self.feet:
                msg = (f'leg_joints names unknown foot {foot!r}{close_matches(foot, self.feet)};'
                       f' feet are {list(self.feet)}')
                raise ConfigError(msg)
        mu = self.friction_coefficient
        if not (math.isfinite(mu) and mu > 0.0):
            raise ConfigError(f'friction_coefficient must be finite and > 0, got {mu!r}')
        n = self.contact_normal
        if len(n) != 3 or not all(math.isfinite(x) for x in n) or math.hypot(*n) == 0.0:
            raise ConfigError(f'contact_normal must be a finite non-zero 3-vector, got {n!r}')
        if self.pyramid_sides < 3:
            raise ConfigError(f'pyramid_sides must be >= 3, got {self.pyramid_sides!r}')
        for joint, (lo, hi) in self.torque_limits.items():
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                msg = f'torque_limits.{joint} must be finite with min < max, got {(lo, hi)!r}'
                raise ConfigError(msg)
        for joint, value in self.standing_posture.items():
            if not math.isfinite(value):
                raise ConfigError(f'standing_posture.{joint} must be finite, got {value!r}')

    @property
    def unit_normal(self) -> tuple[float, float, float]:
        """Return the default contact normal normalised to unit length (world frame)."""
        norm = math.hypot(*self.contact_normal)
        x, y, z = (c / norm for c in self.contact_normal)
        return (x, y, z)

    @classmethod
    def from_dict(cls, params: Mapping, base_dir: str | os.PathLike | None = None, *,
                  where: str = '') -> RobotConfig:
        """
        Build a config from parameters, nested or with dotted keys.

        Accepts the whole parameters file (``{'/**': {'ros__parameters': {...}}}``), the
        ``ros__parameters`` mapping itself, or the flat mapping rclpy exposes
        (``{'leg_joints.lf_foot': [...], 'torque_limits.lf_haa_joint': 150.0}``). Keys of
        the pipeline and the node are accepted (and left to them); keys of
        :data:`ROBOT_KEYS` that are absent take their defaults.

        :param params: the parameters.
        :param base_dir: folder that relative URDF paths are relative to.
        :param where: what the parameters come from (a file), for the messages.
        :return: the validated config.
        :raises ConfigError: a required key missing, a key no reader knows (with its close
            matches), a bad value (named).
        """
        if not isinstance(params, Mapping):
            raise ConfigError(f'robot config must be a mapping, got {type(params).__name__}')
        check_keys(params, where=where)
        p = _nest(ros_parameters(params))
        missing = [k for k, spec in ROBOT_KEYS.items() if spec.required and k not in p]
        if missing:
            at = f' {where}' if where else ''
            raise ConfigError(f'robot config{at} lacks required keys {missing} (required: '
                              f'{", ".join(k for k, s in ROBOT_KEYS.items() if s.required)})')
        feet = _str_tuple(p['feet'], 'feet')
        leg_joints = {str(foot): _str_tuple(joints, f'leg_joints.{foot}')
                      for foot, joints in _mapping(p.get('leg_joints'), 'leg_joints').items()}
        limits = {str(j): _limit_pair(v, f'torque_limits.{j}')
                  for j, v in _mapping(p.get('torque_limits'), 'torque_limits').items()}
        posture = {str(j): _float(v, f'standing_posture.{j}')
                   for j, v in _mapping(p.get('standing_posture'), 'standing_posture').items()}
        normal = p.get('contact_normal', ROBOT_KEYS['contact_normal'].default)
        if not _is_array(normal) or len(normal) != 3:
            raise ConfigError(f'contact_normal must be a list of 3 numbers, got {normal!r}')
        sides = p.get('pyramid_sides', ROBOT_KEYS['pyramid_sides'].default)
        if isinstance(sides, bool) or not isinstance(sides, numbers.Integral):
            raise ConfigError(f'pyramid_sides must be an integer, got {sides!r}')
        urdf = p['urdf']
        if not isinstance(urdf, str) or not urdf.strip():
            raise ConfigError(f'urdf must be a non-empty string, got {urdf!r}')
        name = p.get('robot_name') or ''
        if not isinstance(name, str):
            raise ConfigError(f'robot_name must be a string, got {name!r}')
        return cls(
            robot_name=name or urdf_robot_name(urdf),
            urdf=urdf,
            feet=feet,
            leg_joints=leg_joints,
            torque_limits=limits,
            friction_coefficient=_float(p.get('friction_coefficient',
                                              ROBOT_KEYS['friction_coefficient'].default),
                                        'friction_coefficient'),
            contact_normal=tuple(_float(x, 'contact_normal') for x in normal),
            pyramid_sides=int(sides),
            standing_posture=posture,
            base_dir=None if base_dir is None else str(base_dir),
        )

    def check_joints(self, joint_names: Collection[str], leg_joints: Collection[str]) -> None:
        """
        Check the per-joint keys against a model's joints (the model calls it once built).

        :param joint_names: every joint of the model.
        :param leg_joints: the joints that drive a foot.
        :raises ConfigError: ``torque_limits.<joint>`` for a joint the model does not have
            (with its close matches) or that drives no leg.
        """
        legs = list(leg_joints)
        for joint in self.torque_limits:
            if joint not in joint_names:
                raise ConfigError(f'torque_limits.{joint}: the URDF has no joint {joint!r}'
                                  f'{close_matches(joint, joint_names)}; the leg joints are '
                                  f'{legs}')
            if joint not in legs:
                raise ConfigError(f'torque_limits.{joint}: joint {joint!r} drives no foot '
                                  f'(feet {list(self.feet)}), so its limit would not be used; '
                                  f'the leg joints are {legs}')

    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> RobotConfig:
        """Read a config from a YAML (ROS 2 parameters) file."""
        values, base_dir = read_parameters(path)
        return cls.from_dict(values, base_dir=base_dir, where=str(path))


def read_parameters(path: str | os.PathLike) -> tuple[dict, Path]:
    """
    Return the merged ``ros__parameters`` of a parameters file and the file's folder.

    :raises ConfigError: the file cannot be read, is not YAML or holds no mapping.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding='utf-8')
    except OSError as exc:
        raise ConfigError(f'cannot read parameters file {str(path)!r}: {exc}') from exc
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f'parameters file {str(path)!r} is not valid YAML: {exc}') from exc
    if not isinstance(data, Mapping):
        raise ConfigError(f'parameters file {str(path)!r} must hold a mapping')
    return ros_parameters(data), path.resolve().parent


def find_parameters_file(name_or_path: str | os.PathLike = DEFAULT_ROBOT) -> Path:
    """
    Return the parameters file of a robot: a YAML path, or ``<name>.yaml`` in :func:`config_dirs`.

    :raises ConfigError: no such file or name (the message lists the known names).
    """
    text = os.fspath(name_or_path)
    path = Path(os.path.expanduser(text))
    if path.is_file():
        return path
    if path.suffix in ('.yaml', '.yml') or os.sep in text or (os.altsep or os.sep) in text:
        raise ConfigError(f'robot config file {text!r} does not exist')
    found = find_config_file(f'{text}.yaml')
    if found is None:
        known = available_configs()
        raise ConfigError(f'unknown robot {text!r}{close_matches(text, known)}: neither a '
                          f'file nor a config name; known robots are {known}')
    return found


def load_parameters(name_or_path: str | os.PathLike = DEFAULT_ROBOT,
                    overrides: Mapping | None = None) -> tuple[dict, Path]:
    """
    Return a robot's parameters (its file's, then ``overrides``) and the file's folder.

    What ``awp_node --ros-args --params-file FILE -p key:=value`` starts with, for the
    tools that run the node's pipeline without a node (replay, benchmarks).
    """
    values, base_dir = read_parameters(find_parameters_file(name_or_path))
    values.update(overrides or {})
    return values, base_dir


def config_dirs() -> list[Path]:
    """
    Return the folders searched for ``<name>.yaml``, in order.

    ``$AWP_ROS_CONFIG_DIR``, ``<sys.prefix>/share/awp_ros/config``, the ament index
    share folder of ``awp_ros`` when ``ament_index_python`` finds one, then the source
    tree's ``config/`` next to the ``awp_ros`` package.
    """
    dirs = []
    env = os.environ.get(_ENV_CONFIG_DIR)
    if env:
        dirs.append(Path(env))
    dirs.append(Path(sys.prefix) / 'share' / 'awp_ros' / 'config')
    try:
        from ament_index_python.packages import get_package_share_directory
        dirs.append(Path(get_package_share_directory('awp_ros')) / 'config')
    except Exception:  # noqa: BLE001 -- not installed, or awp_ros not in the index
        pass
    dirs.append(Path(__file__).resolve().parents[2] / 'config')
    unique = []
    for d in dirs:
        if d not in unique:
            unique.append(d)
    return unique


def find_config_file(name: str) -> Path | None:
    """Return the first ``<config dir>/<name>`` of :func:`config_dirs` that is a file, or None."""
    for d in config_dirs():
        if (d / name).is_file():
            return d / name
    return None


def available_configs() -> list[str]:
    """Return the robot names found in :func:`config_dirs`, sorted."""
    names = set()
    for d in config_dirs():
        if d.is_dir():
            names.update(p.stem for p in d.glob('*.yaml'))
    return sorted(names)


def load_config(name_or_path: str | os.PathLike = DEFAULT_ROBOT,
                overrides: Mapping | None = None) -> RobotConfig:
    """
    Load a robot config by name (``'hyq'``) or by path to a YAML file.

    :param overrides: parameters whose robot keys replace the file's (per foot or joint
        for the prefixed keys); their other keys are checked against the schema, not used.
    :raises ConfigError: no such file or name (the message lists the known names), or a bad
        config (see :meth:`RobotConfig.from_dict`).
    """
    path = find_parameters_file(name_or_path)
    if not overrides:
        return RobotConfig.from_yaml(path)
    check_keys(overrides)
    values, base_dir = read_parameters(path)
    merged = _nest(values)
    for key, value in _nest(ros_parameters(overrides)).items():
        if key in ROBOT_KEYS:
            if isinstance(value, Mapping) and isinstance(merged.get(key), Mapping):
                merged[key] = {**merged[key], **value}
            else:
                merged[key] = value
    return RobotConfig.from_dict(merged, base_dir=base_dir, where=str(path))


def urdf_robot_name(urdf: str) -> str:
    """
    Return the default robot name of a config's ``urdf``: its file name without extension.

    ``example-robot-data://a1_description/urdf/a1.urdf``: ``a1``; URDF XML: the ``name``
    attribute of its ``<robot>`` element (``robot`` when it has none).
    """
    text = urdf.strip()
    if text.startswith('<'):
        found = re.search(r"""<robot\b[^>]*\bname\s*=\s*["']([^"']+)["']""", text)
        return found.group(1) if found else 'robot'
    return Path(text.split('://', 1)[-1]).stem or 'robot'


def srdf_standing_posture(urdf_path: str | os.PathLike, joint_names: Collection[str],
                          state: str = 'standing') -> tuple[dict[str, float], Path] | None:
    """
    Return the ``state`` group state of the SRDF beside a URDF file, and that SRDF's path.

    Looked up as example-robot-data lays robots out: ``*.srdf`` in the URDF's folder, its
    sibling ``srdf/`` folder, then the parent's ``srdf/``; the first SRDF with a
    ``<group_state name="standing">`` that gives a value to every joint of
    ``joint_names`` wins (other joints, e.g. ``root_joint``, are dropped).

    :return: ``({joint: position [rad]}, srdf path)``, or None when no SRDF has it.
    """
    folder = Path(urdf_path).resolve().parent
    candidates = []
    for where in (folder, folder.parent / 'srdf', folder / 'srdf'):
        if where.is_dir():
            candidates += sorted(where.glob('*.srdf'))
    wanted = set(joint_names)
    for srdf in candidates:
        try:
            root = ElementTree.parse(srdf).getroot()
        except (ElementTree.ParseError, OSError):
            continue
        for group in root.iter('group_state'):
            if group.get('name') != state:
                continue
            values = {}
            for joint in group.iter('joint'):
                name, value = joint.get('name'), (joint.get('value') or '').split()
                if name in wanted and len(value) == 1:
                    try:
                        values[name] = float(value[0])
                    except ValueError:
                        break
            if set(values) == wanted:
                return values, srdf
    return None


# -- helpers -------------------------------------------------------------------------------


def _nest(params: Mapping) -> dict:
    """Turn dotted keys (``'a.b': 1``) into nested dicts (``{'a': {'b': 1}}``)."""
    out: dict = {}
    for key, value in params.items():
        parts = str(key).split('.')
        node = out
        for part in parts[:-1]:
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise ConfigError(f'parameter {key!r} conflicts with parameter {part!r}')
            node = child
        if isinstance(value, Mapping):
            sub = _nest(value)
            existing = node.setdefault(parts[-1], {})
            if not isinstance(existing, dict):
                raise ConfigError(f'parameter {key!r} is given twice')
            existing.update(sub)
        else:
            node[parts[-1]] = value
    return out


def _mapping(value, name: str) -> Mapping:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(f'{name} must be a mapping, got {value!r}')
    return value


def _is_array(value) -> bool:
    """Return True for lists, tuples and the array types rclpy and numpy hand out."""
    return isinstance(value, (list, tuple, array.array)) or (
        hasattr(value, 'tolist') and getattr(value, 'ndim', 0) == 1)


def _str_tuple(value, name: str) -> tuple[str, ...]:
    if not _is_array(value) or not all(isinstance(v, str) and v for v in value):
        raise ConfigError(f'{name} must be a list of names, got {value!r}')
    return tuple(value)


def _float(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(f'{name} must be a number, got {value!r}')
    return float(value)


def _limit_pair(value, name: str) -> tuple[float, float]:
    if _is_array(value):
        value = list(value)
        if len(value) != 2:
            raise ConfigError(f'{name} must be a number or [min, max], got {value!r}')
        return (_float(value[0], name), _float(value[1], name))
    limit = _float(value, name)
    if not limit > 0.0:
        raise ConfigError(f'{name} must be > 0, got {value!r}')
    return (-limit, limit)
