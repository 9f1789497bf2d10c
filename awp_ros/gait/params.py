"""
Parameters of the gait generator: the gaits, their durations and sizes, the planner's passes.

:class:`GaitParams` is read by :mod:`awp_ros.gait.plan` and :mod:`awp_ros.gait.generator`
(which re-exports it with :data:`GAITS` and :data:`GRAVITY`), so that imports go one way:
params <- plan <- balance <- generator.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from awp_ros.errors import InputError

__all__ = ['GaitParams', 'GAITS', 'GRAVITY', 'QUADRANTS']

#: The gaits of a sequence: standing, the static crawl, the deliberately infeasible lurch on
#: three feet, the trot.
GAITS = ('stand', 'crawl', 'lurch', 'trot')
GRAVITY = 9.81  # [m/s^2], matches Pinocchio's default model.gravity
#: Quadrant names of the four feet (left/right, front/hind in the base frame).
QUADRANTS = ('lf', 'rf', 'lh', 'rh')


@dataclass(frozen=True)
class GaitParams:
    """
    Parameters of the generated motion (durations [s], lengths [m], angles [rad]).

    ``sequence`` lists the gaits in order, each preceded and followed by ``stand_s`` of
    standing. Durations are rounded to whole samples of ``rate_hz``.

    Crawl: per step a four-foot shift of ``crawl_shift_s`` and a swing of ``crawl_swing_s``
    (``crawl_step_m`` forward), the ZMP ``crawl_margin_m`` inside the support triangle.
    Lurch: a four-foot shift of ``lurch_shift_s`` onto the three feet other than
    ``lurch_foot``, which then lifts (``lurch_lift_s``, up to ``swing_height_m``); after
    ``lurch_delay_s`` the body is thrown toward the opposite corner so hard that for
    ``lurch_s`` the ZMP is ``lurch_overshoot_m`` outside the support triangle; the window
    is shortened when the body would otherwise travel more than ``lurch_travel_ratio``
    times the standing CoM height before it is caught (small robots: Go2, Solo-12).
    Trot: ``trot_cycles`` periods of ``trot_period_s``, duty ``trot_duty``, the speed
    ramping in ``trot_ramp_s`` to ``trot_speed_mps``; the base bobs by ``bob_m`` and rolls
    by ``roll_rad`` at full speed. Balance: ``balance_iterations`` passes (a fixed number,
    for reproducible bytes) of the ZMP planner and the whole-body inverse kinematics (see
    :mod:`awp_ros.gait.balance`); four leave the two-foot line moments below 0.01 N.m.
    """

    sequence: tuple[str, ...] = ('crawl', 'lurch', 'trot')
    rate_hz: float = 500.0
    stand_s: float = 0.5
    crawl_shift_s: float = 0.6
    crawl_swing_s: float = 0.5
    crawl_step_m: float = 0.10
    crawl_cycles: int = 1
    crawl_margin_m: float = 0.06
    trot_period_s: float = 0.6
    trot_duty: float = 0.6
    trot_cycles: int = 5
    trot_speed_mps: float = 0.25
    trot_ramp_s: float = 0.9
    swing_height_m: float = 0.08
    bob_m: float = 0.006
    roll_rad: float = 0.02
    round_decimals: int = 9
    lurch_foot: str = 'lf'
    lurch_shift_s: float = 0.6
    lurch_lift_s: float = 1.6
    lurch_delay_s: float = 0.3
    lurch_s: float = 0.2
    lurch_overshoot_m: float = 0.04
    lurch_travel_ratio: float = 0.25
    balance_iterations: int = 4

    def __post_init__(self) -> None:
        """Validate (raise InputError naming the bad value)."""
        unknown = [g for g in self.sequence if g not in GAITS]
        if unknown:
            raise InputError(f'unknown gaits {unknown}; gaits are {list(GAITS)}')
        positive = ('rate_hz', 'crawl_shift_s', 'crawl_swing_s', 'trot_period_s',
                    'swing_height_m', 'trot_ramp_s', 'lurch_shift_s', 'lurch_lift_s',
                    'lurch_s', 'lurch_travel_ratio')
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise InputError(f'{name} must be finite and > 0, got {value!r}')
        for name in ('stand_s', 'crawl_step_m', 'crawl_margin_m', 'trot_speed_mps', 'bob_m',
                     'roll_rad', 'lurch_delay_s', 'lurch_overshoot_m'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise InputError(f'{name} must be finite and >= 0, got {value!r}')
        if not 0.5 < self.trot_duty < 1.0:
            raise InputError(f'trot_duty must be in (0.5, 1), got {self.trot_duty!r}')
        if self.crawl_cycles < 1 or self.trot_cycles < 1:
            msg = f'crawl_cycles and trot_cycles must be >= 1, got ' \
                  f'{self.crawl_cycles!r}, {self.trot_cycles!r}'
            raise InputError(msg)
        if self.lurch_foot not in QUADRANTS:
            raise InputError(f'lurch_foot must be one of {list(QUADRANTS)}, got '
                             f'{self.lurch_foot!r}')
        if self.lurch_delay_s + self.lurch_s >= self.lurch_lift_s:
            msg = (f'lurch_delay_s + lurch_s ({self.lurch_delay_s} + {self.lurch_s} s) must '
                   f'end before the foot is down again (lurch_lift_s = {self.lurch_lift_s} s)')
            raise InputError(msg)
        if self.balance_iterations < 1:
            raise InputError(f'balance_iterations must be >= 1, got '
                             f'{self.balance_iterations!r}')
