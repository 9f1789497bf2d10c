r"""
Time-parametrised curves of the gait generator: rest-to-rest paths, ramps and swings.

Every function is vectorised over the sample times ``t`` [s] (shape (N,)); positions are in
the world frame [m]. The polynomial they share is the quintic smoothstep

.. math::

    S(u) = u^3 (10 - 15 u + 6 u^2), \quad S(0) = 0, S(1) = 1,
    \quad S'(0) = S'(1) = S''(0) = S''(1) = 0,

the minimum-jerk profile between two states at rest.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ['Piecewise', 'min_jerk', 'smoothstep', 'ramp_distance', 'whole', 'swing_foot']


class Piecewise:
    """A function of time [s] made of segments ``[t0, t1)``; constant after the last one."""

    def __init__(self, start: np.ndarray) -> None:
        self.segments: list = []
        self.end = np.asarray(start, dtype=float)

    def add(self, t0: float, t1: float, fn: Callable[[np.ndarray], np.ndarray]) -> None:
        """Append ``fn`` on ``[t0, t1)``; its value at ``t1`` becomes the new end."""
        self.segments.append((t0, t1, fn))
        self.end = fn(np.array([t1]))[0]

    def evaluate(self, t: np.ndarray) -> np.ndarray:
        """Return the values (N, d) at the times ``t`` (N,) [s]."""
        out = np.empty((t.shape[0], self.end.shape[0]))
        out[:] = self.segments[0][2](t[:1])[0] if self.segments else self.end
        for t0, t1, fn in self.segments:
            mask = t >= t0
            out[mask] = fn(np.minimum(t[mask], t1))
        return out


def smoothstep(u: np.ndarray) -> np.ndarray:
    """Return :math:`S(u)` of ``u`` clipped to [0, 1]."""
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (10.0 - 15.0 * u + 6.0 * u ** 2)


def min_jerk(t0: float, t1: float, p0: np.ndarray, p1: np.ndarray
             ) -> Callable[[np.ndarray], np.ndarray]:
    """
    Return the minimum-jerk path from p0 at t0 to p1 at t1 (rest to rest).

    .. math:: p(t) = p_0 + (p_1 - p_0) S((t - t_0) / (t_1 - t_0))
    """
    def fn(t: np.ndarray) -> np.ndarray:
        return p0 + (p1 - p0) * smoothstep((t - t0) / (t1 - t0))[:, None]
    return fn


def whole(duration: float, rate_hz: float) -> float:
    """Round a duration [s] to a whole number of samples of ``rate_hz`` [Hz]."""
    return round(duration * rate_hz) / rate_hz


def ramp_distance(u: np.ndarray, duration: float, ramp: float, speed: float) -> np.ndarray:
    """
    Distance [m] travelled at time u [s] with a quintic speed ramp up and down.

    Speed: ``speed * S(u / ramp)`` up, constant, ``speed * S((duration - u) / ramp)`` down,
    with :math:`S(x) = 10x^3 - 15x^4 + 6x^5`, whose integral is
    :math:`x^6 - 3x^5 + 2.5x^4`.
    """
    def integral(x):
        x = np.clip(x, 0.0, 1.0)
        return x ** 6 - 3.0 * x ** 5 + 2.5 * x ** 4

    u = np.clip(u, 0.0, duration)
    total = speed * (duration - ramp)       # each ramp covers speed * ramp / 2
    up = speed * ramp * integral(u / ramp)
    flat = speed * np.clip(u - ramp, 0.0, duration - 2.0 * ramp)
    down = speed * ramp * (0.5 - integral((duration - u) / ramp))
    down = np.where(u > duration - ramp, down, 0.0)
    return np.minimum(up + flat + down, total)


def swing_foot(u: np.ndarray, p0: np.ndarray, p1: np.ndarray, height: float
               ) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return the swing foot's ground position (n, 2) [m] and height (n,) [m] at phase u.

    A cycloid from ``p0`` to ``p1`` (zero velocity and acceleration at lift-off, u = 0,
    and touch-down, u = 1) and a cosine bump of height ``height`` [m]:

    .. math::

        xy(u) = p_0 + (u - \sin(2 \pi u) / (2 \pi)) (p_1 - p_0), \qquad
        z(u) = h (1 - \cos(2 \pi u)) / 2
    """
    xy = p0 + np.outer(u - np.sin(2.0 * np.pi * u) / (2 * np.pi), p1 - p0)
    z = 0.5 * height * (1.0 - np.cos(2.0 * np.pi * u))
    return xy, z
