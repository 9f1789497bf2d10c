"""
Counts and margin statistics of a list of ``FeasibilityReport`` messages.

The summary ``awp_replay`` prints (and ``awp_demo`` at its end): how many reports were valid,
invalid (by status name) and infeasible, and the distribution of the AWP / FWP / FWS
margins [N, N.m] and of the CoM region margins [m] over the valid ones. Reports may be
rclpy or rosbags message objects, or anything with the same attributes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
import math

import numpy as np

from awp_ros.ros.conversions import STATUS_NAMES

__all__ = ['ReplaySummary', 'summarize_reports']

#: The CoM regions whose margins [m] the reports carry (``<name>_margin``), as printed.
_REGIONS = ('feasible_region', 'support_region', 'fwp_region')


@dataclass
class ReplaySummary:
    """
    Counts and margin statistics of a replay (or of any list of reports).

    ``valid``: reports with status OK or WARNING; ``invalid``: any other status (by name in
    ``statuses``); ``infeasible``: valid reports whose ``feasible`` flag (the FWS) is false;
    ``fwp_infeasible``: valid reports outside the FWP (the seed's criterion). ``margins``:
    set -> {min, p5, median, mean, max} over valid reports [N, N.m] (NaN-free values only)
    of the signed ``*_margin`` (negative exactly for the wrenches outside the set, off a
    flat set's affine hull included: ``min < 0`` when some cycle was infeasible).
    ``region_margins``: ``feasible_region`` / ``support_region`` / ``fwp_region`` -> {min,
    p5, median, mean, max, n} [m] over the valid reports' finite margins, and ``empty``:
    how many were NaN (an empty region, or none computed). Every report's region margins
    are its own cycle's (the feasible region by projection, not the FWS's), so all valid
    reports count, unlike the FWS margin (each FWS once).
    """

    reports: int = 0
    valid: int = 0
    invalid: int = 0
    infeasible: int = 0
    fwp_infeasible: int = 0
    statuses: dict[str, int] = field(default_factory=dict)
    margins: dict[str, dict[str, float]] = field(default_factory=dict)
    region_margins: dict[str, dict[str, float]] = field(default_factory=dict)
    #: messages read per input role and written per output topic (replays)
    inputs: dict[str, int] = field(default_factory=dict)
    outputs: dict[str, int] = field(default_factory=dict)
    wall_s: float = 0.0
    bag_s: float = 0.0

    @property
    def throughput(self) -> float:
        """Return joint-state messages (= reports) processed per wall second."""
        return self.reports / self.wall_s if self.wall_s > 0 else 0.0

    def to_dict(self) -> dict:
        """Return the summary as JSON-ready builtins."""
        return {'reports': self.reports, 'valid': self.valid, 'invalid': self.invalid,
                'infeasible': self.infeasible, 'fwp_infeasible': self.fwp_infeasible,
                'statuses': dict(self.statuses), 'margins': self.margins,
                'region_margins': self.region_margins,
                'inputs': dict(self.inputs), 'outputs': dict(self.outputs),
                'wall_s': self.wall_s, 'bag_s': self.bag_s,
                'throughput_msgs_per_s': self.throughput}

    def to_text(self) -> str:
        """Return a human-readable multi-line summary."""
        lines = [f'reports: {self.reports} (one per joint state)  valid: {self.valid}  '
                 f'invalid: {self.invalid}  infeasible (FWS): {self.infeasible}  '
                 f'outside FWP: {self.fwp_infeasible}']
        bad = {k: v for k, v in self.statuses.items() if k not in ('ok', 'warning')}
        if bad or self.statuses.get('warning'):
            lines.append('statuses: ' + ', '.join(f'{k} {v}' for k, v in
                                                  sorted(self.statuses.items())))
        if self.margins:
            lines.append(f'{"margin [N, N.m]":<16}{"min":>10}{"p5":>10}{"median":>10}'
                         f'{"mean":>10}{"max":>10}{"n":>7}')
            for name, st in self.margins.items():
                lines.append(f'{name:<16}' + ''.join(f'{st[k]:10.2f}' for k in
                                                     ('min', 'p5', 'median', 'mean', 'max'))
                             + f'{st["n"]:7d}')
        if self.region_margins:
            lines.append(f'{"region [m]":<16}{"min":>10}{"p5":>10}{"median":>10}'
                         f'{"mean":>10}{"max":>10}{"n":>7}{"empty":>7}')
            for name, st in self.region_margins.items():
                lines.append(f'{name:<16}' + ''.join(
                    f'{st[k]:10.4f}' if st['n'] else f'{"-":>10}'
                    for k in ('min', 'p5', 'median', 'mean', 'max'))
                    + f'{st["n"]:7d}{st["empty"]:7d}')
        if self.wall_s > 0:
            speed = f', {self.bag_s / self.wall_s:.2f}x real time' if self.bag_s else ''
            lines.append(f'time: {self.wall_s:.2f} s wall for {self.bag_s:.2f} s of bag '
                         f'({self.throughput:.0f} joint states/s{speed})')
        return '\n'.join(lines)


def summarize_reports(reports: Iterable) -> ReplaySummary:
    """
    Count valid / invalid / infeasible reports and compute margin statistics.

    :param reports: ``FeasibilityReport`` messages (rclpy or rosbags objects), in order. Each
        FWS margin is taken once, from the first report carrying it (a new ``fws_stamp``:
        the cycle it was computed for, or with ``fws_lag_s`` the one it was released in; a
        wrench outside the FWS has its own, and the reports after it return to the latest
        FWS's, not counted again).
    """
    s = ReplaySummary()
    values: dict[str, list] = {'awp_margin': [], 'fwp_margin': [], 'fws_margin': []}
    regions: dict[str, list] = {name: [] for name in _REGIONS}
    seen_fws: set[tuple[int, int]] = set()
    for r in reports:
        s.reports += 1
        name = STATUS_NAMES.get(int(r.status), f'status_{int(r.status)}')
        s.statuses[name] = s.statuses.get(name, 0) + 1
        if int(r.status) > 1:
            s.invalid += 1
            continue
        s.valid += 1
        s.infeasible += not r.feasible
        s.fwp_infeasible += not r.fwp_feasible
        values['awp_margin'].append(r.awp_margin)
        values['fwp_margin'].append(r.fwp_margin)
        regions['support_region'].append(getattr(r, 'support_region_margin', math.nan))
        regions['fwp_region'].append(getattr(r, 'fwp_region_margin', math.nan))
        regions['feasible_region'].append(getattr(r, 'feasible_region_margin', math.nan))
        fws_stamp = (r.fws_stamp.sec, r.fws_stamp.nanosec)
        if fws_stamp not in seen_fws and not math.isnan(r.fws_margin):
            values['fws_margin'].append(r.fws_margin)
            seen_fws.add(fws_stamp)
    for name, vals in values.items():
        x = np.asarray(vals, dtype=float)
        x = x[np.isfinite(x)]
        if x.size:
            s.margins[name] = {'min': float(x.min()), 'p5': float(np.percentile(x, 5)),
                               'median': float(np.median(x)), 'mean': float(x.mean()),
                               'max': float(x.max()), 'n': int(x.size)}
    for name, vals in regions.items():
        x = np.asarray(vals, dtype=float)
        finite = x[np.isfinite(x)]
        st: dict = dict.fromkeys(('min', 'p5', 'median', 'mean', 'max'))   # None: no value
        if finite.size:
            st = {'min': float(finite.min()), 'p5': float(np.percentile(finite, 5)),
                  'median': float(np.median(finite)), 'mean': float(finite.mean()),
                  'max': float(finite.max())}
        if x.size:
            s.region_margins[name] = {**st, 'n': int(finite.size),
                                      'empty': int(x.size - finite.size)}
    return s
