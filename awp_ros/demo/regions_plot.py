"""
The CoM regions plot: a top view of the feasible and support regions and the CoM track.

:func:`read_regions` reads a bag of the node's outputs (``/<node>/report``,
``/<node>/feasible_region``, ``/<node>/support_region``: ``geometry_msgs/PolygonStamped``
in the wrench frame, points [m] relative to the CoM, world-aligned x/y); :func:`gait_world`
finds where the CoM was in the world when the input was the default gait bag (the gait is
regenerated: the bag has no base pose); :func:`plot_regions` draws the PNG with matplotlib
(Agg backend, imported when plotting); :func:`demo_regions_plot` is ``awp_demo``'s hook.

The PNG: (top) the world top view [m] with the CoM track and, at a few instants, the
support region (blue outline) and the feasible region (green) placed at the CoM of that
instant, with the stance feet; (middle) one panel per instant in the CoM frame (origin the
CoM, [m]): support region, feasible region (a segment with two stance feet, a point with
one), the CoM and, when the CoM velocity is known (the gait), the instantaneous capture
point ``c + c'/omega_0``; (bottom) the region margins [m] over time, stance phases shaded.
Without a world pose (another bag) the top view shows the regions in the CoM frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import os
from pathlib import Path

import numpy as np

from awp_ros.demo.plot import STANCE_COLOURS, STANCE_LABELS

__all__ = ['GaitWorld', 'RegionTrack', 'demo_regions_plot', 'gait_world', 'plot_regions',
           'read_regions']

_POLYGON = 'geometry_msgs/msg/PolygonStamped'
_COLOURS = {'support_region': '#3b7dd8', 'fwp_region': '#e6a817',
            'feasible_region': '#1b9e77'}


@dataclass
class RegionTrack:
    """
    The regions of one run, read from its output bag.

    ``stamps`` (N,) [ns] of the reports (joint-state stamps), ``t`` (N,) [s] from the first,
    ``stance`` (N,) number of stance feet, ``valid`` (N,) evaluated; ``margins``: region ->
    (N,) [m] as the reports carry them (``feasible_region`` NaN where its polygon was not
    sent with that report: every cycle by projection, else with the FWS); ``feasible`` /
    ``support``: stamp [ns] -> vertices (k, 2)
    [m] relative to the CoM (world-aligned x/y; 2 rows: a segment, 1: a point, 0: empty).
    """

    stamps: np.ndarray
    t: np.ndarray
    stance: np.ndarray
    valid: np.ndarray
    margins: dict[str, np.ndarray]
    feasible: dict[int, np.ndarray] = field(default_factory=dict)
    support: dict[int, np.ndarray] = field(default_factory=dict)


@dataclass
class GaitWorld:
    """
    World quantities of a gait at given stamps (world frame, z up, [m], [m/s]).

    ``com`` (N, 3), ``com_velocity`` (N, 3), ``feet`` (N, K, 3), ``stance`` (N, K) bool.
    """

    com: np.ndarray
    com_velocity: np.ndarray
    feet: np.ndarray
    stance: np.ndarray


def _stamp_ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def read_regions(bag: str | os.PathLike, node_name: str = 'awp_node') -> RegionTrack:
    """
    Read the reports and region polygons of ``/<node_name>/...`` from a bag.

    :raises BagError: unreadable bag, or no ``report`` topic.
    """
    from awp_ros.bags.message_types import typestore
    from awp_ros.bags.reader import bag_info, read_bag

    prefix = '/' + node_name.strip('/') + '/'
    have = bag_info(bag).topics
    topics = [prefix + name for name in ('report', 'feasible_region', 'support_region')
              if prefix + name in have or name == 'report']
    store = typestore()
    stamps, stance, valid = [], [], []
    margins: dict[str, list] = {name: [] for name in _COLOURS}
    polygons: dict[str, dict] = {'feasible_region': {}, 'support_region': {}}
    for m in read_bag(bag, topics=topics):
        msg = store.deserialize_cdr(m.data, m.msgtype)
        name = m.topic[len(prefix):]
        if name == 'report':
            ns = _stamp_ns(msg.header.stamp)
            stamps.append(ns)
            stance.append(len(msg.stance_feet))
            valid.append(int(msg.status) <= 1)
            for region in margins:
                margins[region].append(float(getattr(msg, f'{region}_margin')))
        else:
            V = np.array([[p.x, p.y] for p in msg.polygon.points], dtype=float).reshape(-1, 2)
            polygons[name][_stamp_ns(msg.header.stamp)] = V
    stamps_a = np.array(stamps, dtype=np.int64)
    valid_a = np.array(valid, dtype=bool)
    out = {k: np.array(v, dtype=float) for k, v in margins.items()}
    for v in out.values():
        v[~valid_a] = np.nan
    sent = np.array([ns in polygons['feasible_region'] for ns in stamps], dtype=bool)
    out['feasible_region'][~sent] = np.nan
    t = (stamps_a - stamps_a[0]) * 1e-9 if stamps_a.size else np.zeros(0)
    return RegionTrack(stamps_a, t, np.array(stance, dtype=int), valid_a, out,
                       polygons['feasible_region'], polygons['support_region'])


def gait_world(stamps: np.ndarray, *, robot: str = 'hyq',
               start_ns: int | None = None) -> GaitWorld:
    """
    Return where the CoM and feet of the default gait were at ``stamps`` [ns].

    Regenerates the default gait (:func:`awp_ros.gait.generator.generate_gait` with its
    defaults, the motion of ``config/hyq_gait.mcap``; a few seconds); sample ``i`` is at
    ``start_ns + i / rate``. The CoM velocity is the central difference of the CoM [m/s].
    """
    from awp_ros.gait.bag import DEFAULT_START_NS
    from awp_ros.gait.dynamics import central_difference
    from awp_ros.gait.generator import generate_gait
    from awp_ros.robot.config import load_config

    samples = generate_gait(load_config(robot))
    start = DEFAULT_START_NS if start_ns is None else start_ns
    i = np.rint((np.asarray(stamps, dtype=np.int64) - start) * 1e-9 * samples.rate_hz)
    i = np.clip(i.astype(int), 0, len(samples) - 1)
    vel = central_difference(samples.com, 1.0 / samples.rate_hz)
    return GaitWorld(samples.com[i], vel[i], samples.foot_positions[i], samples.stance[i])


def _instants(track: RegionTrack, count: int) -> list[int]:
    """
    Return up to ``count`` report indices with a feasible region, in time order.

    The instant where the CoM is deepest outside (or least inside) a feasible polygon, then
    the rest shared out among the stance counts of the run (4, 3, 2 feet, ...), each share
    spread evenly in time over that count's candidates.
    """
    have = np.array([int(s) in track.feasible for s in track.stamps], dtype=bool)
    have &= track.valid
    candidates = np.flatnonzero(have)
    if not candidates.size or count < 1:
        return []
    out: set[int] = set()
    polygons = [i for i in candidates.tolist()
                if track.feasible[int(track.stamps[i])].shape[0] >= 3
                and math.isfinite(track.margins['feasible_region'][i])]
    if polygons and count > 1:
        out.add(min(polygons, key=lambda i: track.margins['feasible_region'][i]))
        count -= 1
    kinds = sorted(set(track.stance[candidates].tolist()), reverse=True)[:count]
    share = [count // len(kinds) + (i < count % len(kinds)) for i in range(len(kinds))]
    for kind, n in zip(kinds, share):
        pool = candidates[track.stance[candidates] == kind]
        t = track.t[pool]
        for target in np.linspace(t[0], t[-1], n + 2)[1:-1]:
            out.add(int(pool[np.argmin(np.abs(t - target))]))
    return sorted(out)


def _draw(ax, V: np.ndarray, offset: np.ndarray, colour, *, fill: bool,
          label: str | None = None, zorder: int = 2, alpha: float = 0.45) -> None:
    """Draw a region's vertices (polygon, segment or point) shifted by ``offset``."""
    from matplotlib.patches import Polygon

    if not V.shape[0]:
        return
    P = V + offset[:2]
    if P.shape[0] >= 3:
        ax.add_patch(Polygon(P, closed=True, facecolor=colour if fill else 'none',
                             edgecolor=colour, alpha=alpha if fill else 0.9,
                             lw=1.0 if fill else 1.2, ls='-' if fill else '--',
                             label=label, zorder=zorder))
    elif P.shape[0] == 2:
        ax.plot(P[:, 0], P[:, 1], color=colour, lw=3.5, solid_capstyle='round',
                label=label, zorder=zorder)
    else:
        ax.plot(P[:, 0], P[:, 1], 'o', color=colour, ms=6, label=label, zorder=zorder)


def _margin_text(value: float) -> str:
    return 'empty' if not math.isfinite(value) else f'{value:+.3f} m'


def plot_regions(track: RegionTrack, path, *, world: GaitWorld | None = None,
                 instants: int = 6, title: str = '', gravity: float = 9.81) -> Path:
    """
    Write the regions PNG (see the module docstring) and return its path.

    :param track: the run's regions (:func:`read_regions`).
    :param world: the CoM and feet in the world at ``track.stamps`` (None: no world view).
    :param instants: how many instants to draw.
    :param gravity: ``g`` [m/s^2] of the capture point's ``omega_0 = sqrt(g / h)``.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    picks = _instants(track, instants)
    n = max(len(picks), 1)
    tint = plt.get_cmap('viridis')(np.linspace(0.0, 0.85, n))
    fig = plt.figure(figsize=(12.5, 10.5))
    grid = fig.add_gridspec(3, n, height_ratios=[2.6, 1.7, 1.3], hspace=0.42, wspace=0.25)
    top = fig.add_subplot(grid[0, :])
    zero = np.zeros(3)
    if world is not None:
        top.plot(world.com[:, 0], world.com[:, 1], color='#555555', lw=1.0,
                 label='CoM track (world)', zorder=3)
    for j, i in enumerate(picks):
        c = zero if world is None else world.com[i]
        s = int(track.stamps[i])
        _draw(top, track.support.get(s, np.zeros((0, 2))), c, tint[j], fill=False,
              label='support region (dashed)' if j == 0 else None)
        _draw(top, track.feasible[s], c, tint[j], fill=True, alpha=0.18,
              label='feasible region (filled)' if j == 0 else None)
        top.plot(c[0], c[1], '+', color=tint[j], ms=10, mew=2.0, zorder=5)
        top.annotate(f't={track.t[i]:.1f} s', (c[0], c[1]), xytext=(4, 6),
                     textcoords='offset points', fontsize=8, color=tint[j], zorder=6)
        if world is not None:
            F = world.feet[i][world.stance[i]]
            top.plot(F[:, 0], F[:, 1], 'o', color=tint[j], ms=4, zorder=4,
                     label='stance feet' if j == 0 else None)
    top.set_aspect('equal', adjustable='datalim')
    top.set_xlabel('x [m] (world)' if world is not None else 'x [m] (CoM frame)')
    top.set_ylabel('y [m]')
    top.grid(True, lw=0.4, alpha=0.5)
    top.legend(loc='upper right', fontsize=8, framealpha=0.95)
    head = title or 'CoM regions'
    where = 'top view, regions placed at the CoM of each instant' if world is not None \
        else 'regions in the CoM frame (no world pose known for this bag)'
    top.set_title(f'{head}\n{where}', fontsize=10)
    reach = 0.1
    for i in picks:
        s = int(track.stamps[i])
        for V in (track.support.get(s, np.zeros((0, 2))), track.feasible[s]):
            if V.size:
                reach = max(reach, float(np.max(np.abs(V))))
    reach *= 1.1
    for j, i in enumerate(picks):
        ax = fig.add_subplot(grid[1, j])
        s = int(track.stamps[i])
        _draw(ax, track.support.get(s, np.zeros((0, 2))), zero, _COLOURS['support_region'],
              fill=False)
        _draw(ax, track.feasible[s], zero, _COLOURS['feasible_region'], fill=True)
        ax.plot(0.0, 0.0, 'k+', ms=9, mew=1.6, zorder=5)
        if world is not None:
            F = world.feet[i][world.stance[i]]
            if F.size:
                ax.plot(F[:, 0] - world.com[i, 0], F[:, 1] - world.com[i, 1], 'o',
                        color='#222222', ms=3.5, zorder=4)
                h = world.com[i, 2] - float(F[:, 2].mean())
                if h > 0.0:
                    xi = world.com_velocity[i, :2] * math.sqrt(h / gravity)
                    ax.plot(xi[0], xi[1], 'x', color='#d62728', ms=7, mew=1.6, zorder=6)
        ax.set_xlim(-reach, reach)
        ax.set_ylim(-reach, reach)
        ax.set_aspect('equal')
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.tick_params(labelsize=7)
        ax.set_title(f't={track.t[i]:.2f} s, {track.stance[i]} feet\nfeasible '
                     f'{_margin_text(track.margins["feasible_region"][i])}', fontsize=8)
        if j == 0:
            ax.set_ylabel('y [m] (CoM frame)', fontsize=8)
        ax.set_xlabel('x [m]', fontsize=8)
    bottom = fig.add_subplot(grid[2, :])
    dt = float(np.median(np.diff(track.t))) if track.t.size > 1 else 0.0
    edges = np.flatnonzero(np.diff(track.stance)) + 1
    for a, b in zip(np.r_[0, edges], np.r_[edges, track.t.size]):
        if b > a:
            bottom.axvspan(track.t[a], track.t[b - 1] + dt, lw=0, zorder=0,
                           color=STANCE_COLOURS.get(int(track.stance[a]), '#eeeeee'))
    for name, style in (('support_region', '-'), ('fwp_region', '-')):
        bottom.plot(track.t, track.margins[name], style, color=_COLOURS[name], lw=1.0,
                    label=f'{name.replace("_", " ")} margin')
    bottom.plot(track.t, track.margins['feasible_region'], '-',
                color=_COLOURS['feasible_region'], lw=1.0, label='feasible region margin')
    for i in picks:
        bottom.axvline(track.t[i], color='#888888', lw=0.7, ls=':')
    bottom.axhline(0.0, color='k', lw=0.8)
    bottom.set_xlabel('time [s] (joint-state stamps, from the first)')
    bottom.set_ylabel('CoM margin [m]')
    handles, _ = bottom.get_legend_handles_labels()
    handles += [Patch(color=STANCE_COLOURS[c], label=STANCE_LABELS[c])
                for c in sorted(set(track.stance.tolist()), reverse=True)
                if c in STANCE_COLOURS]
    if world is not None:
        handles.append(Line2D([], [], marker='x', ls='', color='#d62728',
                              label="capture point c + c'/ω₀ (middle row)"))
    bottom.legend(handles=handles, loc='lower left', fontsize=7, ncol=4, framealpha=0.95)
    bottom.grid(True, lw=0.4, alpha=0.5)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, bbox_inches='tight')
    plt.close(fig)
    return path


def demo_regions_plot(out_bag, png, input_bag, node_name: str = 'awp_node', *,
                      title: str = '') -> Path | None:
    """
    Write ``awp_demo``'s regions PNG from its output bag; print and return its path.

    The world view needs the default gait bag as input (else the regions are drawn in the
    CoM frame). Prints why and returns None when the bag has no region topic.
    """
    from awp_ros.bags.reader import bag_info
    from awp_ros.gait.bag import default_bag_path

    prefix = '/' + node_name.strip('/') + '/'
    have = bag_info(out_bag).topics
    if prefix + 'report' not in have or prefix + 'feasible_region' not in have:
        print(f'regions plot: skipped, {out_bag} has no {prefix}report and '
              f'{prefix}feasible_region')
        return None
    track = read_regions(out_bag, node_name)
    world = None
    try:
        if Path(input_bag).resolve() == default_bag_path().resolve():
            world = gait_world(track.stamps)
    except OSError:
        world = None
    path = plot_regions(track, png, world=world, title=title)
    print(f'regions plot: {path}')
    return path
