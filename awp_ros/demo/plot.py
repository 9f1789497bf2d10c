"""
The margins plot: AWP / FWP / FWS margins of a run over time, stance phases shaded.

:class:`MarginSeries` turns ``FeasibilityReport`` messages (rclpy or rosbags objects) into
time series; :func:`plot_margins` draws them into a PNG with matplotlib (imported when
plotting, with the non-interactive Agg backend).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from awp_ros.ros.conversions import stamp_to_ns

__all__ = ['MarginSeries', 'plot_margins', 'STANCE_COLOURS', 'STANCE_LABELS']

STANCE_COLOURS = {4: '#e6f2e6', 3: '#fff2c2', 2: '#fadcd7', 1: '#f4c7c3', 0: '#dddddd'}
STANCE_LABELS = {4: '4 feet down', 3: '3 feet (crawl swing)', 2: '2 feet (trot)',
                 1: '1 foot', 0: 'no contact'}


@dataclass
class MarginSeries:
    """
    Per-report time series.

    ``t`` [s] from the first report, margins [N, N.m] (NaN when not evaluated; ``fws`` NaN also
    where it was not computed for that very cycle).
    """

    feet: tuple[str, ...]
    t: np.ndarray
    stance: np.ndarray
    awp: np.ndarray
    fwp: np.ndarray
    fws: np.ndarray
    fwp_residual: np.ndarray
    fwp_feasible: np.ndarray
    valid: np.ndarray

    @classmethod
    def from_reports(cls, reports, feet) -> MarginSeries:
        """Build from ``FeasibilityReport`` messages (rclpy or rosbags objects)."""
        reports = list(reports)
        feet = tuple(feet)
        stamp = np.array([stamp_to_ns(r.header.stamp) for r in reports], dtype=np.int64)
        fws_stamp = np.array([stamp_to_ns(r.fws_stamp) for r in reports], dtype=np.int64)
        t = (stamp - stamp[0]) * 1e-9 if reports else np.zeros(0)
        stance = np.array([[f in r.stance_feet for f in feet] for r in reports],
                          dtype=bool).reshape(len(reports), len(feet))
        valid = np.array([int(r.status) <= 1 for r in reports], dtype=bool)

        def values(name):
            x = np.array([getattr(r, name) for r in reports], dtype=float)
            x[~valid] = np.nan
            return x

        fws = np.where(fws_stamp == stamp, values('fws_margin'), np.nan)
        fwp_in = np.array([bool(r.fwp_feasible) for r in reports], dtype=bool)
        return cls(feet, t, stance, values('awp_margin'), values('fwp_margin'), fws,
                   values('fwp_affine_residual'), fwp_in & valid, valid)


def _runs(values: np.ndarray):
    """Yield ``(start, stop, value)`` of each run of equal values."""
    if values.size == 0:
        return
    edges = np.flatnonzero(values[1:] != values[:-1]) + 1
    for a, b in zip(np.r_[0, edges], np.r_[edges, values.size]):
        yield int(a), int(b), values[a]


def _caption(s: MarginSeries, count: np.ndarray) -> str:
    """Return 'outside the FWP: n of N cycles (k with 2 feet down, ...)'."""
    out = ~s.fwp_feasible & s.valid
    parts = [f'{int((out & (count == c)).sum())} with {c} feet down'
             for c in sorted(set(count[out].tolist()), reverse=True)]
    text = f'outside the FWP: {int(out.sum())} of {s.t.size} cycles'
    if parts:
        text += ' (' + ', '.join(parts) + ')'
    invalid = int((~s.valid).sum())
    return text + (f'; {invalid} not evaluated' if invalid else '')


def plot_margins(series: MarginSeries, path, *, title: str = '') -> Path:
    """
    Write the margins PNG and return its path.

    Top: AWP and FWP margins (and the FWS margin where computed) [N, N.m], measured inside
    each set's affine hull. Middle: distance of the wrench from the FWP's affine hull (non
    zero with 2 stance feet when the CoM is off the line between them), with the cycles
    outside the FWP marked. Bottom: which feet are in stance. Background: number of stance
    feet (4 green, 3 yellow, 2 red).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    s = series
    dt = float(np.median(np.diff(s.t))) if s.t.size > 1 else 0.0
    fig, axes = plt.subplots(3, 1, figsize=(11, 7.5), sharex=True,
                             gridspec_kw={'height_ratios': [3.2, 1.4, 1.2]})
    ax, ax_res, ax_gait = axes
    count = s.stance.sum(axis=1)
    for a in axes:
        for i0, i1, c in _runs(count):
            a.axvspan(s.t[i0], s.t[i1 - 1] + dt, color=STANCE_COLOURS.get(int(c), '#eeeeee'),
                      lw=0, zorder=0)
    ax.plot(s.t, s.awp, color='#1f77b4', lw=1.4, label='AWP margin')
    ax.plot(s.t, s.fwp, color='#d95f02', lw=1.4, label='FWP margin')
    if np.isfinite(s.fws).any():
        ax.plot(s.t, s.fws, '.', color='#1b9e77', ms=3, label='FWS margin (when computed)')
    ax.axhline(0.0, color='k', lw=0.8)
    top = np.nanmax(np.r_[s.awp, s.fwp, 1.0]) if s.t.size else 1.0
    bottom = min(0.0, np.nanmin(np.r_[s.awp, s.fwp, 0.0])) if s.t.size else 0.0
    ax.set_ylim(bottom - 0.05 * (top - bottom), top + 0.3 * (top - bottom))
    ax.set_ylabel('margin [N, N·m]\n(inside the affine hull)')
    handles, _ = ax.get_legend_handles_labels()
    handles += [Patch(color=STANCE_COLOURS[c], label=STANCE_LABELS[c])
                for c in sorted(set(count.tolist()), reverse=True)]
    ax.legend(handles=handles, loc='upper center', fontsize=8, ncol=3, framealpha=0.95)
    ax.set_title((title or 'Feasibility margins of the gravito-inertial wrench') + '\n'
                 + _caption(s, count), fontsize=10)
    ax_res.plot(s.t, s.fwp_residual, color='#7b3294', lw=1.2,
                label='distance of the wrench from the FWP affine hull')
    out = ~s.fwp_feasible & s.valid
    peak = max(1.0, float(np.nanmax(np.r_[s.fwp_residual, 1.0])))
    spans = [(s.t[i0], s.t[i1 - 1] + dt - s.t[i0]) for i0, i1, v in _runs(out) if v]
    ax_res.broken_barh(spans, (-0.1 * peak, 0.08 * peak), color='#d62728', lw=0)
    ax_res.set_ylim(-0.12 * peak, 1.45 * peak)
    ax_res.set_ylabel('off hull\n[N, N·m]')
    handles, _ = ax_res.get_legend_handles_labels()
    handles.append(Patch(color='#d62728', label='outside the FWP'))
    ax_res.legend(handles=handles, loc='upper center', fontsize=8, ncol=2, framealpha=0.95)
    for k in range(len(s.feet)):
        spans = [(s.t[i0], s.t[i1 - 1] + dt - s.t[i0])
                 for i0, i1, down in _runs(s.stance[:, k]) if down]
        ax_gait.broken_barh(spans, (k - 0.35, 0.7), color='#444444')
    ax_gait.set_yticks(range(len(s.feet)),
                       [f.split('_')[0].upper() for f in s.feet])
    ax_gait.set_ylim(len(s.feet) - 0.5, -0.5)
    ax_gait.set_ylabel('stance')
    ax_gait.set_xlabel('time [s] (joint-state stamps, from the first)')
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
