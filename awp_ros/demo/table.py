"""
The live table of ``awp_demo``: one row of a report every so many seconds of bag time.

Columns: time [s], stance feet (``--`` = swing), FWP margin [N, N.m], FWP membership,
distance off the FWP's affine hull [N, N.m], and the report's ``feasible`` (FWS) verdict.
"""

from __future__ import annotations

import threading

from awp_ros.ros.conversions import stamp_to_ns

__all__ = ['TABLE_HEADER', 'format_row', 'ReportTable']

TABLE_HEADER = f'{"t [s]":>7}  {"stance":<12}  {"FWP margin":>10}  {"in FWP":<6}  ' \
               f'{"off hull":>8}  feasible (FWS)'


def format_row(report, feet, t0_ns: int) -> str:
    """
    Return one table row.

    Time [s] since ``t0_ns``, stance (``--`` = swing), FWP margin [N, N.m], FWP membership,
    distance off the FWP hull, and the report's ``feasible``.
    """
    t = (stamp_to_ns(report.header.stamp) - t0_ns) * 1e-9
    stance = ' '.join(f.split('_')[0].upper()[:2] if f in report.stance_feet else '--'
                      for f in feet)
    if int(report.status) > 1:
        return f'{t:7.2f}  {stance:<12}  {"-":>10}  {"-":<6}  {"-":>8}  ' \
               f'not evaluated: {report.status_message}'
    return (f'{t:7.2f}  {stance:<12}  {report.fwp_margin:10.2f}  '
            f'{"yes" if report.fwp_feasible else "no":<6}  '
            f'{report.fwp_affine_residual:8.2f}  {"yes" if report.feasible else "no"}')


class ReportTable:
    """
    Print a table row every ``period`` [s] of report stamps.

    ``rec`` is a :class:`~awp_ros.demo.recorder.Recorder` (its ``lock`` and ``reports``);
    ``say`` prints one line.
    """

    def __init__(self, rec, feet, t0_ns: int, period: float, say) -> None:
        self.rec, self.feet, self.t0_ns, self.say = rec, feet, t0_ns, say
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
                self.say(format_row(r, self.feet, self.t0_ns))
                self.next_ns = stamp - (stamp - self.t0_ns) % self.period_ns + self.period_ns

    def run(self, stop: threading.Event) -> None:
        """Flush every 50 ms until ``stop`` is set (a thread's target)."""
        while not stop.wait(0.05):
            self.flush()
