r"""
The IMU's mounting on the base (from the URDF) and the base motion one IMU reading implies.

Frames (REP 103 / REP 145): ``w`` the world (z up), ``b`` the base (the model's root link,
the free flyer's frame), ``i`` the IMU frame named by the message's ``header.frame_id``. An
IMU reading holds ``orientation`` (:math:`R_{wi}`, optional: ``orientation_covariance[0] ==
-1`` means none), ``angular_velocity`` :math:`\omega_i` [rad/s] in ``i`` and
``linear_acceleration`` :math:`f_i` [m/s^2] in ``i``, the specific force (at rest, z up:
about :math:`+9.81` on z). The mounting :math:`{}^b M_i = (R_{bi}, r)` is fixed (the IMU frame
must be rigidly attached to the base); :math:`r` [m] is the IMU's position in ``b``.

.. math::

    (1)\quad R_{wb} = R_{wi} R_{bi}^T \qquad
    (2)\quad \omega_b = R_{bi}\, \omega_i\ \text{[rad/s]} \qquad
    (3)\quad \alpha_b = \frac{d \omega_b}{dt}\ \text{[rad/s^2] (filtered, lag } \tau_g)

    (4)\quad a_i = R_{bi} f_i + R_{wb}^T g \qquad
    (5)\quad a_b = a_i - \alpha_b \times r - \omega_b \times (\omega_b \times r)\
        \text{[m/s^2]}

with :math:`g` the model's gravity (world, default :math:`(0, 0, -9.81)`), :math:`a_i` the
classical acceleration of the IMU point and :math:`a_b` that of the base origin, both
expressed in ``b`` and without gravity (the ``base_acceleration`` of
:class:`~awp_ros.robot.state.RobotState`). In (3) the base-frame components may be
differentiated directly: :math:`\dot\omega` is the same in the world and in ``b`` as
:math:`\omega \times \omega = 0`. :math:`\alpha_b` comes from
:class:`~awp_ros.estimation.filters.ButterworthDifferentiator` (lag
:math:`\tau_g = \sqrt 2 / (2 \pi f_c)`); (1), (2), (4) use the reading as it is.
"""

from __future__ import annotations

from dataclasses import dataclass
import difflib
import math

import numpy as np
import pinocchio as pin

from awp_ros.errors import ConfigError, InputError
from awp_ros.estimation.filters import (ButterworthDifferentiator, DEFAULT_CUTOFF_HZ,
                                        DEFAULT_MAX_GAP_S)

__all__ = ['ImuMount', 'BaseMotion', 'ImuConverter']

#: The model's joint of the floating base (0 is the universe).
ROOT_JOINT = 1


@dataclass(frozen=True)
class ImuMount:
    """
    The fixed placement of an IMU frame in the base frame.

    ``frame`` the IMU frame's name, ``base_frame`` the root link's name, ``rotation``
    :math:`R_{bi}` (3, 3) (IMU axes in base axes), ``translation`` :math:`r` (3,) [m], the
    IMU's origin in the base frame, ``quaternion`` :math:`R_{bi}` as ``[x, y, z, w]``.
    """

    frame: str
    base_frame: str
    rotation: np.ndarray
    translation: np.ndarray
    quaternion: np.ndarray

    @classmethod
    def from_model(cls, model: pin.Model, frame: str) -> ImuMount:
        """
        Read the placement of ``frame`` relative to the base from a free-flyer model.

        :param model: a Pinocchio model whose joint 1 is the floating base.
        :param frame: the IMU frame (the IMU message's ``header.frame_id``).
        :raises ConfigError: ``frame`` is not in the URDF (the message lists close names)
            or is not rigidly attached to the base (it names the joint that moves it).
        """
        names = [f.name for f in model.frames]
        if not isinstance(frame, str) or not frame or not model.existFrame(frame):
            close = difflib.get_close_matches(str(frame), names, n=5, cutoff=0.5)
            close += [n for n in names if 'imu' in n.lower() and n not in close]
            raise ConfigError(f'IMU frame {frame!r} is not in the URDF (close frame names: '
                              f'{close})')
        frame_id = model.getFrameId(frame)
        parent = model.frames[frame_id].parentJoint
        if parent != ROOT_JOINT:
            raise ConfigError(f'IMU frame {frame!r} is not rigidly attached to the base: '
                              f'joint {model.names[parent]!r} moves it')
        base_frame = next((f.name for f in model.frames
                           if f.parentJoint == ROOT_JOINT and f.type == pin.FrameType.BODY),
                          model.names[ROOT_JOINT])
        data = model.createData()
        q = pin.neutral(model)
        pin.framesForwardKinematics(model, data, q)
        placement = data.oMi[ROOT_JOINT].actInv(data.oMf[frame_id])
        rotation = placement.rotation.copy()
        quat = pin.Quaternion(rotation).coeffs().copy()   # [x, y, z, w]
        return cls(frame, base_frame, rotation, placement.translation.copy(), quat)


@dataclass(frozen=True)
class BaseMotion:
    r"""
    The base motion implied by one IMU reading (see the module docstring, (1)-(5)).

    ``stamp_ns`` the reading's stamp [ns]; ``orientation`` (4,) :math:`R_{wb}` as
    ``[x, y, z, w]``; ``angular_velocity`` :math:`\omega_b` (3,) [rad/s],
    ``angular_acceleration`` :math:`\alpha_b` (3,) [rad/s^2], ``linear_acceleration``
    :math:`a_b` (3,) [m/s^2] of the base origin without gravity, all in the base frame;
    ``orientation_source`` ``'imu'``, ``'given'`` (the caller's, e.g. odometry) or
    ``'level'``; ``settled`` whether the :math:`\alpha_b` filter is past its start
    transient.
    """

    stamp_ns: int
    orientation: np.ndarray
    angular_velocity: np.ndarray
    angular_acceleration: np.ndarray
    linear_acceleration: np.ndarray
    orientation_source: str
    settled: bool


class ImuConverter:
    """
    Turn IMU readings into base motion, equations (1)-(5).

    :param mount: the IMU's mounting (:meth:`ImuMount.from_model`).
    :param gravity: (3,) gravity in the world [m/s^2] (the model's ``gravity.linear``).
    :param cutoff_hz: cut-off of the angular-velocity differentiator [Hz].
    :param max_gap_s: a reading more than this after the previous one restarts it [s].
    :param unit_tol: quaternions farther than this from unit norm are refused [-].

    Not thread-safe; one converter per IMU stream.
    """

    def __init__(self, mount: ImuMount, *, gravity=(0.0, 0.0, -9.81),
                 cutoff_hz: float = DEFAULT_CUTOFF_HZ, max_gap_s: float = DEFAULT_MAX_GAP_S,
                 unit_tol: float = 1e-3) -> None:
        self.mount = mount
        self.gravity = np.array(gravity, dtype=float)
        self.unit_tol = unit_tol
        self.differentiator = ButterworthDifferentiator(3, cutoff_hz, max_gap_s=max_gap_s)
        # Scalars: the per-reading work is on 3-vectors, cheaper in floats than in numpy.
        self._r_bi = tuple(float(c) for c in np.asarray(mount.rotation).ravel())
        self._r = tuple(float(c) for c in mount.translation)
        self._g = tuple(float(c) for c in self.gravity)
        x, y, z, w = (float(c) for c in mount.quaternion)
        self._q_ib = (-x, -y, -z, w)      # conjugate of q_bi

    def reset(self) -> None:
        """Restart the angular-acceleration filter."""
        self.differentiator.reset()

    def update(self, stamp_ns: int, orientation, angular_velocity, linear_acceleration, *,
               base_orientation=None) -> BaseMotion:
        r"""
        Convert one IMU reading (REP 145) into base motion.

        :param stamp_ns: the reading's stamp [ns].
        :param orientation: ``[x, y, z, w]`` of the IMU frame in the world, or None if the
            IMU gives none (then ``base_orientation`` is used, else the base is taken level).
        :param angular_velocity: (3,) :math:`\omega_i` [rad/s], IMU frame.
        :param linear_acceleration: (3,) specific force :math:`f_i` [m/s^2], IMU frame.
        :param base_orientation: ``[x, y, z, w]`` of the base in the world (e.g. odometry),
            used only when ``orientation`` is None.
        :raises InputError: non-finite values, wrong lengths, zero or non-unit quaternions.
        """
        wx, wy, wz = _vec3(angular_velocity, 'angular_velocity')
        fx, fy, fz = _vec3(linear_acceleration, 'linear_acceleration')
        if orientation is not None:
            qx, qy, qz, qw = self._unit(orientation, 'orientation')
            bx, by, bz, bw = self._q_ib
            # (1): q_wb = q_wi * q_ib (Hamilton product).
            x = qw * bx + qx * bw + qy * bz - qz * by
            y = qw * by - qx * bz + qy * bw + qz * bx
            z = qw * bz + qx * by - qy * bx + qz * bw
            w = qw * bw - qx * bx - qy * by - qz * bz
            source = 'imu'
        elif base_orientation is not None:
            x, y, z, w = self._unit(base_orientation, 'base_orientation')
            source = 'given'
        else:
            x, y, z, w = 0.0, 0.0, 0.0, 1.0
            source = 'level'
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._r_bi
        # (2) omega_b = R_bi omega_i and the specific force in the base frame.
        ox = r00 * wx + r01 * wy + r02 * wz
        oy = r10 * wx + r11 * wy + r12 * wz
        oz = r20 * wx + r21 * wy + r22 * wz
        sx = r00 * fx + r01 * fy + r02 * fz
        sy = r10 * fx + r11 * fy + r12 * fz
        sz = r20 * fx + r21 * fy + r22 * fz
        # (3) alpha_b.
        omega = np.array((ox, oy, oz))
        ax, ay, az = self.differentiator.update(stamp_ns, omega).tolist()
        # (4) R_wb^T g, with R_wb from q_wb (columns c0, c1, c2 of R_wb dotted with g).
        gx, gy, gz = self._g
        gbx = (gx * (1.0 - 2.0 * (y * y + z * z)) + gy * 2.0 * (x * y + w * z)
               + gz * 2.0 * (x * z - w * y))
        gby = (gx * 2.0 * (x * y - w * z) + gy * (1.0 - 2.0 * (x * x + z * z))
               + gz * 2.0 * (y * z + w * x))
        gbz = (gx * 2.0 * (x * z + w * y) + gy * 2.0 * (y * z - w * x)
               + gz * (1.0 - 2.0 * (x * x + y * y)))
        # (5) a_b = a_i - alpha x r - omega (omega . r) + r |omega|^2.
        rx, ry, rz = self._r
        dot = ox * rx + oy * ry + oz * rz
        ww = ox * ox + oy * oy + oz * oz
        acc = np.array((sx + gbx - (ay * rz - az * ry) - ox * dot + rx * ww,
                        sy + gby - (az * rx - ax * rz) - oy * dot + ry * ww,
                        sz + gbz - (ax * ry - ay * rx) - oz * dot + rz * ww))
        return BaseMotion(stamp_ns, np.array((x, y, z, w)), omega, np.array((ax, ay, az)),
                          acc, source, self.differentiator.settled)

    def _unit(self, quaternion, name: str) -> tuple[float, float, float, float]:
        """Return a quaternion as 4 floats, normalised, after checking it is near unit."""
        try:
            x, y, z, w = (float(c) for c in quaternion)
        except (TypeError, ValueError):
            raise InputError(f'{name} must be 4 numbers [x, y, z, w], got {quaternion!r}'
                             ) from None
        n = math.sqrt(x * x + y * y + z * z + w * w)
        if not math.isfinite(n) or abs(n - 1.0) > self.unit_tol:
            raise InputError(f'{name} {quaternion!r} is not a unit quaternion (norm {n!r})')
        return x / n, y / n, z / n, w / n


def _vec3(value, name: str) -> tuple[float, float, float]:
    """Return three finite floats, or raise InputError naming the value."""
    try:
        x, y, z = (float(c) for c in value)
    except (TypeError, ValueError):
        raise InputError(f'{name} must be 3 numbers, got {value!r}') from None
    if not math.isfinite(x + y + z):
        raise InputError(f'{name} is not finite: {value!r}')
    return x, y, z
