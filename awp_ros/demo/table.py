"""
The live table of ``awp_demo`` and its quasi-static comparison.

:class:`ReportTable` prints a row of the node's report every so many seconds of bag time.
Columns: time [s], stance feet (``--`` = swing), then the node's verdict on the measured
wrench (base motion from the IMU, joint velocities and accelerations): FWP margin
[N, N.m], FWP membership, distance off the FWP's affine hull [N, N.m], the report's
``feasible`` (FWS) verdict; then the same joint state judged quasi-statically, without
base or joint accelerations (:class:`QuasiStatic`: the same pipeline run offline over the
same bag with ``motion=quasi_static``): FWP margin and ``feasible``. Rows inside an
intended infeasible window of the bag (:func:`intended_windows`) end with its name.
:func:`comparison_lines` sums both up: infeasible joint states in and outside the windows.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
import os
from pathlib import Path
import threading
import time

from awp_ros.ros.conversions import stamp_to_ns

__all__ = ['QuasiStatic', 'ReportTable', 'TABLE_HEADER', 'TABLE_LEGEND', 'comparison_lines',
           'format_row', 'intended_windows']

TABLE_HEADER = (f'{"t [s]":>7}  {"stance":<12}  {"FWP margin":>10}  {"in FWP":<6}  '
                f'{"off hull":>8}  {"feasible":<8}  {"quasi-static":>12}  feasible')
TABLE_LEGEND = ('margins [N, N.m] of the measured wrench (the node: IMU + joint motion), '
                'then quasi-static (the same pipeline offline, motion=quasi_static)')

#: A window ``(name, start, end)`` of joint-state stamps [ns] where infeasibility is intended.
Window = tuple[str, int, int]


def _yes(flag) -> str:
    return 'yes' if flag else 'no'


def format_row(report, feet, t0_ns: int, quasi_static=None,
               windows: Iterable[Window] = ()) -> str:
    """
    Return one table row.

    Time [s] since ``t0_ns``, stance (``--`` = swing), FWP margin [N, N.m], FWP membership,
    distance off the FWP hull, the report's ``feasible``; then the FWP margin and
    ``feasible`` of ``quasi_static`` (the quasi-static report of the same joint state;
    ``-`` when None) and, inside one of ``windows``, its name.
    """
    ns = stamp_to_ns(report.header.stamp)
    t = (ns - t0_ns) * 1e-9
    stance = ' '.join(f.split('_')[0].upper()[:2] if f in report.stance_feet else '--'
                      for f in feet)
    if int(report.status) > 1:
        return f'{t:7.2f}  {stance:<12}  {"-":>10}  {"-":<6}  {"-":>8}  ' \
               f'not evaluated: {report.status_message}'
    row = (f'{t:7.2f}  {stance:<12}  {report.fwp_margin:10.2f}  '
           f'{_yes(report.fwp_feasible):<6}  {report.fwp_affine_residual:8.2f}  '
           f'{_yes(report.feasible):<8}  ')
    qs = quasi_static
    if qs is None or int(qs.status) > 1:
        row += f'{"-":>12}  -'
    else:
        row += f'{qs.fwp_margin:12.2f}  {_yes(qs.feasible)}'
    for name, start, end in windows:
        if start <= ns < end:
            row = f'{row:<86}<- intended infeasible: {name}'
    return row


class ReportTable:
    """
    Print a table row every ``period`` [s] of report stamps.

    ``rec`` is a :class:`~awp_ros.demo.recorder.Recorder` (its ``lock`` and ``reports``);
    ``say`` prints one line; ``quasi_static`` (a :class:`QuasiStatic`) and ``windows`` fill
    the last columns (see :func:`format_row`).
    """

    def __init__(self, rec, feet, t0_ns: int, period: float, say, *,
                 quasi_static: QuasiStatic | None = None,
                 windows: Iterable[Window] = ()) -> None:
        self.rec, self.feet, self.t0_ns, self.say = rec, feet, t0_ns, say
        self.quasi_static = quasi_static
        self.windows = tuple(windows)
        self.period_ns = int(period * 1e9)
        self.next_ns = t0_ns
        self.seen = 0

    def flush(self) -> None:
        """Print the rows due among the reports received since the last call."""
        with self.rec.lock:
            new = self.rec.reports[self.seen:]
        self.seen += len(new)
        for r in new:
            stamp = stamp_to_ns(r.header.stamp)
            if stamp >= self.next_ns:
                qs = None if self.quasi_static is None else self.quasi_static.get(stamp)
                self.say(format_row(r, self.feet, self.t0_ns, qs, self.windows))
                self.next_ns = stamp - (stamp - self.t0_ns) % self.period_ns + self.period_ns

    def run(self, stop: threading.Event) -> None:
        """Flush every 50 ms until ``stop`` is set (a thread's target)."""
        while not stop.wait(0.05):
            self.flush()


@dataclass
class QuasiStatic:
    """
    The reports of the same pipeline run offline with ``motion=quasi_static`` over a bag.

    ``reports`` maps joint-state stamps [ns] to ``FeasibilityReport`` messages; ``wall_s``
    is the time the run took [s].
    """

    reports: dict = field(default_factory=dict)
    wall_s: float = 0.0

    def get(self, stamp_ns: int):
        """Return the quasi-static report of the joint state stamped ``stamp_ns``, or None."""
        return self.reports.get(stamp_ns)

    @classmethod
    def from_bag(cls, bag: str | os.PathLike, params_file: str | os.PathLike, *,
                 overrides: Mapping | None = None,
                 duration_s: float | None = None) -> QuasiStatic:
        """
        Run a bag through the node's pipeline, the motion quasi-static, without DDS.

        The parameters are the node's (``params_file`` and ``overrides``, e.g. ``use_imu``)
        with ``motion`` set to ``quasi_static``; the input topics are fed in recorded order
        as ``awp_replay`` feeds them (imu only with ``use_imu``, odometry only with
        ``use_odometry``). ``duration_s``: only the messages logged less than this after
        the bag's start [s].

        :raises BagError: unreadable bag; :raises ConfigError: bad parameters.
        """
        from awp_ros.runtime import limit_blas_threads

        t0 = time.perf_counter()
        # One BLAS thread while it runs (3x faster on 2 busy cores: see awp_ros.runtime).
        limiter = limit_blas_threads(1)
        try:
            reports = cls._run(bag, params_file, overrides, duration_s)
        finally:
            if limiter is not None:
                limiter.restore_original_limits()
        return cls(reports, time.perf_counter() - t0)

    @staticmethod
    def _run(bag, params_file, overrides, duration_s) -> dict:
        """Return the quasi-static reports by stamp (see :meth:`from_bag`)."""
        from rclpy.serialization import deserialize_message

        from awp_ros.bags.message_types import INPUT_TOPICS, message_class
        from awp_ros.bags.reader import bag_info, read_bag
        from awp_ros.robot.config import load_parameters
        from awp_ros.ros.pipeline import Pipeline

        params, base_dir = load_parameters(params_file, {**dict(overrides or {}),
                                                         'motion': 'quasi_static'})
        pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
        p = pipeline.params
        handlers = {'joint_states': None, 'contacts': pipeline.on_contacts}
        if p.use_imu:
            handlers['imu'] = pipeline.on_imu
        if p.use_odometry:
            handlers['odom'] = pipeline.on_odometry
        info = bag_info(bag)
        inputs = {topic: (handlers[role], message_class(msgtype))
                  for role, (topic, msgtype) in INPUT_TOPICS.items()
                  if role in handlers and topic in info.topics}
        stop = None if duration_s is None else info.start_ns + int(duration_s * 1e9)
        reports = {}
        for msg in read_bag(bag, topics=list(inputs)):
            if stop is not None and msg.timestamp >= stop:
                break
            handler, msg_class = inputs[msg.topic]
            obj = deserialize_message(msg.data, msg_class)
            if handler is not None:
                handler(obj)
                continue
            report = pipeline.on_joint_state(obj).report
            reports[stamp_to_ns(report.header.stamp)] = report
        return reports


def intended_windows(bag: str | os.PathLike) -> tuple[Window, ...]:
    """
    Return the windows of a bag where infeasibility is intended (joint-state stamps [ns]).

    Known for the default bag (``config/hyq_gait.mcap``, which ``python -m awp_ros.gait``
    regenerates byte-for-byte from the gait generator's defaults): the plan of that gait
    (its :attr:`~awp_ros.gait.generator.GaitSamples.infeasible`: the lurch, 6.3-6.5 s
    after the first stamp), checked against the bag's joint-state count. No window for
    any other bag.
    """
    from awp_ros.bags.reader import bag_info
    from awp_ros.errors import BagError
    from awp_ros.gait.bag import DEFAULT_START_NS, default_bag_path
    from awp_ros.gait.params import GaitParams
    from awp_ros.gait.plan import GaitPlan
    from awp_ros.robot.config import load_config
    from awp_ros.robot.model import RobotModel

    try:
        default = default_bag_path()
    except BagError:
        return ()
    if Path(bag).resolve() != default.resolve():
        return ()
    plan = GaitPlan.build(RobotModel(load_config('hyq')), GaitParams())
    joint_states = bag_info(bag).topics.get('/joint_states')
    if joint_states is None or joint_states.count != plan.n_samples:
        return ()
    return tuple((w.name, DEFAULT_START_NS + int(round(w.t0 * 1e9)),
                  DEFAULT_START_NS + int(round(w.t1 * 1e9))) for w in plan.windows)


def comparison_lines(reports, quasi_static: QuasiStatic | None, windows: Iterable[Window],
                     t0_ns: int) -> list[str]:
    """
    Return the demo's closing lines: infeasible joint states, measured vs quasi-static.

    For the node's reports (the measured wrench) and, by stamp, their quasi-static
    counterparts: how many evaluated joint states are infeasible (not ``feasible``), how
    many of them fall inside the intended windows (of how many joint states there) and how
    many elsewhere, with the stance sizes of the latter. Times [s] since ``t0_ns``.
    """
    windows = tuple(windows)
    stamps = [stamp_to_ns(r.header.stamp) for r in reports]

    def inside(ns):
        return any(start <= ns < end for _, start, end in windows)

    lines = [f'intended infeasible window: {name} {(start - t0_ns) * 1e-9:.2f}-'
             f'{(end - t0_ns) * 1e-9:.2f} s' for name, start, end in windows]
    in_window = sum(inside(ns) for ns in stamps)
    runs = [('measured wrench (the node)', dict(zip(stamps, reports)))]
    if quasi_static is not None:
        runs.append((f'quasi-static wrench (same pipeline offline, '
                     f'{quasi_static.wall_s:.1f} s)',
                     {ns: quasi_static.get(ns) for ns in stamps}))
    for label, by_stamp in runs:
        bad = [(ns, r) for ns, r in by_stamp.items()
               if r is not None and int(r.status) <= 1 and not r.feasible]
        text = f'{label}: {len(bad)} of {len(by_stamp)} joint states infeasible'
        if windows:
            hits = sum(inside(ns) for ns, _ in bad)
            elsewhere = [len(r.stance_feet) for ns, r in bad if not inside(ns)]
            text += f'; {hits} of the {in_window} in the window, {len(elsewhere)} elsewhere'
            if elsewhere:
                text += ' (' + ', '.join(f'{elsewhere.count(k)} with {k} feet down'
                                         for k in sorted(set(elsewhere), reverse=True)) + ')'
        lines.append(text)
    return lines
