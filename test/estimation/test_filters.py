"""
Tests of awp_ros.estimation.filters: the Butterworth differentiator against calculus.

References are closed forms (the derivative of a sinusoid, a ramp's slope, a step's height
and the 2nd-order step overshoot), never the filter's own equations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from awp_ros.errors import InputError
from awp_ros.estimation.filters import (ButterworthDifferentiator, DEFAULT_CUTOFF_HZ,
                                        group_delay)

NS = 1_000_000_000
RNG_SEED = 3


def _stamps(duration: float, dt: float, *, jitter: float = 0.0, start_ns: int = 5 * NS):
    """Return integer stamps [ns] every dt [s], each moved by up to +-jitter * dt."""
    rng = np.random.default_rng(RNG_SEED)
    n = int(duration / dt)
    offsets = np.arange(n) * dt + rng.uniform(-jitter, jitter, n) * dt
    return start_ns + np.round(offsets * 1e9).astype(np.int64)


def _run(filt: ButterworthDifferentiator, stamps, signal):
    """Feed signal(t) [t in s from the first stamp]; return t and the derivative outputs."""
    t = (stamps - stamps[0]) * 1e-9
    out = np.array([filt.update(int(s), np.atleast_1d(signal(ti))).copy()
                    for s, ti in zip(stamps, t)])
    return t, out


def _fit_sinusoid(t, y, omega):
    """Return (gain-free amplitude, lag [s]) of y ~ A cos(omega (t - lag)) by least squares."""
    X = np.column_stack([np.cos(omega * t), np.sin(omega * t)])
    a, b = np.linalg.lstsq(X, y, rcond=None)[0]
    return math.hypot(a, b), math.atan2(b, a) / omega


def test_group_delay_formula():
    assert group_delay(30.0) == pytest.approx(math.sqrt(2.0) / (2.0 * math.pi * 30.0))
    filt = ButterworthDifferentiator(1, DEFAULT_CUTOFF_HZ)
    assert filt.lag == pytest.approx(0.225 / DEFAULT_CUTOFF_HZ, rel=1e-3)


@pytest.mark.parametrize('cutoff_hz,rate_hz', [(10.0, 500.0), (30.0, 500.0), (50.0, 1000.0),
                                               (100.0, 500.0)])
def test_sinusoid_lag_and_gain_match_the_documented_formula(cutoff_hz, rate_hz):
    # Measured lag of the derivative of a 1.5 Hz sinusoid: tau_g within the documented
    # departure (sqrt(2) / 3) (f / f_c)^3 rad of phase and the hold's 0.5 % (f_c <= f_s / 5);
    # the gain is maximally flat: 1 within (f / f_c)^4 / 2 + (W dt)^2 / 12.
    freq = 1.5
    omega = 2.0 * math.pi * freq
    filt = ButterworthDifferentiator(1, cutoff_hz)
    stamps = _stamps(4.0, 1.0 / rate_hz)
    t, out = _run(filt, stamps, lambda ti: math.sin(omega * ti))
    settled = t > 1.0
    amp, lag = _fit_sinusoid(t[settled], out[settled, 0], omega)
    x = freq / cutoff_hz
    phase_tol = math.sqrt(2.0) / 3.0 * x ** 3 + 1e-5
    tau = group_delay(cutoff_hz)
    assert abs(lag - tau) <= 2.0 * phase_tol / omega + 5e-3 * tau
    gain_tol = x ** 4 / 2.0 + (omega / rate_hz) ** 2 / 12.0
    assert abs(amp / omega - 1.0) <= 2.0 * gain_tol + 1e-6


@pytest.mark.parametrize('jitter', [0.0, 0.45])
def test_sinusoid_derivative_error_is_bounded_by_the_lag(jitter):
    # After settling: |y - u'| <= A W * 2 sin(W tau_g / 2) (a pure delay) + the small
    # non-delay terms; and y is u' delayed by tau_g to within those terms. Irregular stamps
    # (dt 0.2..3.8 ms) add the error of the straight lines between samples (at most
    # dt^2 / 8 |u''|) times the differentiator's largest gain, max |s H| = w_c / sqrt(2).
    amp, freq, cutoff = 0.7, 1.5, 30.0
    omega = 2.0 * math.pi * freq
    filt = ButterworthDifferentiator(1, cutoff)
    stamps = _stamps(2.0, 0.002, jitter=jitter)
    t, out = _run(filt, stamps, lambda ti: amp * math.sin(omega * ti))
    settled = t > 5.0 * filt.settling_time
    y = out[settled, 0]
    ts = t[settled]
    tau = group_delay(cutoff)
    x = freq / cutoff
    dt_max = np.diff(stamps).max() * 1e-9
    small = amp * omega * (2.0 * (math.sqrt(2.0) / 3.0 * x ** 3 + x ** 4 / 2.0)
                           + (omega * dt_max) ** 2 / 12.0 + 1e-6)
    small += 2.0 * math.pi * cutoff / math.sqrt(2.0) * dt_max ** 2 / 8.0 * amp * omega ** 2
    err = np.abs(y - amp * omega * np.cos(omega * ts))
    assert err.max() <= amp * omega * 2.0 * math.sin(omega * tau / 2.0) + small
    assert err.max() >= 0.9 * amp * omega * omega * tau          # it does lag
    delayed = amp * omega * np.cos(omega * (ts - tau))
    assert np.abs(y - delayed).max() <= small


def test_ramp_derivative_is_exact_from_the_second_sample_with_irregular_stamps():
    slope = np.array([2.0, -3.0, 0.0])
    offset = np.array([1.0, 0.5, -2.0])
    filt = ButterworthDifferentiator(3, 25.0)
    stamps = _stamps(0.5, 0.002, jitter=0.45)
    t, out = _run(filt, stamps, lambda ti: offset + slope * ti)
    np.testing.assert_array_equal(out[0], 0.0)
    np.testing.assert_allclose(out[1:], np.broadcast_to(slope, out[1:].shape), atol=1e-9)
    # The filtered value lags the ramp by tau_g.
    np.testing.assert_allclose(filt.value, offset + slope * (t[-1] - filt.lag), atol=1e-9)


def test_step_integrates_to_its_height_and_overshoots_like_a_butterworth():
    # Area under the derivative = height; value overshoot = exp(-pi zeta / sqrt(1 -
    # zeta^2)) = exp(-pi) for zeta = 1 / sqrt(2); the derivative returns to 0.
    height, cutoff, dt = 2.0, 20.0, 0.001
    filt = ButterworthDifferentiator(1, cutoff)
    stamps = _stamps(0.6, dt)
    values = []
    t, out = [], []
    for k, s in enumerate(stamps):
        ti = (s - stamps[0]) * 1e-9
        u = height if ti >= 0.05 else 0.0
        out.append(filt.update(int(s), np.array([u]))[0])
        values.append(filt.value[0])
        t.append(ti)
    out = np.array(out)
    values = np.array(values)
    area = np.sum(out[1:] * np.diff(stamps) * 1e-9)
    assert area == pytest.approx(height, rel=2e-2)
    overshoot = values.max() / height - 1.0
    assert overshoot == pytest.approx(math.exp(-math.pi), abs=5e-3)
    assert abs(out[-1]) <= 1e-3 * height / filt.lag
    assert values[-1] == pytest.approx(height, rel=1e-3)


def test_high_frequencies_are_attenuated_like_the_low_pass():
    # At f = 5 f_c the derivative's gain is |H| = 1 / sqrt(1 + 5^4) of the ideal one.
    cutoff, freq, rate = 30.0, 150.0, 20000.0
    omega = 2.0 * math.pi * freq
    filt = ButterworthDifferentiator(1, cutoff)
    t, out = _run(filt, _stamps(0.4, 1.0 / rate), lambda ti: math.sin(omega * ti))
    settled = t > 0.2
    amp, _ = _fit_sinusoid(t[settled], out[settled, 0], omega)
    assert amp / omega == pytest.approx(1.0 / math.sqrt(1.0 + 5.0 ** 4), rel=2e-2)


def test_time_going_backwards_or_a_gap_restarts_and_a_repeated_stamp_is_ignored():
    filt = ButterworthDifferentiator(1, 30.0, max_gap_s=0.05)
    assert not filt.ready and filt.stamp_ns is None
    slope = 4.0
    for k in range(40):
        filt.update(NS + k * 2_000_000, np.array([slope * k * 0.002]))
    assert filt.ready and filt.settled
    assert filt.derivative[0] == pytest.approx(slope)
    # Same stamp, other value: ignored.
    before = filt.derivative.copy()
    filt.update(NS + 39 * 2_000_000, np.array([100.0]))
    np.testing.assert_array_equal(filt.derivative, before)
    # Backwards: restart (derivative 0, not ready), then a fresh ramp of another slope.
    out = filt.update(NS, np.array([7.0]))
    assert out[0] == 0.0 and not filt.ready and filt.value[0] == 7.0
    out = filt.update(NS + 3_000_000, np.array([7.0 - 0.003]))
    assert filt.ready and not filt.settled
    assert out[0] == pytest.approx(-1.0)
    # Gap above max_gap_s: restart again.
    out = filt.update(NS + 3_000_000 + 60_000_000, np.array([1.0]))
    assert out[0] == 0.0 and not filt.ready
    # A gap just below max_gap_s is a normal step.
    filt.update(NS + 3_000_000 + 60_000_000 + 49_000_000, np.array([1.0]))
    assert filt.ready
    filt.reset()
    assert filt.stamp_ns is None and not filt.ready


def test_settled_after_the_settling_time():
    filt = ButterworthDifferentiator(1, 30.0, settle_tol=1e-2)
    # The transient's envelope exp(-zeta w_c t) falls to 1 % after ln(100) / (zeta w_c).
    assert filt.settling_time == pytest.approx(
        math.log(100.0) / (2.0 * math.pi * 30.0 / math.sqrt(2.0)))
    step_ns = 1_000_000
    n_settle = math.ceil(filt.settling_time * 1e9 / step_ns)
    for k in range(n_settle + 1):
        filt.update(k * step_ns, np.zeros(1))
        assert filt.settled == (k >= n_settle)


@pytest.mark.parametrize('kw', [{'size': 0}, {'cutoff_hz': 0.0}, {'cutoff_hz': math.inf},
                                {'max_gap_s': -1.0}, {'settle_tol': 1.0}])
def test_bad_parameters_raise_input_error(kw):
    args = {'size': 2, 'cutoff_hz': 30.0, **kw}
    with pytest.raises(InputError):
        ButterworthDifferentiator(args.pop('size'), **args)
