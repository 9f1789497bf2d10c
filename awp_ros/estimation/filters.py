r"""
A causal differentiator: a 2nd-order Butterworth low-pass whose state holds the derivative.

The signal :math:`u(t)` (any vector, e.g. joint velocities [rad/s] or a gyro rate [rad/s])
drives the low-pass

.. math::

    (1)\quad H(s) = \frac{\omega_c^2}{s^2 + 2 \zeta \omega_c s + \omega_c^2},\quad
        \omega_c = 2 \pi f_c\ \text{[rad/s]},\quad \zeta = 1 / \sqrt 2\ \text{(Butterworth)}

    (2)\quad \dot x_1 = x_2,\quad \dot x_2 = \omega_c^2 (u - x_1) - 2 \zeta \omega_c x_2

so that :math:`x_1` is the filtered signal and :math:`x_2 = \dot x_1` the filtered derivative,
:math:`s H(s) u`. Between two samples the input is the straight line through them
(first-order hold) and (2) is integrated exactly for any sample interval (stamps in [ns],
irregular spacing allowed): with :math:`r` the slope of the segment, the ramp solution
:math:`x^p = (u - r \tau_g, r)` plus the free response :math:`e^{A\,dt}` of the error.

Lag (group delay at low frequency), checked numerically in the tests:

.. math::

    (3)\quad \tau_g = \frac{2 \zeta}{\omega_c} = \frac{\sqrt 2}{2 \pi f_c}
        \approx \frac{0.225}{f_c}\ \text{[s]}

(7.5 ms at the default :data:`DEFAULT_CUTOFF_HZ` = 30 Hz), within 0.5 % for cut-offs up to a
fifth of the sample rate (above, the hold's own lag shows; it tends to half a sample interval
when :math:`f_c` exceeds the sample rate). At :math:`f \ll f_c` the output is
the true derivative delayed by :math:`\tau_g`: the phase departs from a pure delay by
:math:`(\sqrt 2 / 3) (f / f_c)^3` [rad] and the gain from 1 by :math:`(f / f_c)^4 / 2`
(maximally flat), so the error against the *undelayed* derivative of a sinusoid of
amplitude :math:`A` at :math:`\Omega` is at most about :math:`A \Omega \cdot \Omega \tau_g`.
The first-order hold adds no lag (linear interpolation is symmetric), only a gain
:math:`\approx 1 - (\Omega\,dt)^2 / 12`. A ramp's derivative is exact (no lag), at every
sample from the second one on.

Why this filter: differentiating amplifies noise like :math:`\omega`; a 2nd-order low-pass
makes the differentiator's gain fall again above :math:`f_c` (like :math:`\omega_c^2 /
\omega`), a 1st-order one would leave it flat at :math:`\omega_c`. Butterworth damping is
the maximally flat magnitude, and the smallest lag of the 2nd-order low-passes without gain
peaking (critically damped, same :math:`\omega_c`: :math:`2 / \omega_c`, 41 % more, and a
gain error of order :math:`(f / f_c)^2`). Its step overshoot is :math:`e^{-\pi} \approx
4.3` %. The default 30 Hz balances lag against the differentiated gyro and encoder noise
(the output noise grows like :math:`f_c^{3/2}`); a lower-noise robot may raise it (the lag
error of the dynamic terms is about :math:`2 \pi f \tau_g = \sqrt 2 f / f_c`).

Start and resets: the first sample (or the first after a reset) initialises
:math:`x_1 = u, x_2 = 0` (output 0, :attr:`ButterworthDifferentiator.ready` False); the
second one initialises the state to the ramp through both samples (no start transient for
a ramp). A sample whose stamp is before the previous one (time going backwards, e.g. a
replay restarted) or more than ``max_gap_s`` after it resets the filter and starts again
from that sample; a sample with the same stamp as the previous one is ignored.
"""

from __future__ import annotations

import math

import numpy as np

from awp_ros.errors import InputError

__all__ = ['ButterworthDifferentiator', 'DEFAULT_CUTOFF_HZ', 'DEFAULT_MAX_GAP_S',
           'group_delay']

#: Default cut-off frequency [Hz] of the differentiators.
DEFAULT_CUTOFF_HZ = 30.0
#: Default largest sample interval [s] before a differentiator resets.
DEFAULT_MAX_GAP_S = 0.1

_ZETA = 1.0 / math.sqrt(2.0)


def group_delay(cutoff_hz: float) -> float:
    r"""
    Return the low-frequency lag of the differentiator, equation (3) [s].

    .. math::

        \tau_g = \sqrt 2 / (2 \pi f_c)

    :param cutoff_hz: cut-off frequency :math:`f_c` [Hz].
    """
    return 2.0 * _ZETA / (2.0 * math.pi * cutoff_hz)


class ButterworthDifferentiator:
    """
    Filter and differentiate a vector signal sampled at (possibly irregular) stamps.

    :param size: length of the signal vector.
    :param cutoff_hz: cut-off frequency :math:`f_c` [Hz] of the low-pass (1).
    :param max_gap_s: a sample more than this after the previous one resets the filter [s].
    :param settle_tol: :attr:`settled` turns True once the start transient has decayed
        below this fraction (:attr:`settling_time` after the (re)start).
    :raises InputError: size < 1, cut-off or gap not positive and finite, settle_tol
        not in (0, 1).

    Not thread-safe. :meth:`update` returns a view of the internal state, valid until the
    next call: copy it to keep it.
    """

    def __init__(self, size: int, cutoff_hz: float = DEFAULT_CUTOFF_HZ, *,
                 max_gap_s: float = DEFAULT_MAX_GAP_S, settle_tol: float = 1e-2) -> None:
        if not isinstance(size, int) or size < 1:
            raise InputError(f'size must be a positive integer, got {size!r}')
        for name, value in (('cutoff_hz', cutoff_hz), ('max_gap_s', max_gap_s)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise InputError(f'{name} must be a positive finite number, got {value!r}')
        if not 0.0 < settle_tol < 1.0:
            raise InputError(f'settle_tol must be in (0, 1), got {settle_tol!r}')
        self.size = size
        self.cutoff_hz = float(cutoff_hz)
        self.max_gap_s = float(max_gap_s)
        self._wc = 2.0 * math.pi * self.cutoff_hz
        self.lag = group_delay(self.cutoff_hz)
        #: Time after a (re)start until the transient is below ``settle_tol`` [s].
        self.settling_time = math.log(1.0 / settle_tol) / (_ZETA * self._wc)
        self._max_gap_ns = int(round(self.max_gap_s * 1e9))
        self._settle_ns = int(math.ceil(self.settling_time * 1e9))
        # Rows: x1 (filtered value), x2 (derivative), u_k, u_{k-1}; x_new = M @ Z.
        self._z = np.zeros((4, size))
        self._out = np.zeros((2, size))
        self._m = np.zeros((2, 4))
        self._m_dt_ns = -1
        self._stamp_ns: int | None = None
        self._start_ns = 0
        self._count = 0

    # -- state -------------------------------------------------------------------------

    @property
    def ready(self) -> bool:
        """Return True once two samples since the last (re)start initialised the state."""
        return self._count >= 2

    @property
    def settled(self) -> bool:
        """Return True once :attr:`settling_time` has passed since the last (re)start."""
        return self._count >= 2 and self._stamp_ns - self._start_ns >= self._settle_ns

    @property
    def stamp_ns(self) -> int | None:
        """Return the stamp of the last sample used [ns], None before the first."""
        return self._stamp_ns

    @property
    def value(self) -> np.ndarray:
        """Return the filtered signal :math:`x_1` (a view; copy it to keep it)."""
        return self._z[0]

    @property
    def derivative(self) -> np.ndarray:
        """Return the filtered derivative :math:`x_2` (a view; copy it to keep it)."""
        return self._z[1]

    def reset(self) -> None:
        """Forget every sample: the next one starts the filter again."""
        self._stamp_ns = None
        self._count = 0
        self._z[:] = 0.0

    # -- update ------------------------------------------------------------------------

    def update(self, stamp_ns: int, u: np.ndarray) -> np.ndarray:
        """
        Add the sample ``u`` taken at ``stamp_ns`` and return the derivative estimate.

        :param stamp_ns: sample time [ns] (integer; any epoch, same clock for all samples).
        :param u: (size,) finite sample, in the signal's units.
        :return: (size,) view of the filtered derivative [units/s] (see the class notes).
        """
        z = self._z
        prev = self._stamp_ns
        dt_ns = -1 if prev is None else stamp_ns - prev
        if dt_ns == 0:
            return z[1]
        if dt_ns < 0 or dt_ns > self._max_gap_ns:
            # (Re)start: x1 = u, x2 = 0, both held samples = u.
            z[0] = u
            z[1] = 0.0
            z[2] = u
            z[3] = u
            self._stamp_ns = stamp_ns
            self._start_ns = stamp_ns
            self._count = 1
            return z[1]
        z[3] = z[2]
        z[2] = u
        if self._count == 1:
            # Second sample: the state of the ramp through both samples.
            np.subtract(z[2], z[3], out=z[1])
            z[1] *= 1e9 / dt_ns
            np.multiply(z[1], -self.lag, out=z[0])
            z[0] += z[2]
        else:
            if dt_ns != self._m_dt_ns:
                self._coefficients(dt_ns)
            np.matmul(self._m, z, out=self._out)
            z[:2] = self._out
        self._stamp_ns = stamp_ns
        self._count += 1
        return z[1]

    def _coefficients(self, dt_ns: int) -> None:
        """Set M = [Phi | G_u | G_p] of the exact first-order-hold step of length dt."""
        dt = dt_ns * 1e-9
        wc, tau = self._wc, self.lag
        sigma = _ZETA * wc
        wd = wc * math.sqrt(1.0 - _ZETA * _ZETA)
        e = math.exp(-sigma * dt)
        c, s = math.cos(wd * dt), math.sin(wd * dt)
        p00 = e * (c + s * sigma / wd)
        p01 = e * s / wd
        p10 = -e * s * wc * wc / wd
        p11 = e * (c - s * sigma / wd)
        k = 1.0 / dt
        tk = tau * k
        m = self._m
        m[0, 0], m[0, 1], m[1, 0], m[1, 1] = p00, p01, p10, p11
        # x_new = x^p(dt) + Phi (x - x^p(0)), x^p(0) = (u_p - r tau, r), x^p(dt) = (u - r tau, r)
        # with r = (u - u_p) / dt, written as G_u u + G_p u_p.
        m[0, 2] = 1.0 - tk + p00 * tk - p01 * k
        m[1, 2] = k + p10 * tk - p11 * k
        m[0, 3] = tk - p00 * (1.0 + tk) + p01 * k
        m[1, 3] = -k - p10 * (1.0 + tk) + p11 * k
        self._m_dt_ns = dt_ns
