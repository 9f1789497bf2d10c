"""
The robot state one evaluation answers, and its validation.

Conventions (SI units):

- ``joint_positions`` / ``joint_velocities`` / ``joint_accelerations``: joint name ->
  [rad], [rad/s], [rad/s^2] (or [m], [m/s], [m/s^2] for prismatic joints). Positions must
  name every joint of the model; velocities and accelerations, when given, too.
- ``joint_efforts``: joint name -> measured (or commanded) torque [N.m] (force [N] for
  prismatic joints), as ``sensor_msgs/JointState.effort``; optional, but when given it
  names every joint. It gives the measured contact forces (not the sets).
- ``base_orientation``: unit quaternion ``[x, y, z, w]`` of the base in the world (ROS
  order), default level ``[0, 0, 0, 1]``.
- ``base_twist``: ``[v; omega]`` [m/s, rad/s] of the base frame, **expressed in the base
  frame** (the ``child_frame_id`` convention of ``nav_msgs/Odometry`` and of an IMU's
  angular rate; Pinocchio's free-flyer velocity).
- ``base_acceleration``: ``[a; alpha]`` [m/s^2, rad/s^2], the classical (not spatial)
  linear acceleration of the base origin without gravity (an IMU's specific force plus
  ``R^T g``) and the angular acceleration, both **expressed in the base frame**; None
  means zero (also when ``base_twist`` is given).
- ``stance``: the feet in contact (any subset of the config's feet, possibly empty);
  ``None`` means all feet.
- ``normals``: foot -> contact normal (world axes, pointing from the ground into the robot);
  default the config's. Non-unit normals are normalised with a warning.
- ``friction_coefficient``: one mu for every stance foot (default the config's);
  ``friction_coefficients``: foot -> mu, taking precedence.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
import math

import numpy as np

from awp_ros.errors import InputError

__all__ = ['RobotState', 'ResolvedState', 'resolve_state']

_PLAIN_NUMBERS = {float, int}   # exact types (bool is not int here): no per-value check


@dataclass
class RobotState:
    """One state of the robot (see the module docstring for frames and units)."""

    joint_positions: Mapping[str, float]
    joint_velocities: Mapping[str, float] | None = None
    joint_accelerations: Mapping[str, float] | None = None
    joint_efforts: Mapping[str, float] | None = None
    base_orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0)
    base_twist: Sequence[float] | None = None
    base_acceleration: Sequence[float] | None = None
    stance: Sequence[str] | None = None
    normals: Mapping[str, Sequence[float]] = field(default_factory=dict)
    friction_coefficient: float | None = None
    friction_coefficients: Mapping[str, float] = field(default_factory=dict)


@dataclass
class ResolvedState:
    """
    A validated state as arrays, in the model's joint order.

    ``q`` (n_j,), ``v`` / ``a`` (6 + n_j,) in Pinocchio's convention (base part in the base
    frame, spatial acceleration) or None, ``quaternion`` (4,) unit ``[x, y, z, w]``,
    ``tau`` (n_j,) measured joint efforts or None,
    ``stance`` the feet in config order, ``normals`` (K, 3) unit, ``mus`` (K,),
    ``warnings`` human-readable notes (normalised inputs, joints beyond their limits).
    """

    q: np.ndarray
    v: np.ndarray | None
    a: np.ndarray | None
    tau: np.ndarray | None
    quaternion: np.ndarray
    stance: tuple[str, ...]
    normals: np.ndarray
    mus: np.ndarray
    warnings: list[str]


def resolve_state(state: RobotState, joint_names: Sequence[str], feet: Sequence[str], *,
                  default_normal: Sequence[float] = (0.0, 0.0, 1.0),
                  default_mu: float = 0.7,
                  position_limits: tuple[np.ndarray, np.ndarray] | None = None,
                  unit_tol: float = 1e-6) -> ResolvedState:
    """
    Validate ``state`` against a model's joints and feet and return arrays.

    :param state: the state.
    :param joint_names: the model's joint names in q order.
    :param feet: the config's feet (the stance is returned in this order).
    :param default_normal: unit contact normal used when a foot has none (world axes).
    :param default_mu: friction coefficient used when none is given [-].
    :param position_limits: optional (lower, upper) joint limits [rad]; positions beyond
        them give a warning, not an error.
    :param unit_tol: normals and quaternions farther than this from unit norm are
        normalised with a warning.
    :raises InputError: NaN/inf, unknown or missing joints, unknown feet, zero normals or
        quaternions, mu <= 0, wrong lengths; the message names the bad value.
    """
    warnings: list[str] = []
    q = _joint_vector(state.joint_positions, joint_names, 'joint_positions')
    if position_limits is not None:
        lo, hi = position_limits
        beyond = np.maximum(lo - q, q - hi)          # > 0 outside [lo, hi] [rad or m]
        if float(beyond.max(initial=-np.inf)) > unit_tol:
            for i in np.flatnonzero(beyond > unit_tol).tolist():
                warnings.append(f'joint {joint_names[i]!r} at {q[i]:.4g} rad is outside its '
                                f'limits [{lo[i]:.4g}, {hi[i]:.4g}]')
    quat = _vector(state.base_orientation, 4, 'base_orientation')
    norm = math.sqrt(float(quat @ quat))
    if norm == 0.0:
        raise InputError('base_orientation is a zero quaternion')
    if abs(norm - 1.0) > unit_tol:
        warnings.append(f'base_orientation had norm {norm:.6g}; normalised')
    if norm != 1.0:
        quat /= norm
    v = a = None
    nj = len(joint_names)
    if state.joint_velocities is not None or state.base_twist is not None:
        v = np.zeros(6 + nj)
        if state.base_twist is not None:
            v[:6] = _vector(state.base_twist, 6, 'base_twist')
        if state.joint_velocities is not None:
            v[6:] = _joint_vector(state.joint_velocities, joint_names, 'joint_velocities')
    if state.joint_accelerations is not None or state.base_acceleration is not None \
            or state.base_twist is not None:
        a = np.zeros(6 + nj)
        if state.base_acceleration is not None:
            a[:6] = _vector(state.base_acceleration, 6, 'base_acceleration')
        if state.base_twist is not None:
            # Classical -> spatial: a_spatial = a_classical - omega x v (base frame); an
            # absent base_acceleration is a classical zero, not a spatial one.
            a[:3] -= np.cross(v[3:6], v[:3])
        if state.joint_accelerations is not None:
            a[6:] = _joint_vector(state.joint_accelerations, joint_names,
                                  'joint_accelerations')
    tau = None if state.joint_efforts is None else _joint_vector(
        state.joint_efforts, joint_names, 'joint_efforts')
    stance = _stance(state.stance, feet)
    normals = np.empty((len(stance), 3))
    normals[:] = _unit_normal(tuple(default_normal))
    if state.normals:
        _check_feet(state.normals, feet, 'normals')
        for k, foot in enumerate(stance):
            if foot in state.normals:
                n = _vector(state.normals[foot], 3, f'normals[{foot!r}]')
                norm = math.sqrt(float(n @ n))
                if norm == 0.0:
                    raise InputError(f'normals[{foot!r}] is the zero vector')
                if abs(norm - 1.0) > unit_tol:
                    warnings.append(f'normals[{foot!r}] had norm {norm:.6g}; normalised')
                normals[k] = n / norm
    elif not isinstance(state.normals, Mapping):
        _check_feet(state.normals, feet, 'normals')
    mu = default_mu
    if state.friction_coefficient is not None:
        mu = _mu(state.friction_coefficient, 'friction_coefficient')
    mus = np.full(len(stance), float(mu))
    if state.friction_coefficients:
        _check_feet(state.friction_coefficients, feet, 'friction_coefficients')
        for k, foot in enumerate(stance):
            if foot in state.friction_coefficients:
                mus[k] = _mu(state.friction_coefficients[foot],
                             f'friction_coefficients[{foot!r}]')
    elif not isinstance(state.friction_coefficients, Mapping):
        _check_feet(state.friction_coefficients, feet, 'friction_coefficients')
    return ResolvedState(q, v, a, tau, quat, stance, normals, mus, warnings)


# -- helpers -------------------------------------------------------------------------------


def _joint_vector(values, joint_names: Sequence[str], name: str) -> np.ndarray:
    if type(values) is dict and len(values) == len(joint_names):
        # Fast path: every joint present, plain numbers, all finite (else the checks below
        # name the problem).
        try:
            raw = [values[j] for j in joint_names]
        except KeyError:
            raw = None
        # Plain numbers whose sum is finite are all finite (inf, nan propagate; a sum that
        # overflows takes the checks below, which then pass).
        if raw is not None and set(map(type, raw)) <= _PLAIN_NUMBERS \
                and math.isfinite(sum(raw)):
            return np.array(raw, dtype=float)
    if not isinstance(values, Mapping):
        raise InputError(f'{name} must map joint names to numbers, got {type(values).__name__}')
    known = set(joint_names)
    unknown = [j for j in values if j not in known]
    if unknown:
        raise InputError(f'{name} names unknown joints {unknown}; joints are '
                         f'{list(joint_names)}')
    missing = [j for j in joint_names if j not in values]
    if missing:
        raise InputError(f'{name} lacks joints {missing}')
    out = np.empty(len(joint_names))
    for i, j in enumerate(joint_names):
        out[i] = _number(values[j], f'{name}[{j!r}]')
    return out


@lru_cache(maxsize=16)
def _unit_normal(normal: tuple) -> np.ndarray:
    """Return ``normal`` (3,) scaled to unit length (read-only; cached: a config's default)."""
    dn = np.asarray(normal, dtype=float)
    unit = dn / math.sqrt(float(dn @ dn))
    unit.setflags(write=False)
    return unit


def _number(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise InputError(f'{name} must be a number, got {value!r}')
    x = float(value)
    if not math.isfinite(x):
        raise InputError(f'{name} is not finite: {x!r}')
    return x


def _vector(value, n: int, name: str) -> np.ndarray:
    # Fast path: a tuple or list of n plain numbers with a finite sum (all finite).
    if type(value) in (tuple, list) and len(value) == n \
            and set(map(type, value)) <= _PLAIN_NUMBERS and math.isfinite(sum(value)):
        return np.array(value, dtype=float)
    if isinstance(value, (str, bytes, Mapping)) or not hasattr(value, '__len__') \
            or len(value) != n:
        raise InputError(f'{name} must be a list of {n} numbers, got {value!r}')
    return np.array([_number(x, f'{name}[{i}]') for i, x in enumerate(value)])


def _stance(stance, feet: Sequence[str]) -> tuple[str, ...]:
    if stance is None:
        return tuple(feet)
    if type(stance) in (tuple, list):         # fast path: known feet, each once
        ordered = tuple(f for f in feet if f in stance)
        if len(ordered) == len(stance):
            return ordered
    if isinstance(stance, (str, bytes, Mapping)) or not hasattr(stance, '__iter__'):
        raise InputError(f'stance must be a list of foot names, got {stance!r}')
    stance = list(stance)
    unknown = [f for f in stance if f not in feet]
    if unknown:
        raise InputError(f'stance names unknown feet {unknown}; feet are {list(feet)}')
    if len(set(stance)) != len(stance):
        raise InputError(f'stance lists a foot twice: {stance}')
    return tuple(f for f in feet if f in stance)


def _check_feet(values, feet: Sequence[str], name: str) -> None:
    if not isinstance(values, Mapping):
        raise InputError(f'{name} must map foot names to values, got {values!r}')
    unknown = [f for f in values if f not in feet]
    if unknown:
        raise InputError(f'{name} names unknown feet {unknown}; feet are {list(feet)}')


def _mu(value, name: str) -> float:
    mu = _number(value, name)
    if mu <= 0.0:
        raise InputError(f'{name} must be > 0, got {mu!r}')
    return mu
