r"""
The motion of a legged robot at each joint state, from joint states, an IMU and odometry.

One :class:`MotionEstimator` per robot model is fed time-stamped inputs in arrival order:

- :meth:`MotionEstimator.add_imu`: a ``sensor_msgs/Imu`` reading (REP 145, frame
  ``header.frame_id``), converted at once into base motion (:mod:`~awp_ros.estimation.imu`);
- :meth:`MotionEstimator.add_odometry` (optional): a ``nav_msgs/Odometry`` reading, the
  base orientation in the world and its twist in ``child_frame_id`` = the base;
- :meth:`MotionEstimator.add_joints`: a joint state (positions, velocities if measured),
  which returns the :class:`MotionEstimate` the evaluation of that joint state needs.

For a joint state at stamp :math:`t`, with :math:`\tau_g = \sqrt 2 / (2 \pi f_c)` the lag of
:class:`~awp_ros.estimation.filters.ButterworthDifferentiator`:

.. math::

    \ddot q(t) = \frac{d}{dt} \dot q\ \text{[rad/s^2] (lag } \tau_g),\qquad
    \text{or, without measured velocities:}\quad
    \dot q = \frac{d}{dt} q\ (\tau_g),\ \ddot q = \frac{d}{dt} \dot q\ (2 \tau_g)

- the IMU reading used is the **newest one whose stamp is at or before** :math:`t` (the
  pairing is by stamp, not by arrival), provided it is at most ``max_imu_age_s`` older;
  likewise the odometry reading (``max_odometry_age_s``); a reading arriving after a joint
  state it would have been paired with is not used for it;
- base orientation (world from base, ``[x, y, z, w]``): the IMU's if it gives one, else
  the odometry's (newest at or before the IMU stamp, when the IMU reading is converted),
  else level;
- base twist :math:`[v; \omega]` [m/s, rad/s] in the base frame: :math:`v` from odometry
  (else 0), :math:`\omega` from the IMU (else odometry, else 0);
- base acceleration :math:`[a; \alpha]` [m/s^2, rad/s^2], classical, without gravity, base
  frame: from the IMU (else 0). The gravito-inertial wrench and the bias torques do not
  depend on :math:`v` when :math:`a` is classical, so an IMU alone suffices.

The result is a pure function of the input sequence (no clock is read): the live node and
an offline replay of the same messages in the same order give identical estimates.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass
import math

import numpy as np

from awp_ros.errors import ConfigError, InputError
from awp_ros.estimation.filters import (ButterworthDifferentiator, DEFAULT_CUTOFF_HZ,
                                        DEFAULT_MAX_GAP_S)
from awp_ros.estimation.imu import BaseMotion, ImuConverter, ImuMount
from awp_ros.robot.model import RobotModel
from awp_ros.robot.state import RobotState

__all__ = ['MotionEstimate', 'MotionEstimator', 'OdometryReading', 'fill_motion']

_LEVEL = (0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class OdometryReading:
    """
    One odometry reading (``nav_msgs/Odometry``).

    ``stamp_ns`` [ns], ``orientation`` (4,) ``[x, y, z, w]`` (world from base) or None,
    ``linear_velocity`` and ``angular_velocity`` (3,) [m/s, rad/s] in the base frame
    (``child_frame_id``).
    """

    stamp_ns: int
    orientation: tuple[float, float, float, float] | None
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray


@dataclass(frozen=True)
class MotionEstimate:
    """
    The motion at one joint state (see the module docstring for sources and frames).

    Arrays in the model's joint order: ``joint_positions`` [rad], ``joint_velocities``
    [rad/s], ``joint_accelerations`` [rad/s^2]. Base: ``base_orientation`` (4,)
    ``[x, y, z, w]`` world from base, ``base_twist`` (6,) ``[v; omega]`` [m/s, rad/s] and
    ``base_acceleration`` (6,) ``[a; alpha]`` [m/s^2, rad/s^2] (classical, without
    gravity), both in the base frame. ``imu_stamp_ns`` / ``odometry_stamp_ns``: the
    readings used (None: none); ``orientation_source`` ``'imu'``, ``'given'`` (odometry
    used by the IMU conversion), ``'odometry'`` or ``'level'``; ``velocities_measured``
    whether the joint state had velocities; ``settled`` whether every filter used is past
    its start transient.
    """

    stamp_ns: int
    joint_names: tuple[str, ...]
    joint_positions: np.ndarray
    joint_velocities: np.ndarray
    joint_accelerations: np.ndarray
    base_orientation: np.ndarray
    base_twist: np.ndarray
    base_acceleration: np.ndarray
    imu_stamp_ns: int | None
    odometry_stamp_ns: int | None
    orientation_source: str
    velocities_measured: bool
    settled: bool

    def state_fields(self) -> dict:
        """Return the motion fields of a :class:`RobotState` (plain lists and dicts)."""
        names = self.joint_names
        return {'base_orientation': self.base_orientation.tolist(),
                'base_twist': self.base_twist.tolist(),
                'base_acceleration': self.base_acceleration.tolist(),
                'joint_velocities': dict(zip(names, self.joint_velocities.tolist())),
                'joint_accelerations': dict(zip(names, self.joint_accelerations.tolist()))}

    def to_state(self, **kw) -> RobotState:
        """Return the :class:`RobotState` of this estimate (``kw``: stance, normals, ...)."""
        return RobotState(joint_positions=dict(zip(self.joint_names,
                                                   self.joint_positions.tolist())),
                          **self.state_fields(), **kw)


class MotionEstimator:
    """
    Estimate joint accelerations and base motion at each joint state of one robot.

    :param model: the robot model (joint order, IMU mounting, gravity).
    :param imu_frame: the IMU's frame (``header.frame_id`` of its messages); may be set
        later with :meth:`set_imu_frame`, before the first :meth:`add_imu`.
    :param cutoff_hz: cut-off of the joint differentiators [Hz].
    :param imu_cutoff_hz: cut-off of the angular-velocity differentiator [Hz]
        (default ``cutoff_hz``).
    :param max_gap_s: a differentiator restarts after a larger gap between its samples [s].
    :param max_imu_age_s: an IMU reading older than this at a joint state is not used [s].
    :param max_odometry_age_s: same for odometry [s].
    :param history: IMU and odometry readings kept for the pairing by stamp.
    :raises ConfigError: ``imu_frame`` not in the URDF or not rigidly attached to the base.

    Not thread-safe; feed it from one thread in arrival order.
    """

    def __init__(self, model: RobotModel, *, imu_frame: str | None = None,
                 cutoff_hz: float = DEFAULT_CUTOFF_HZ, imu_cutoff_hz: float | None = None,
                 max_gap_s: float = DEFAULT_MAX_GAP_S, max_imu_age_s: float = 0.05,
                 max_odometry_age_s: float = 0.2, history: int = 32) -> None:
        if not isinstance(history, int) or history < 1:
            raise InputError(f'history must be a positive integer, got {history!r}')
        for name, value in (('max_imu_age_s', max_imu_age_s),
                            ('max_odometry_age_s', max_odometry_age_s)):
            if not (math.isfinite(value) and value >= 0.0):
                raise InputError(f'{name} must be a finite number >= 0, got {value!r}')
        self.model = model
        self.joint_names: tuple[str, ...] = tuple(model.joint_names)
        self._n = len(self.joint_names)
        self.cutoff_hz = float(cutoff_hz)
        self.imu_cutoff_hz = float(cutoff_hz if imu_cutoff_hz is None else imu_cutoff_hz)
        self.max_gap_s = float(max_gap_s)
        self._imu_age_ns = int(round(max_imu_age_s * 1e9))
        self._odom_age_ns = int(round(max_odometry_age_s * 1e9))
        self._gravity = np.array(model.model.gravity.linear, dtype=float)
        self._dv = ButterworthDifferentiator(self._n, self.cutoff_hz, max_gap_s=max_gap_s)
        self._dq = ButterworthDifferentiator(self._n, self.cutoff_hz, max_gap_s=max_gap_s)
        self._imu: ImuConverter | None = None
        self._imus = _History(history)
        self._odoms = _History(history)
        if imu_frame is not None:
            self.set_imu_frame(imu_frame)

    # -- configuration -----------------------------------------------------------------

    @property
    def imu_mount(self) -> ImuMount | None:
        """Return the IMU's mounting, None before :meth:`set_imu_frame`."""
        return None if self._imu is None else self._imu.mount

    def set_imu_frame(self, frame: str) -> None:
        """
        Use the IMU frame ``frame`` (a change restarts the IMU filter and history).

        :raises ConfigError: ``frame`` is not in the URDF or not rigidly attached to the base.
        """
        if self._imu is not None and self._imu.mount.frame == frame:
            return
        mount = ImuMount.from_model(self.model.model, frame)
        self._imu = ImuConverter(mount, gravity=self._gravity, cutoff_hz=self.imu_cutoff_hz,
                                 max_gap_s=self.max_gap_s)
        self._imus.clear()

    def reset(self) -> None:
        """Forget every input (filters, IMU and odometry history)."""
        self._dv.reset()
        self._dq.reset()
        if self._imu is not None:
            self._imu.reset()
        self._imus.clear()
        self._odoms.clear()

    # -- inputs ------------------------------------------------------------------------

    def add_imu(self, stamp_ns: int, orientation, angular_velocity,
                linear_acceleration) -> BaseMotion:
        """
        Add an IMU reading (REP 145) and return the base motion it implies.

        :param stamp_ns: ``header.stamp`` [ns].
        :param orientation: ``[x, y, z, w]`` of the IMU frame in the world, or None when the
            message has none (``orientation_covariance[0] == -1``).
        :param angular_velocity: (3,) [rad/s], IMU frame.
        :param linear_acceleration: (3,) specific force [m/s^2], IMU frame.
        :raises ConfigError: no IMU frame set; :raises InputError: invalid values.
        """
        imu = self._imu
        if imu is None:
            raise ConfigError('add_imu before the IMU frame is known: pass imu_frame or '
                              'call set_imu_frame(header.frame_id)')
        imus = self._imus
        if imus and stamp_ns < imus.last_stamp_ns:
            imus.clear()                       # time went backwards: a new run
        base_orientation = None
        if orientation is None:
            odom = self._odoms.newest_at_or_before(stamp_ns, self._odom_age_ns)
            if odom is not None:
                base_orientation = odom.orientation
        motion = imu.update(stamp_ns, orientation, angular_velocity, linear_acceleration,
                            base_orientation=base_orientation)
        imus.append(motion)
        return motion

    def add_odometry(self, stamp_ns: int, orientation, linear_velocity,
                     angular_velocity) -> OdometryReading:
        """
        Add an odometry reading (``nav_msgs/Odometry``).

        :param stamp_ns: ``header.stamp`` [ns].
        :param orientation: ``pose.pose.orientation`` ``[x, y, z, w]`` (world from base), or
            None if the odometry has no usable orientation.
        :param linear_velocity: ``twist.twist.linear`` (3,) [m/s], base frame.
        :param angular_velocity: ``twist.twist.angular`` (3,) [rad/s], base frame.
        :raises InputError: invalid values.
        """
        quat = None
        if orientation is not None:
            quat = tuple(float(c) for c in _finite(orientation, 4, 'orientation'))
            n = math.sqrt(sum(c * c for c in quat))
            if n == 0.0:
                raise InputError('odometry orientation is a zero quaternion')
            quat = tuple(c / n for c in quat)
        reading = OdometryReading(stamp_ns, quat,
                                  _finite(linear_velocity, 3, 'linear_velocity'),
                                  _finite(angular_velocity, 3, 'angular_velocity'))
        odoms = self._odoms
        if odoms and stamp_ns < odoms.last_stamp_ns:
            odoms.clear()
        odoms.append(reading)
        return reading

    def add_joints(self, stamp_ns: int, q, v=None) -> MotionEstimate:
        """
        Add a joint state and return the motion estimate at its stamp.

        :param stamp_ns: ``header.stamp`` [ns].
        :param q: (n,) joint positions in the model's joint order [rad or m].
        :param v: (n,) joint velocities in the same order [rad/s or m/s], or None if the
            joint state has none (they are then estimated from the positions).
        :raises InputError: wrong lengths or non-finite values.
        """
        q = _finite(q, self._n, 'joint positions')
        if v is not None:
            v = _finite(v, self._n, 'joint velocities')
            if self._dq.stamp_ns is not None:
                self._dq.reset()
            measured = True
        else:
            v = self._dq.update(stamp_ns, q).copy()
            measured = False
        acc = self._dv.update(stamp_ns, v).copy()
        settled = self._dv.settled and (measured or self._dq.settled)
        twist = np.zeros(6)
        base_acc = np.zeros(6)
        imu = self._imus.newest_at_or_before(stamp_ns, self._imu_age_ns)
        odom = self._odoms.newest_at_or_before(stamp_ns, self._odom_age_ns)
        if imu is not None:
            orientation = imu.orientation
            source = imu.orientation_source
            twist[3:] = imu.angular_velocity
            base_acc[:3] = imu.linear_acceleration
            base_acc[3:] = imu.angular_acceleration
            settled = settled and imu.settled
        elif odom is not None and odom.orientation is not None:
            orientation = np.array(odom.orientation)
            source = 'odometry'
        else:
            orientation = np.array(_LEVEL)
            source = 'level'
        if odom is not None:
            twist[:3] = odom.linear_velocity
            if imu is None:
                twist[3:] = odom.angular_velocity
        return MotionEstimate(stamp_ns, self.joint_names, q, v, acc, orientation, twist,
                              base_acc, None if imu is None else imu.stamp_ns,
                              None if odom is None else odom.stamp_ns, source, measured,
                              settled)


def fill_motion(estimator: MotionEstimator, stamp_ns: int, state: RobotState, *,
                measured: bool) -> None:
    """
    Feed a joint state to ``estimator`` and fill ``state``'s orientation (and motion).

    :param stamp_ns: the joint state's stamp [ns].
    :param state: the state of the joint state (positions, velocities when used), filled in
        place: ``base_orientation`` always, and with ``measured`` the base twist and
        acceleration and the joint velocities and accelerations.
    :param measured: whether the evaluation uses the measured motion (else only the
        orientation: quasi-static).

    A state that lacks joints is left as it is (the evaluator names them).
    """
    model = estimator.model
    try:
        q = model.joint_vector(state.joint_positions)
        v = None if state.joint_velocities is None \
            else model.joint_vector(state.joint_velocities)
    except KeyError:
        return
    est = estimator.add_joints(stamp_ns, q, v)
    state.base_orientation = est.base_orientation
    if measured:
        fields = est.state_fields()
        state.base_twist = fields['base_twist']
        state.base_acceleration = fields['base_acceleration']
        state.joint_velocities = fields['joint_velocities']
        state.joint_accelerations = fields['joint_accelerations']


class _History:
    """
    The last ``maxlen`` readings of one input, in stamp order, found by bisection.

    A node lagging behind its joint states holds the readings of its whole lag; the pairing
    costs O(log n), not O(lag).
    """

    def __init__(self, maxlen: int) -> None:
        self.maxlen = maxlen
        self._stamps: list[int] = []
        self._readings: list = []
        self._head = 0

    def __len__(self) -> int:
        return len(self._stamps) - self._head

    @property
    def last_stamp_ns(self) -> int:
        """Return the stamp of the newest reading [ns] (the history must not be empty)."""
        return self._stamps[-1]

    def clear(self) -> None:
        """Forget every reading."""
        self._stamps.clear()
        self._readings.clear()
        self._head = 0

    def append(self, reading) -> None:
        """Add a reading not older than the newest one; drop the oldest beyond ``maxlen``."""
        self._stamps.append(reading.stamp_ns)
        self._readings.append(reading)
        if len(self) > self.maxlen:
            self._head += 1
            if self._head > 64 and 2 * self._head > len(self._stamps):
                del self._stamps[:self._head]
                del self._readings[:self._head]
                self._head = 0

    def newest_at_or_before(self, stamp_ns: int, max_age_ns: int):
        """Return the newest reading with stamp in [stamp - max_age, stamp], else None."""
        i = bisect_right(self._stamps, stamp_ns, self._head) - 1
        if i < self._head or stamp_ns - self._stamps[i] > max_age_ns:
            return None
        return self._readings[i]


def _finite(values, n: int, name: str) -> np.ndarray:
    """Return ``values`` as a new (n,) float array, or raise InputError naming them."""
    try:
        out = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f'{name} must be {n} numbers, got {values!r}') from None
    if out.shape != (n,):
        raise InputError(f'{name} must be {n} numbers, got shape {out.shape}')
    if not np.isfinite(out).all():
        raise InputError(f'{name} are not all finite: {out.tolist()}')
    return out
