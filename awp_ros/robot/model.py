r"""
The Pinocchio model of a legged robot and its per-cycle kinematic/dynamic quantities.

The base is a free flyer placed at the world origin with the measured orientation (the
margins do not depend on the base position). For a state :math:`(q, \dot q, \ddot q)`:

.. math::

    (1)\quad \tau = \underbrace{M_b^T \ddot q_b + M \ddot q + c + g}_{\text{bias}
        = \mathrm{rnea}(q, \dot q, \ddot q)} - \sum_k J_k^T f_k
    \qquad \text{(seed eq. 1)}

    (2)\quad w = \begin{bmatrix} m (\ddot c - g) \\ \dot L \end{bmatrix}
        = \dot h_G - \begin{bmatrix} m g \\ 0 \end{bmatrix}

with :math:`J_k` (3 x n_k) the translational LOCAL_WORLD_ALIGNED Jacobian of foot k
w.r.t. its leg's joints and :math:`\dot h_G` the centroidal momentum rate (world axes,
about the CoM). Foot positions are returned relative to the CoM, world axes [m].
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
import importlib.metadata
import os
from pathlib import Path
import site
import sys
import sysconfig

import numpy as np
import pinocchio as pin

from awp_ros.errors import ConfigError, ModelError
from awp_ros.robot.config import RobotConfig

__all__ = ['RobotModel', 'LegInfo', 'Kinematics', 'resolve_urdf',
           'example_robot_data_dirs']

_ERD_SCHEME = 'example-robot-data://'
_ERD_SHARE = ('share', 'example-robot-data')


def example_robot_data_dirs() -> list[Path]:
    """
    Return the ``share/example-robot-data`` folders found on this machine.

    Looked up, in order: the installed ``example-robot-data`` distribution (its cmeel
    prefix), ``cmeel.prefix`` in every site-packages folder, ``<prefix>/share`` of
    ``sys.prefix``, ``$AMENT_PREFIX_PATH``, ``$CMAKE_PREFIX_PATH`` and /opt/openrobots.
    """
    candidates: list[Path] = []
    try:
        dist = importlib.metadata.distribution('example-robot-data')
        candidates.append(Path(dist.locate_file('cmeel.prefix')).joinpath(*_ERD_SHARE))
    except importlib.metadata.PackageNotFoundError:
        pass
    sites = [sysconfig.get_paths().get(k) for k in ('purelib', 'platlib')]
    try:
        sites += site.getsitepackages()
    except AttributeError:  # some virtualenv flavours lack it
        pass
    sites += sys.path
    candidates += [Path(s, 'cmeel.prefix', *_ERD_SHARE) for s in sites if s]
    prefixes = [sys.prefix]
    for var in ('AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH'):
        prefixes += [p for p in os.environ.get(var, '').split(os.pathsep) if p]
    prefixes += ['/opt/openrobots', '/usr/local', '/usr']
    candidates += [Path(p, *_ERD_SHARE) for p in prefixes]
    out = []
    for c in candidates:
        if c.is_dir() and c not in out:
            out.append(c)
    return out


def resolve_urdf(urdf: str, base_dir: str | os.PathLike | None = None) -> tuple[str, str]:
    """
    Resolve a config's ``urdf`` entry to ``('xml', text)`` or ``('file', path)``.

    :param urdf: URDF XML, ``example-robot-data://<rel>``, ``file://<path>`` or a path.
    :param base_dir: folder relative paths are relative to (the YAML's folder).
    :raises ConfigError: the file cannot be found (the message names where it looked).
    """
    text = urdf.strip()
    if text.startswith('<'):
        return 'xml', text
    if text.startswith(_ERD_SCHEME):
        rel = text[len(_ERD_SCHEME):].lstrip('/')
        roots = example_robot_data_dirs()
        for root in roots:
            for candidate in (root / 'robots' / rel, root / rel):
                if candidate.is_file():
                    return 'file', str(candidate)
        msg = (f'urdf {urdf!r} not found in example-robot-data '
               f'(searched {[str(r) for r in roots] or "nothing: package not installed"})')
        raise ConfigError(msg)
    if text.startswith('file://'):
        text = text[len('file://'):]
    path = Path(os.path.expanduser(text))
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    if not path.is_file():
        raise ConfigError(f'urdf file {str(path)!r} does not exist')
    return 'file', str(path)


@dataclass(frozen=True)
class LegInfo:
    """Static data of one leg: its foot frame, joints and torque box."""

    foot: str
    frame_id: int
    joints: tuple[str, ...]
    v_idx: np.ndarray        # (n_k,) columns of the leg's joints in v / rows of rnea
    tau_min: np.ndarray      # (n_k,) [N.m]
    tau_max: np.ndarray      # (n_k,) [N.m]


@dataclass
class Kinematics:
    """
    Per-cycle quantities of the stance legs (world axes, origin at the CoM).

    ``p_foot__com`` (K, 3) [m], ``J`` list of (3, n_k) translational Jacobians [m/rad],
    ``bias`` list of (n_k,) [N.m], ``wrench`` (6,) gravito-inertial wrench [N, N.m].
    """

    mass: float
    com: np.ndarray
    wrench: np.ndarray
    p_foot__com: np.ndarray
    J: list
    bias: list


class RobotModel:
    """
    A Pinocchio free-flyer model with the legs of a :class:`RobotConfig`.

    :param config: the robot config.
    :raises ModelError: the URDF cannot be parsed.
    :raises ConfigError: the config does not match the URDF (unknown foot or joint,
        a joint not on its foot's chain, no torque limit).
    """

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        kind, source = resolve_urdf(config.urdf, config.base_dir)
        try:
            if kind == 'xml':
                model = pin.buildModelFromXML(source, pin.JointModelFreeFlyer())
            else:
                model = pin.buildModelFromUrdf(source, pin.JointModelFreeFlyer())
        except Exception as exc:  # noqa: BLE001 -- pinocchio raises plain exceptions
            where = 'robot_description' if kind == 'xml' else repr(source)
            raise ModelError(f'cannot build a model from urdf {where}: {exc}') from exc
        self.model = model
        self.data = model.createData()
        # Joint names in q order (the free flyer is joint 1; 0 is the universe).
        self.joint_names: tuple[str, ...] = tuple(model.names[j] for j in range(2, model.njoints))
        for j in range(2, model.njoints):
            if model.joints[j].nq != 1 or model.joints[j].nv != 1:
                msg = (f'joint {model.names[j]!r} has {model.joints[j].nv} DoF; only '
                       '1-DoF joints (revolute, prismatic) are supported')
                raise ConfigError(msg)
        self._q_index = {model.names[j]: model.joints[j].idx_q for j in range(2, model.njoints)}
        self._v_index = {model.names[j]: model.joints[j].idx_v for j in range(2, model.njoints)}
        self.legs: dict[str, LegInfo] = {foot: self._leg(foot) for foot in config.feet}
        owners: dict[str, str] = {}
        for foot, leg in self.legs.items():
            for name in leg.joints:
                if name in owners:
                    msg = f'joint {name!r} drives both {owners[name]!r} and {foot!r}; ' \
                          'legs must not share joints'
                    raise ConfigError(msg)
                owners[name] = foot
        # Per foot: its frame and its joints' columns, a slice when they are consecutive
        # (a view, not numpy's copy by an index array, in the per-cycle Jacobians).
        self._leg_columns = {foot: (leg.frame_id, _columns(leg.v_idx))
                             for foot, leg in self.legs.items()}
        config.check_joints(self.joint_names, owners)   # limits of unknown joints: errors
        lower = model.lowerPositionLimit[7:]
        upper = model.upperPositionLimit[7:]
        self.position_limits = (lower.copy(), upper.copy())
        self.total_mass = float(sum(inertia.mass for inertia in model.inertias))
        self.standing_q = self._standing_q()
        # Preallocated per-cycle buffers (hoisted out of the hot path).
        self._q = pin.neutral(model)
        self._v = np.zeros(model.nv)
        self._a = np.zeros(model.nv)
        self._mg = np.zeros(6)
        self._mg[:3] = self.total_mass * model.gravity.linear

    # -- construction ------------------------------------------------------------------

    def _leg(self, foot: str) -> LegInfo:
        model = self.model
        if not model.existFrame(foot):
            names = [f.name for f in model.frames if 'foot' in f.name.lower()]
            msg = f'foot frame {foot!r} not in the URDF (frames with "foot": {names})'
            raise ConfigError(msg)
        frame_id = model.getFrameId(foot)
        chain = []
        j = model.frames[frame_id].parentJoint
        while j > 1:  # stop at the free flyer
            chain.append(model.names[j])
            j = model.parents[j]
        chain.reverse()
        joints = tuple(self.config.leg_joints.get(foot, chain))
        for name in joints:
            if name not in self._v_index:
                msg = f'leg_joints.{foot} names unknown joint {name!r}; joints are ' \
                      f'{list(self.joint_names)}'
                raise ConfigError(msg)
            if name not in chain:
                msg = f'joint {name!r} is not on the chain of foot {foot!r} ({chain})'
                raise ConfigError(msg)
        if not joints:
            raise ConfigError(f'foot {foot!r} has no actuated joint between it and the base')
        lo = np.empty(len(joints))
        hi = np.empty(len(joints))
        for i, name in enumerate(joints):
            if name in self.config.torque_limits:
                lo[i], hi[i] = self.config.torque_limits[name]
            else:
                effort = float(model.effortLimit[self._v_index[name]])
                if not (np.isfinite(effort) and 0.0 < effort < 1e300):
                    msg = f'joint {name!r} has no URDF effort limit; set torque_limits.{name}'
                    raise ConfigError(msg)
                lo[i], hi[i] = -effort, effort
        v_idx = np.array([self._v_index[n] for n in joints], dtype=int)
        return LegInfo(foot, frame_id, joints, v_idx, lo, hi)

    def _standing_q(self) -> np.ndarray | None:
        posture = self.config.standing_posture
        if not posture:
            return None
        unknown = sorted(set(posture) - set(self.joint_names))
        if unknown:
            msg = f'standing_posture names unknown joints {unknown}; joints are ' \
                  f'{list(self.joint_names)}'
            raise ConfigError(msg)
        missing = [n for n in self.joint_names if n not in posture]
        if missing:
            raise ConfigError(f'standing_posture lacks joints {missing}')
        return np.array([posture[n] for n in self.joint_names])

    @property
    def root_link(self) -> str:
        """Return the URDF root link: the body fixed to the free flyer (e.g. ``base_link``)."""
        for frame in self.model.frames:
            if frame.parentJoint == 1 and frame.type == pin.FrameType.BODY:
                return frame.name
        return ''

    # -- per cycle ---------------------------------------------------------------------

    def joint_vector(self, values: Mapping[str, float]) -> np.ndarray:
        """Return the joint values of a complete name -> value map in q order."""
        return np.array([values[n] for n in self.joint_names], dtype=float)

    def kinematics(self, q_joints: np.ndarray, stance: tuple[str, ...], *,
                   quaternion: np.ndarray | None = None,
                   v: np.ndarray | None = None,
                   a: np.ndarray | None = None) -> Kinematics:
        """
        Update the model and return the stance legs' quantities (equations 1-2).

        :param q_joints: joint positions in ``joint_names`` order [rad or m].
        :param stance: the stance feet, in the order of the outputs.
        :param quaternion: base orientation ``[x, y, z, w]`` (world from base), unit.
        :param v: full generalised velocity (nv,), base part in the base frame.
        :param a: full generalised acceleration (nv,), base part in the base frame.
        """
        model, data, q = self.model, self.data, self._q
        q[3:7] = (0.0, 0.0, 0.0, 1.0) if quaternion is None else quaternion
        q[7:] = q_joints
        dynamic = v is not None or a is not None
        v = self._v if v is None else v
        a = self._a if a is None else a
        tau = pin.rnea(model, data, q, v, a)
        wrench = 0.0 - self._mg                 # (not -mg: no negative zeros)
        # One forward kinematics pass after RNEA's (which leaves data.oMi as it was): the
        # centroidal momentum's (dynamic) or the CoM's fills data.oMi and data.com[0], which
        # the joint Jacobians and frame placements then take as they are.
        if dynamic:
            pin.computeCentroidalMomentumTimeVariation(model, data, q, v, a)
            wrench[:3] += data.dhg.linear
            wrench[3:] += data.dhg.angular
            com = data.com[0].copy()
        else:
            com = pin.centerOfMass(model, data, q, False).copy()
        pin.computeJointJacobians(model, data)
        K = len(stance)
        p = np.empty((K, 3))
        J, bias = [], []
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        columns = self._leg_columns
        for k, foot in enumerate(stance):
            frame_id, cols = columns[foot]
            # The stance feet's placements only (data.oMf of the other frames is not read).
            p[k] = pin.updateFramePlacement(model, data, frame_id).translation
            J.append(pin.getFrameJacobian(model, data, frame_id, lwa)[:3, cols])
            bias.append(tau[cols])
        p -= com
        return Kinematics(self.total_mass, com, wrench, p, J, bias)


def _columns(idx: np.ndarray) -> slice | np.ndarray:
    """Return ``idx`` as a slice when its entries are consecutive and increasing, else itself."""
    idx = np.asarray(idx, dtype=int)
    if idx.size and np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size)):
        return slice(int(idx[0]), int(idx[0]) + idx.size)
    return idx
