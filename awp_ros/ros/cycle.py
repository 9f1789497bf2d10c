"""The outputs answering one joint-state message: :class:`Cycle` (built on demand)."""

from __future__ import annotations

from dataclasses import replace

from awp_ros_msgs.msg import FeasibilityReport, LegPolytopes, WrenchPolytope
from geometry_msgs.msg import PolygonStamped
import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from awp_ros.evaluation.result import FeasibilityResult, WrenchSetResult
from awp_ros.ros.conversions import (leg_polytopes_msg, region_polygon_msg, report_status,
                                     wrench_polytope_msg)
from awp_ros.ros.markers import build_markers, error_markers, MarkerStyle

__all__ = ['Cycle', 'OUTPUTS']

#: Output topics (relative to the node, ``~/<name>``) in the order of :meth:`Cycle.messages`.
OUTPUTS = ('report', 'awp', 'fwp', 'fws', 'leg_polytopes', 'markers', 'feasible_region',
           'support_region')


class Cycle:
    """
    The outputs answering one joint-state message (built on demand, then cached).

    :ivar header: stamp of the joint state, frame_id ``wrench_frame_id``.
    :ivar report: the FeasibilityReport (always); :attr:`report_bytes` the same serialized
        (what the node publishes). An evaluated joint state's report is made as bytes and
        its message only when read (replay, demo), a report of an error as a message.
    :ivar status, status_message, compute_time: the report's fields of those names.
    :ivar result: the evaluation, or None when the message was not evaluated.
    :ivar fws_computed: whether the FWS was computed for this message.
    :ivar markers_due: whether markers are published for this message.

    ``released_fws``: ``(stamp, result, reference point)`` of a lagged FWS released in this
    cycle (``fws_lag_s``): :meth:`fws` publishes it, stamped with its own joint state's stamp.
    """

    def __init__(self, header: Header, report: FeasibilityReport | bytes,
                 result: FeasibilityResult | None, *, fws_computed: bool, markers_due: bool,
                 marker_frame_id: str, marker_frame: tuple, style: MarkerStyle,
                 reference_point: np.ndarray, latest_fws: WrenchSetResult | None,
                 pyramid_sides: int, released_fws: tuple | None = None) -> None:
        self.header = header
        if isinstance(report, bytes):
            self._report, self._report_bytes = None, report
            self.status, self.status_message, self.compute_time = report_status(report)
        else:
            self._report, self._report_bytes = report, None
            self.status, self.status_message = report.status, report.status_message
            self.compute_time = report.compute_time
        self.result = result
        self.fws_computed = fws_computed
        self.markers_due = markers_due
        self._marker_frame_id = marker_frame_id
        self._marker_frame = marker_frame
        self._style = style
        self._reference_point = reference_point
        self._latest_fws = latest_fws
        self._sides = pyramid_sides
        self._released_fws = released_fws
        self._cache: dict = {}

    @classmethod
    def unevaluated(cls, report: FeasibilityReport) -> Cycle:
        """Return the outputs of a joint state that was not evaluated: its report only."""
        return cls(report.header, report, None, fws_computed=False, markers_due=False,
                   marker_frame_id=report.header.frame_id,
                   marker_frame=(np.eye(3), np.zeros(3)),
                   style=MarkerStyle(), reference_point=np.zeros(3), latest_fws=None,
                   pyramid_sides=4)

    def _marker_header(self) -> Header:
        """Return the markers' header: the joint state's stamp, ``marker_frame_id``."""
        return Header(stamp=self.header.stamp, frame_id=self._marker_frame_id)

    @property
    def report(self) -> FeasibilityReport:
        """Return the report message (deserialized on first use when made as bytes)."""
        if self._report is None:
            self._report = deserialize_message(self._report_bytes, FeasibilityReport)
        return self._report

    @property
    def report_bytes(self) -> bytes:
        """Return the serialized report (serialized on first use when made as a message)."""
        if self._report_bytes is None:
            self._report_bytes = serialize_message(self._report)
        return self._report_bytes

    def _cached(self, key: str, available: bool, build, *args):
        """Return ``build(self.header, *args)``, built once; None when not ``available``."""
        if not available:
            return None
        if key not in self._cache:
            self._cache[key] = build(self.header, *args)
        return self._cache[key]

    def _wrench(self, kind: str) -> WrenchPolytope | None:
        r = self.result
        available = r is not None and (kind != 'fws' or self.fws_computed)
        return self._cached(kind, available, lambda h: wrench_polytope_msg(
            h, kind, r.stance, self._reference_point, getattr(r, kind).polytope))

    def awp(self) -> WrenchPolytope | None:
        """Return the AWP message (None when not evaluated)."""
        return self._wrench('awp')

    def fwp(self) -> WrenchPolytope | None:
        """Return the FWP message (None when not evaluated)."""
        return self._wrench('fwp')

    def fws(self) -> WrenchPolytope | None:
        """
        Return the FWS message when it was computed for (or released in) this message.

        None otherwise. A released lagged FWS carries the stamp of the joint state it was
        computed for.
        """
        if self._released_fws is None:
            return self._wrench('fws')
        stamp, r, ref = self._released_fws
        return self._cached('fws', True, lambda h: wrench_polytope_msg(
            Header(stamp=stamp, frame_id=h.frame_id), 'fws', r.stance, ref, r.fws.polytope))

    def feasible_region(self) -> PolygonStamped | None:
        """
        Return the feasible region (PolygonStamped): every cycle (by projection).

        Frame the wrench frame, points [m] relative to the CoM at ``z = 0``; a segment (two
        stance legs) has 2 points, a point (one leg) 1, an empty region none. Where the
        projection is not available (a singular leg) it comes with the FWS: None when the
        FWS was not computed for this message (the reports carry the latest margin).
        """
        r = self.result
        available = r is not None and (r.feasible_region_per_cycle is not None
                                       or (self.fws_computed and r.fws is not None))
        return self._cached('feasible_region', available, lambda h: region_polygon_msg(
            h, r.feasible_region))

    def support_region(self) -> PolygonStamped | None:
        """Return the support region (PolygonStamped, as above; None when not evaluated)."""
        r = self.result
        return self._cached('support_region', r is not None,
                            lambda h: region_polygon_msg(h, r.support_region))

    def leg_polytopes(self) -> LegPolytopes | None:
        """Return the LegPolytopes message (None when not evaluated)."""
        return self._cached('legs', self.result is not None, leg_polytopes_msg, self.result)

    def markers(self) -> MarkerArray | None:
        """Return the MarkerArray when markers are due for this message, else None."""
        if not self.markers_due:
            return None
        if 'markers' not in self._cache:
            function, args, kwargs = self.marker_job()
            self._cache['markers'] = function(*args, **kwargs)
        return self._cache['markers']

    def marker_job(self) -> tuple:
        """
        Return ``(function, args, kwargs)`` building :meth:`markers` (picklable).

        What :class:`awp_ros.node.marker_worker.MarkerWorker` runs in its process. The wrench
        sets whose margins only label the markers travel without their polytopes.
        """
        if self.result is None:
            return error_markers, (self._marker_header(), self.status_message), {
                'style': self._style}
        r = self.result
        slim = replace(r, awp=replace(r.awp, polytope=None), cwc=None,
                       fws=None if r.fws is None else replace(r.fws, polytope=None))
        fws = None if self._latest_fws is None else replace(self._latest_fws, polytope=None)
        R, t = self._marker_frame
        return build_markers, (slim, self._marker_header()), {
            'style': self._style, 'fws': fws, 'pyramid_sides': self._sides, 'rotation': R,
            'translation': t, 'status_text': self.status_message}

    def messages(self) -> dict:
        """Return every output of this message: topic name (``OUTPUTS``) -> message."""
        out = {'report': self.report, 'awp': self.awp(), 'fwp': self.fwp(),
               'fws': self.fws(), 'leg_polytopes': self.leg_polytopes(),
               'markers': self.markers(), 'feasible_region': self.feasible_region(),
               'support_region': self.support_region()}
        return {k: v for k, v in out.items() if v is not None}
