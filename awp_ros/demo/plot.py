"""
The margins plot: AWP / FWP / FWS margins of a run over time, stance phases shaded.

:class:`MarginSeries` turns ``FeasibilityReport`` messages (rclpy or rosbags objects) into
time series, optionally beside the quasi-static reports of the same joint states (the
pipeline with ``motion=quasi_static``: no accelerations) and the intended infeasible
windows of the bag;
:func:`plot_margins` draws them into a PNG with matplotlib (imported when plotting, with
the non-interactive Agg backend).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from awp_ros.ros.conversions import stamp_to_ns

__all__ = ['MarginSeries', 'plot_margins', 'STANCE_COLOURS', 'STANCE_LABELS', 'MEASURED_COLOUR',
           'QUASI_STATIC_COLOUR', 'WINDOW_COLOUR']

STANCE_COLOURS = {4: '#e6f2e6', 3: '#fff2c2', 2: '#fadcd7', 1: '#f4c7c3', 0: '#dddddd'}
STANCE_LABELS = {4: '4 feet down', 3: '3 feet (crawl swing)', 2: '2 feet (trot)',
                 1: '1 foot', 0: 'no contact'}
#: Infeasible cycles of the measured wrench (the node) and of the quasi-static one.
MEASURED_COLOUR = '#d62728'
QUASI_STATIC_COLOUR = '#7f7f7f'
#: Outline and hatching of an intended infeasible window.
WINDOW_COLOUR = '#6a3d9a'


@dataclass
class MarginSeries:
    """
    Per-report time series.

    ``t`` [s] from the first report, margins [N, N.m] (NaN when not evaluated; ``fws`` NaN also
    where it was not computed for that very cycle), ``feasible`` the reports' verdicts.
    ``qs_fwp`` / ``qs_feasible``: the FWP margin and verdict of the quasi-static report of
    the same joint state (NaN / False where there is none; None without quasi-static
    reports); ``windows``: intended infeasible windows ``(name, start, end)`` [s], as ``t``.
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
    feasible: np.ndarray | None = None
    qs_fwp: np.ndarray | None = None
    qs_feasible: np.ndarray | None = None
    windows: tuple[tuple[str, float, float], ...] = ()

    @classmethod
    def from_reports(cls, reports, feet, quasi_static=None, windows=()) -> MarginSeries:
        """
        Build from ``FeasibilityReport`` messages (rclpy or rosbags objects).

        :param quasi_static: the quasi-static reports by stamp (anything with
            ``get(stamp_ns)``, e.g. :class:`~awp_ros.demo.table.QuasiStatic`), or None.
        :param windows: intended infeasible windows ``(name, start, end)`` of joint-state
            stamps [ns].
        """
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

        # Each FWS margin once, at the first valid report carrying it (the cycle it was
        # computed for; with fws_lag_s, the one it was released in; a wrench outside the FWS
        # has its own, then the reports return to the latest FWS's: not drawn again).
        k = np.flatnonzero(valid)
        first_carrier = np.zeros(len(reports), dtype=bool)
        first_carrier[k[np.unique(fws_stamp[k], return_index=True)[1]]] = True
        fws = np.where(first_carrier, values('fws_margin'), np.nan)
        fwp_in = np.array([bool(r.fwp_feasible) for r in reports], dtype=bool)
        feasible = np.array([bool(r.feasible) for r in reports], dtype=bool) & valid
        qs_fwp = qs_feasible = None
        if quasi_static is not None:
            qs = [quasi_static.get(int(ns)) for ns in stamp]
            ok = [q is not None and int(q.status) <= 1 for q in qs]
            qs_fwp = np.array([q.fwp_margin if k else np.nan for q, k in zip(qs, ok)],
                              dtype=float)
            qs_feasible = np.array([k and bool(q.feasible) for q, k in zip(qs, ok)],
                                   dtype=bool)
        first = int(stamp[0]) if reports else 0
        spans = tuple((name, (a - first) * 1e-9, (b - first) * 1e-9) for name, a, b in windows)
        return cls(feet, t, stance, values('awp_margin'), values('fwp_margin'), fws,
                   values('fwp_affine_residual'), fwp_in & valid, valid, feasible, qs_fwp,
                   qs_feasible, spans)


def _runs(values: np.ndarray):
    """Yield ``(start, stop, value)`` of each run of equal values."""
    if values.size == 0:
        return
    edges = np.flatnonzero(values[1:] != values[:-1]) + 1
    for a, b in zip(np.r_[0, edges], np.r_[edges, values.size]):
        yield int(a), int(b), values[a]


def _in_windows(s: MarginSeries) -> np.ndarray:
    """Return the cycles inside an intended infeasible window."""
    inside = np.zeros(s.t.size, dtype=bool)
    for _, a, b in s.windows:
        inside |= (s.t >= a - 1e-12) & (s.t < b - 1e-12)
    return inside


def _count_text(bad: np.ndarray, inside: np.ndarray, windows) -> str:
    """Return 'n' or 'n (k in the window, m elsewhere)'."""
    text = f'{int(bad.sum())}'
    if windows:
        text += (f' ({int((bad & inside).sum())} of {int(inside.sum())} in the window, '
                 f'{int((bad & ~inside).sum())} elsewhere)')
    return text


def _caption(s: MarginSeries, count: np.ndarray) -> str:
    """Return the subtitle: the infeasible cycles (measured, quasi-static) or outside-FWP ones."""
    invalid = int((~s.valid).sum())
    tail = f'; {invalid} not evaluated' if invalid else ''
    if s.feasible is not None and s.qs_feasible is not None:
        inside = _in_windows(s)
        text = (f'infeasible of {s.t.size} cycles: measured wrench (the node) '
                f'{_count_text(~s.feasible & s.valid, inside, s.windows)}\n'
                f'quasi-static (same pipeline, motion=quasi_static) '
                f'{_count_text(~s.qs_feasible & np.isfinite(s.qs_fwp), inside, s.windows)}')
        return text + tail
    out = ~s.fwp_feasible & s.valid
    parts = [f'{int((out & (count == c)).sum())} with {c} feet down'
             for c in sorted(set(count[out].tolist()), reverse=True)]
    text = f'outside the FWP: {int(out.sum())} of {s.t.size} cycles'
    if parts:
        text += ' (' + ', '.join(parts) + ')'
    return text + tail


def _spans(t: np.ndarray, mask: np.ndarray, dt: float) -> list[tuple[float, float]]:
    """Return ``(start, width)`` [s] of each run of True in ``mask``."""
    return [(t[i0], t[i1 - 1] + dt - t[i0]) for i0, i1, v in _runs(mask) if v]


def plot_margins(series: MarginSeries, path, *, title: str = '') -> Path:
    """
    Write the margins PNG and return its path.

    Top: AWP and FWP margins (and the FWS margin where computed) [N, N.m], measured inside
    each set's affine hull, and the quasi-static wrench's FWP margin when the series has
    it. Then: distance of the wrench from the FWP's affine hull (non zero with 2 stance
    feet when the CoM is off the line between them), with the cycles outside the FWP
    marked; the infeasible cycles, measured wrench and quasi-static (when the series has
    verdicts); which feet are in stance. Background: number of stance feet (4 green, 3
    yellow, 2 red); hatched: the intended infeasible windows.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    s = series
    dt = float(np.median(np.diff(s.t))) if s.t.size > 1 else 0.0
    verdicts = s.feasible is not None
    ratios = [3.2, 1.3] + ([0.9] if verdicts else []) + [1.2]
    fig, axes = plt.subplots(len(ratios), 1, figsize=(11, 7.5 + (1.0 if verdicts else 0.0)),
                             sharex=True, gridspec_kw={'height_ratios': ratios})
    ax, ax_res, ax_gait = axes[0], axes[1], axes[-1]
    count = s.stance.sum(axis=1)
    for a in axes:
        for i0, i1, c in _runs(count):
            a.axvspan(s.t[i0], s.t[i1 - 1] + dt, color=STANCE_COLOURS.get(int(c), '#eeeeee'),
                      lw=0, zorder=0)
        for _, t0, t1 in s.windows:
            a.axvspan(t0, t1, facecolor='none', edgecolor=WINDOW_COLOUR, hatch='////',
                      lw=0.8, zorder=0.5)
    quasi = s.qs_fwp is not None and bool(np.isfinite(s.qs_fwp).any())
    ax.plot(s.t, s.awp, color='#1f77b4', lw=1.4, label='AWP margin')
    ax.plot(s.t, s.fwp, color='#d95f02', lw=1.4,
            label='FWP margin' + (' (measured wrench)' if quasi else ''))
    if np.isfinite(s.fws).any():
        ax.plot(s.t, s.fws, '.', color='#1b9e77', ms=3,
                label='FWS margin (when computed; outside it, every cycle)')
    if quasi:
        ax.plot(s.t, s.qs_fwp, '--', color='#444444', lw=0.9,
                label='FWP margin, quasi-static wrench')
    ax.axhline(0.0, color='k', lw=0.8)
    shown = [s.awp, s.fwp] + ([s.qs_fwp] if quasi else [])
    top = np.nanmax(np.r_[(*shown, [1.0])]) if s.t.size else 1.0
    bottom = min(0.0, np.nanmin(np.r_[(*shown, [0.0])])) if s.t.size else 0.0
    ax.set_ylim(bottom - 0.05 * (top - bottom), top + 0.3 * (top - bottom))
    ax.set_ylabel('signed margin [N, N·m]\n(< 0: not in the set)')
    handles, _ = ax.get_legend_handles_labels()
    handles += [Patch(color=STANCE_COLOURS[c], label=STANCE_LABELS[c])
                for c in sorted(set(count.tolist()), reverse=True)]
    handles += [Patch(facecolor='none', edgecolor=WINDOW_COLOUR, hatch='////',
                      label=f'intended infeasible: {name}') for name, _, _ in s.windows]
    ax.legend(handles=handles, loc='upper center', fontsize=8, ncol=3, framealpha=0.95)
    ax.set_title((title or 'Feasibility margins of the gravito-inertial wrench') + '\n'
                 + _caption(s, count), fontsize=10)
    ax_res.plot(s.t, s.fwp_residual, color='#7b3294', lw=1.2,
                label='distance of the wrench from the FWP affine hull')
    peak = max(1.0, float(np.nanmax(np.r_[s.fwp_residual, 1.0])))
    ax_res.broken_barh(_spans(s.t, ~s.fwp_feasible & s.valid, dt), (-0.1 * peak, 0.08 * peak),
                       color=MEASURED_COLOUR, lw=0)
    ax_res.set_ylim(-0.12 * peak, 1.45 * peak)
    ax_res.set_ylabel('off hull\n[N, N·m]')
    handles, _ = ax_res.get_legend_handles_labels()
    handles.append(Patch(color=MEASURED_COLOUR, label='outside the FWP'))
    ax_res.legend(handles=handles, loc='upper center', fontsize=8, ncol=2, framealpha=0.95)
    if verdicts:
        ax_bad = axes[2]
        rows = [('measured', ~s.feasible & s.valid, MEASURED_COLOUR)]
        if s.qs_feasible is not None:
            rows.append(('quasi-static', ~s.qs_feasible & np.isfinite(s.qs_fwp),
                         QUASI_STATIC_COLOUR))
        for k, (_, bad, colour) in enumerate(rows):
            ax_bad.broken_barh(_spans(s.t, bad, dt), (k - 0.32, 0.64), color=colour, lw=0)
        ax_bad.set_yticks(range(len(rows)), [name for name, _, _ in rows])
        ax_bad.set_ylim(len(rows) - 0.5, -0.5)
        ax_bad.set_ylabel('infeasible', fontsize=9)
    for k in range(len(s.feet)):
        ax_gait.broken_barh(_spans(s.t, s.stance[:, k], dt), (k - 0.35, 0.7), color='#444444')
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
