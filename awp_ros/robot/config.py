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
Unknown keys are ignored: the node keeps its own parameters in the same file.
"""

from __future__ import annotations

import array
from collections.abc import Mapping
from dataclasses import dataclass, field
import math
import numbers
import os
from pathlib import Path
import sys

import yaml

from awp_ros.errors import ConfigError

__all__ = ['DEFAULT_ROBOT', 'RobotConfig', 'available_configs', 'config_dirs', 'find_config_file',
           'find_parameters_file', 'load_config', 'load_parameters', 'read_parameters',
           'ros_parameters']

DEFAULT_ROBOT = 'hyq'
_ENV_CONFIG_DIR = 'AWP_ROS_CONFIG_DIR'


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
                msg = f'leg_joints names unknown foot {foot!r}; feet are {list(self.feet)}'
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
    def from_dict(cls, params: Mapping, base_dir: str | os.PathLike | None = None
                  ) -> RobotConfig:
        """
        Build a config from parameters, nested or with dotted keys.

        Accepts the whole parameters file (``{'/**': {'ros__parameters': {...}}}``), the
        ``ros__parameters`` mapping itself, or the flat mapping rclpy exposes
        (``{'leg_joints.lf_foot': [...], 'torque_limits.lf_haa_joint': 150.0}``).

        :param params: the parameters.
        :param base_dir: folder that relative URDF paths are relative to.
        :return: the validated config.
        """
        if not isinstance(params, Mapping):
            raise ConfigError(f'robot config must be a mapping, got {type(params).__name__}')
        p = _nest(ros_parameters(params))
        missing = [k for k in ('robot_name', 'urdf', 'feet') if k not in p]
        if missing:
            raise ConfigError(f'robot config lacks required keys {missing}')
        feet = _str_tuple(p['feet'], 'feet')
        leg_joints = {str(foot): _str_tuple(joints, f'leg_joints.{foot}')
                      for foot, joints in _mapping(p.get('leg_joints'), 'leg_joints').items()}
        limits = {str(j): _limit_pair(v, f'torque_limits.{j}')
                  for j, v in _mapping(p.get('torque_limits'), 'torque_limits').items()}
        posture = {str(j): _float(v, f'standing_posture.{j}')
                   for j, v in _mapping(p.get('standing_posture'), 'standing_posture').items()}
        normal = p.get('contact_normal', (0.0, 0.0, 1.0))
        if not _is_array(normal) or len(normal) != 3:
            raise ConfigError(f'contact_normal must be a list of 3 numbers, got {normal!r}')
        sides = p.get('pyramid_sides', 4)
        if isinstance(sides, bool) or not isinstance(sides, numbers.Integral):
            raise ConfigError(f'pyramid_sides must be an integer, got {sides!r}')
        return cls(
            robot_name=str(p['robot_name']),
            urdf=str(p['urdf']),
            feet=feet,
            leg_joints=leg_joints,
            torque_limits=limits,
            friction_coefficient=_float(p.get('friction_coefficient', 0.7),
                                        'friction_coefficient'),
            contact_normal=tuple(_float(x, 'contact_normal') for x in normal),
            pyramid_sides=int(sides),
            standing_posture=posture,
            base_dir=None if base_dir is None else str(base_dir),
        )

    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> RobotConfig:
        """Read a config from a YAML (ROS 2 parameters) file."""
        values, base_dir = read_parameters(path)
        return cls.from_dict(values, base_dir=base_dir)


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
    path = Path(text)
    if path.suffix in ('.yaml', '.yml') or os.sep in text or path.is_file():
        if not path.is_file():
            raise ConfigError(f'robot config file {text!r} does not exist')
        return path
    found = find_config_file(f'{text}.yaml')
    if found is None:
        raise ConfigError(f'unknown robot {text!r}; known robots are {available_configs()}')
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


def load_config(name_or_path: str | os.PathLike = DEFAULT_ROBOT) -> RobotConfig:
    """
    Load a robot config by name (``'hyq'``) or by path to a YAML file.

    :raises ConfigError: no such file or name (the message lists the known names).
    """
    return RobotConfig.from_yaml(find_parameters_file(name_or_path))


# -- helpers -------------------------------------------------------------------------------


def ros_parameters(params: Mapping) -> dict:
    """
    Merge the ``ros__parameters`` sections of a parameters file's mapping.

    A mapping without such a section (the section itself, or rclpy's flat parameters) is
    returned as a copy.
    """
    sections = [v['ros__parameters'] for v in params.values()
                if isinstance(v, Mapping) and isinstance(v.get('ros__parameters'), Mapping)]
    if isinstance(params.get('ros__parameters'), Mapping):
        sections.append(params['ros__parameters'])
    merged: dict = {}
    for section in sections or [params]:
        merged.update(section)
    return merged


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
