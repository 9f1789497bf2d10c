"""
Conversions between ROS messages and the core's objects (the node's and replay's glue).

- :class:`~awp_ros.geometry.polytope.Polytope` <-> ``awp_ros_msgs/Polytope``: numpy arrays go into
  the ``float64[]`` fields as ``array.array('d')`` built from their bytes (no per-element Python
  objects); matrices are flattened row-major (element ``(i, j)`` of a ``k x n`` matrix at
  ``i * n + j``), as ``Polytope.msg`` documents.
- :class:`~awp_ros.evaluation.evaluator.FeasibilityResult` -> ``FeasibilityReport``,
  ``WrenchPolytope`` (AWP / FWP / FWS) and ``LegPolytopes``. Wrenches ``[f; tau]`` [N, N.m] and
  forces [N] are in the CoM-centred frame with world-aligned axes (REP 103) whose name the caller
  passes in the header (parameter ``wrench_frame_id``); foot positions [m] relative to the CoM,
  same axes.
- :class:`~awp_ros.wrench.com_region.ComRegion` -> ``geometry_msgs/PolygonStamped``
  (:func:`region_polygon_msg`): the CoM region's vertices [m], world-aligned x/y relative to
  the CoM, ``z = 0`` (the CoM height), in the wrench frame.
- ``sensor_msgs/JointState`` + ``awp_ros_msgs/ContactState`` (+ ``sensor_msgs/Imu``) ->
  :class:`~awp_ros.robot.state.RobotState`. Message-level checks (array lengths, duplicate names,
  contact names that are not feet) raise :class:`~awp_ros.errors.InputError`; joints the
  model does not have are dropped with a note (when the caller passes the model's joints);
  the values themselves are validated by the evaluator.

This module imports message classes but not rclpy.
"""

from __future__ import annotations

from array import array
from collections.abc import Collection, Sequence
import math

from awp_ros_msgs.msg import ContactState, FeasibilityReport, LegPolytope, LegPolytopes
from awp_ros_msgs.msg import Polytope as PolytopeMsg
from awp_ros_msgs.msg import WrenchPolytope
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Point32, PolygonStamped
import numpy as np
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header

from awp_ros.errors import InputError
from awp_ros.evaluation.result import AXES, FeasibilityResult, WrenchSetResult
from awp_ros.geometry.polytope import Polytope
from awp_ros.robot.state import RobotState
from awp_ros.ros.cdr import layout, report_status
from awp_ros.wrench.com_region import ComRegion

__all__ = [
    'KINDS',
    'STATUS_NAMES',
    'error_report',
    'leg_polytopes_msg',
    'polytope_from_msg',
    'polytope_to_msg',
    'region_polygon_msg',
    'report_bytes',
    'report_status',
    'report_msg',
    'robot_state_from_msgs',
    'stamp_to_ns',
    'wrench_polytope_msg',
]

#: WrenchPolytope.kind of each wrench set name.
KINDS = {'awp': WrenchPolytope.AWP, 'fwp': WrenchPolytope.FWP, 'fws': WrenchPolytope.FWS}
#: ``FeasibilityReport.status`` -> its name, in status order (diagnostics, summaries, JSON).
STATUS_NAMES = {
    FeasibilityReport.STATUS_OK: 'ok',
    FeasibilityReport.STATUS_WARNING: 'warning',
    FeasibilityReport.STATUS_INVALID_INPUT: 'invalid_input',
    FeasibilityReport.STATUS_STALE_INPUT: 'stale_input',
    FeasibilityReport.STATUS_ERROR: 'error',
}

#: The CDR layout of reports (:func:`report_bytes`).
_REPORT = layout(FeasibilityReport)


def _shorten(items: Sequence, limit: int = 8) -> str:
    """Return ``repr(list(items))``, eliding entries after the first ``limit``."""
    items = list(items)
    if len(items) <= limit:
        return repr(items)
    return repr(items[:limit])[:-1] + f', ... ({len(items) - limit} more)]'


def stamp_to_ns(stamp: Time) -> int:
    """Return a ``builtin_interfaces/Time`` (rclpy's or a rosbags object) as integer [ns]."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _doubles(x: np.ndarray) -> array:
    """Return ``x`` flattened row-major as ``array('d')`` (one memcpy, no Python floats)."""
    return array('d', np.ascontiguousarray(x, dtype=np.float64).tobytes())


# -- polytopes -----------------------------------------------------------------------------


def polytope_to_msg(P: Polytope, msg: PolytopeMsg | None = None) -> PolytopeMsg:
    """
    Fill an ``awp_ros_msgs/Polytope`` from a :class:`Polytope` (units unchanged).

    :param P: the polytope, ambient dimension n (3: forces [N]; 6: wrenches [N, N.m]).
    :param msg: a message to fill in place (default: a new one).
    :return: the message: ``vertices`` (k x n), ``halfspace_normals`` (m x n),
        ``halfspace_offsets`` (m), ``hull_origin`` (n), ``hull_basis`` (n x r), and the
        affine hull's equations ``equality_normals`` C ((n - r) x n, orthonormal rows) and
        ``equality_offsets`` d (C x = d), row-major.
    """
    msg = PolytopeMsg() if msg is None else msg
    msg.ambient_dimension = P.ambient_dim
    msg.dimension = int(P.dimension)
    msg.vertices = _doubles(P.vertices)
    msg.halfspace_normals = _doubles(P.A)
    msg.halfspace_offsets = _doubles(P.b)
    msg.hull_origin = _doubles(P.hull_origin)
    msg.hull_basis = _doubles(P.hull_basis)
    C, d = P.equalities
    msg.equality_normals = _doubles(C)
    msg.equality_offsets = _doubles(d)
    return msg


def polytope_from_msg(msg: PolytopeMsg) -> Polytope:
    """
    Return the :class:`Polytope` of an ``awp_ros_msgs/Polytope`` (inverse of the above).

    :raises InputError: when an array length does not fit ``ambient_dimension`` and
        ``dimension``.
    """
    n = int(msg.ambient_dimension)
    r = int(msg.dimension)
    if n <= 0 or not -1 <= r <= n:
        raise InputError(f'polytope message has dimension {r} in ambient dimension {n}')
    V = _matrix(msg.vertices, n, 'vertices')
    A = _matrix(msg.halfspace_normals, n, 'halfspace_normals')
    b = np.array(msg.halfspace_offsets, dtype=float)
    o = np.array(msg.hull_origin, dtype=float)
    U = np.array(msg.hull_basis, dtype=float)
    if b.shape != (A.shape[0],):
        raise InputError(f'polytope message has {A.shape[0]} halfspace normals but '
                         f'{b.size} offsets')
    if o.shape != (n,):
        raise InputError(f'polytope message hull_origin has {o.size} values, not {n}')
    if U.size != n * max(r, 0):
        raise InputError(f'polytope message hull_basis has {U.size} values, not {n} x '
                         f'{max(r, 0)}')
    C = _matrix(msg.equality_normals, n, 'equality_normals')
    if len(msg.equality_offsets) != C.shape[0]:
        raise InputError(f'polytope message has {C.shape[0]} equality normals but '
                         f'{len(msg.equality_offsets)} offsets')
    return Polytope(r, V, A, b, o, U.reshape(n, max(r, 0)))


def _matrix(values, n: int, name: str) -> np.ndarray:
    """Return a row-major flattened field as a (k, n) array."""
    flat = np.array(values, dtype=float)
    if flat.size % n:
        raise InputError(f'polytope message field {name} has {flat.size} values, not a '
                         f'multiple of {n}')
    return flat.reshape(-1, n)


def wrench_polytope_msg(header: Header, kind: str, stance: Sequence[str],
                        reference_point: np.ndarray, P: Polytope) -> WrenchPolytope:
    """
    Return a ``WrenchPolytope`` message.

    :param header: stamp of the answered joint state; frame_id the CoM-centred,
        world-aligned wrench frame.
    :param kind: ``'awp'``, ``'fwp'`` or ``'fws'``.
    :param stance: the stance feet summed.
    :param reference_point: the CoM in the base link frame [m] (moments are about it).
    :param P: the 6D wrench polytope [N, N.m].
    """
    msg = WrenchPolytope()
    msg.header = header
    msg.kind = KINDS[kind]
    msg.stance_feet = list(stance)
    x, y, z = (float(c) for c in reference_point)
    msg.reference_point = Point(x=x, y=y, z=z)
    polytope_to_msg(P, msg.polytope)
    return msg


def leg_polytopes_msg(header: Header, result: FeasibilityResult) -> LegPolytopes:
    """Return the ``LegPolytopes`` of an evaluation (stance feet in config order)."""
    msg = LegPolytopes()
    msg.header = header
    legs = []
    for foot, leg in result.legs.items():
        item = LegPolytope()
        item.foot = foot
        x, y, z = (float(c) for c in leg.position)
        item.position = Point(x=x, y=y, z=z)
        polytope_to_msg(leg.force_polytope, item.force_polytope)
        polytope_to_msg(leg.friction_polytope, item.friction_polytope)
        item.singular = bool(leg.singular)
        m = result.measured
        if m is None:
            f, item.slip_margin, item.torque_ratio = (math.nan,) * 3, math.nan, math.nan
        else:
            f = tuple(float(c) for c in m.forces[foot])
            item.slip_margin = float(m.slip_margins[foot])
            item.torque_ratio = float(m.torque_ratios[foot])
        item.measured_force.x, item.measured_force.y, item.measured_force.z = f
        legs.append(item)
    msg.legs = legs
    return msg


# -- reports -------------------------------------------------------------------------------


_NAN6_LIST = [math.nan] * 6


def _set_values(s: WrenchSetResult | None) -> tuple:
    """Return one set's (margin, margin_in_hull, normal, dimension, residual, feasible)."""
    if s is None:
        return math.nan, math.nan, _NAN6_LIST, 0, math.nan, False
    return (float(s.margin), float(s.margin_in_hull), np.asarray(s.normal, dtype=float).tolist(),
            max(int(s.dimension), 0), float(s.affine_residual), bool(s.feasible))


def report_bytes(header: Header, result: FeasibilityResult | None, *, compute_time: float,
                 fws: WrenchSetResult | None = None, fws_stamp: Time | None = None,
                 status: int | None = None, status_message: str | None = None,
                 fws_pending: bool = False) -> bytes:
    """
    Return the serialized ``FeasibilityReport`` of an evaluation (CDR, what is published).

    The one place where a report's fields are set; :func:`report_msg` is its message and
    :func:`error_report` the report of a message that was not evaluated (``result`` None:
    margins NaN, not feasible). ``feasible`` is ``fwp_feasible`` and the wrench in the FWS:
    ``fws_feasible`` when the FWS was computed for this message (FWS is a subset of FWP),
    else this cycle's verdict when there is one
    (:attr:`~awp_ros.evaluation.result.FeasibilityResult.fws_feasible_per_cycle`: the
    feasible region with three or more stance legs, an LP with two), else the latest FWS's;
    never true when the current FWP excludes the
    wrench. ``fws_directional_*`` are this cycle's with three or more stance legs
    (:attr:`~awp_ros.evaluation.result.FeasibilityResult.fws_directional_per_cycle`), else
    those of ``fws``. The other ``fws_*`` fields are those of ``fws``, but when the wrench
    is outside the FWS with three or more stance legs and ``fws`` was not computed for this
    message: then they are this cycle's
    (:attr:`~awp_ros.evaluation.result.FeasibilityResult.fws_margin_per_cycle`: the signed
    margin, minus the distance to the FWS, and its witness), and ``fws_stamp`` is the
    header's.

    :param header: stamp of the answered joint state; frame_id the wrench frame.
    :param result: the evaluation, or None (not evaluated).
    :param compute_time: wall time of the evaluation [s].
    :param fws: the latest FWS result (default ``result.fws``); None leaves the ``fws_*``
        fields NaN / false.
    :param fws_stamp: stamp of the joint state ``fws`` was computed for (default the header's).
    :param status: STATUS_* constant (default OK, or WARNING when the result has warnings).
    :param status_message: default the warnings joined with ``'; '``.
    :param fws_pending: no FWS of this stance yet, it is being computed (``fws_lag_s``):
        ``feasible`` is then ``fwp_feasible`` (``fws`` must be None).
    """
    stamp = header.stamp
    if result is None:
        head = (FeasibilityReport.STATUS_ERROR if status is None else status,
                (status_message or '').encode(), [], FeasibilityReport.MOTION_QUASI_STATIC,
                math.nan, math.nan, math.nan, math.nan, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        sets = (_set_values(None),) * 3
        directional = (_NAN6_LIST, _NAN6_LIST, 0, 0)
        feasible, regions, measured = False, (math.nan,) * 4, None
    else:
        if status is None:
            status = FeasibilityReport.STATUS_WARNING if result.warnings \
                else FeasibilityReport.STATUS_OK
        if status_message is None:
            status_message = '; '.join(result.warnings)
        head = (status, status_message.encode(), [f.encode() for f in result.stance],
                FeasibilityReport.MOTION_MEASURED if result.motion == 'measured'
                else FeasibilityReport.MOTION_QUASI_STATIC, float(result.mass),
                *np.asarray(result.com, dtype=float).tolist(),
                *np.asarray(result.wrench, dtype=float).tolist())
        fws = result.fws if fws is None else fws
        fresh = fws is not None and (fws_stamp is None or fws_stamp == stamp)
        # Outside the FWS with three or more legs, its margin and witness are this cycle's.
        outside = None if fresh else result.fws_margin_per_cycle
        sets = (_set_values(result.awp), _set_values(result.fwp),
                _set_values(fws if outside is None else outside))
        # This cycle's directional margins (three or more legs), else the FWS's.
        d = result.fws_directional_per_cycle
        if d is None and fws is not None:
            d = fws.directional
        if d is not None:
            plus, minus = [float(d[a][0]) for a in AXES], [float(d[a][1]) for a in AXES]
        else:
            plus, minus = _NAN6_LIST, _NAN6_LIST
        at = stamp if fws_stamp is None or outside is not None else fws_stamp
        directional = (plus, minus) + ((at.sec, at.nanosec) if fws is not None or
                                       outside is not None else (0, 0))
        # The FWS's verdict when it was computed for this joint state, else this cycle's
        # (three or more legs: the feasible region; two: their LP), else the latest FWS's.
        per_cycle = None if fresh else result.fws_feasible_per_cycle
        in_fws = (sets[2][5] or fws_pending and fws is None) if per_cycle is None else per_cycle
        feasible = bool(sets[1][5] and in_fws)
        # The regions are this cycle's: an FWS of an earlier joint state does not give them.
        regions = _region_margins(result, fws if fresh else None)
        measured = result.measured
    if measured is None:
        tail = (False, b'', math.nan, math.nan) + (math.nan,) * 6
    else:
        tail = (True, measured.slip_foot.encode(), float(measured.slip_margin),
                float(measured.torque_ratio),
                *np.asarray(measured.external_wrench, dtype=float).tolist())
    return _REPORT.pack((stamp.sec, stamp.nanosec, header.frame_id.encode(), *head,
                         *(s[i] for i in range(6) for s in sets), feasible, *directional,
                         *regions, *tail, float(compute_time)))


def report_msg(header: Header, result: FeasibilityResult, *, compute_time: float,
               fws: WrenchSetResult | None = None, fws_stamp: Time | None = None,
               status: int | None = None, status_message: str | None = None,
               fws_pending: bool = False) -> FeasibilityReport:
    """Return the ``FeasibilityReport`` message of :func:`report_bytes` (same arguments)."""
    return deserialize_message(report_bytes(
        header, result, compute_time=compute_time, fws=fws, fws_stamp=fws_stamp,
        status=status, status_message=status_message, fws_pending=fws_pending),
        FeasibilityReport)


def _region_margins(result: FeasibilityResult, fws: WrenchSetResult | None = None
                    ) -> tuple[float, float, float, float]:
    """
    Return the feasible, support and FWP regions' margins and the capture point's [m].

    NaN when empty or not computed. The support and FWP regions come from ``result``, the
    feasible region and the capture point's margin too when it has them (every cycle, by
    projection), else from ``fws`` (given only when it was computed for this joint state).
    """
    feasible, capture = result.feasible_region_with(fws)
    return tuple(math.nan if region is None else float(region.margin)
                 for region in (feasible, result.support_region, result.fwp.region)) \
        + (float(capture),)


def region_polygon_msg(header: Header, region: ComRegion | None) -> PolygonStamped:
    """
    Return a CoM region as a ``geometry_msgs/PolygonStamped`` (RViz and Foxglove draw it).

    :param header: stamp of the joint state the region was computed for; frame_id the
        wrench frame (origin the CoM, world-aligned axes).
    :param region: the region; its vertices [m] relative to the CoM become the points with
        ``z = 0`` (the CoM height): a polygon's counter-clockwise vertices, a segment's 2
        end points (two stance legs), a point's 1 point (one leg); an empty region (or
        None: not computed) is a polygon without points.
    """
    msg = PolygonStamped()
    msg.header = header
    V = np.zeros((0, 2)) if region is None else np.asarray(region.vertices, dtype=float)
    msg.polygon.points = [Point32(x=x, y=y, z=0.0) for x, y in V.reshape(-1, 2).tolist()]
    return msg


def error_report(header: Header, status: int, reason: str, *, compute_time: float = 0.0
                 ) -> FeasibilityReport:
    """
    Return a report for a message that was not evaluated: margins NaN, not feasible.

    :param status: ``STATUS_INVALID_INPUT``, ``STATUS_STALE_INPUT`` or ``STATUS_ERROR``.
    :param reason: human-readable reason (names the bad value).
    """
    return report_msg(header, None, compute_time=compute_time, status=status,
                      status_message=reason)


# -- inputs --------------------------------------------------------------------------------


def _per_name(names: list[str], values, what: str) -> dict | None:
    """Return ``{name: value}`` of an optional JointState array (None when it is empty)."""
    if not len(values):
        return None
    if len(values) != len(names):
        raise InputError(f'joint_states has {len(names)} names but {len(values)} {what}')
    return dict(zip(names, np.asarray(values, dtype=float).tolist()))


def robot_state_from_msgs(joints: JointState, contacts: ContactState | None,
                          imu: Imu | None = None, *, feet: Sequence[str],
                          use_velocities: bool = True, use_efforts: bool = True,
                          joint_names: Collection[str] | None = None,
                          notes: list[str] | None = None) -> RobotState:
    """
    Return the :class:`RobotState` of one joint-state message and the latest inputs.

    :param joints: ``name`` and ``position`` [rad] of every joint (same length); ``velocity``
        [rad/s] is used when ``use_velocities`` and it has one entry per name (empty = none).
        ``effort`` [N.m], when it has one entry per name and ``use_efforts``, gives the
        measured contact forces.
    :param contacts: stance (``in_contact``), per-foot unit normals (world-aligned axes) and
        friction coefficients; feet not named are in swing; None = no stance leg.
    :param imu: when given, ``orientation`` is the base orientation (the IMU frame must be
        aligned with the base link); an orientation covariance starting with -1 (no
        orientation estimate) is an error.
    :param feet: the config's feet (contact names must be among them).
    :param use_velocities: pass joint velocities (Coriolis terms in the bias torques).
    :param use_efforts: pass joint efforts (measured contact forces).
    :param joint_names: the model's joints (a set is fastest). Names of ``joints`` not among
        them (e.g. an arm's or a gripper's joints that the model leaves out) are ignored and
        a note naming them is appended to ``notes``. None: every name is passed on, and the
        evaluator rejects unknown ones.
    :param notes: receives the notes about ignored entries (warnings of the report).
    :raises InputError: array lengths that do not match, duplicate names, contact names that
        are not feet (the message names the bad entry).
    """
    names = list(joints.name)
    if len(joints.position) != len(names):
        raise InputError(f'joint_states has {len(names)} names but {len(joints.position)} '
                         'positions')
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise InputError(f'joint_states names joints twice: {_shorten(dup)}')
    positions = dict(zip(names, np.asarray(joints.position, dtype=float).tolist()))
    velocities = _per_name(names, joints.velocity, 'velocities') if use_velocities else None
    efforts = _per_name(names, joints.effort, 'efforts') if use_efforts else None
    if joint_names is not None:
        unknown = [n for n in names if n not in joint_names]
        if unknown:
            for n in unknown:
                del positions[n]
                if velocities is not None:
                    del velocities[n]
                if efforts is not None:
                    del efforts[n]
            if notes is not None:
                notes.append(f'joint_states names joints the model does not have, ignored: '
                             f'{_shorten(unknown)}')
    stance: list[str] = []
    normals: dict = {}
    mus: dict = {}
    if contacts is not None:
        cnames = list(contacts.names)
        unknown = [n for n in cnames if n not in feet]
        if unknown:
            raise InputError(f'contacts names unknown feet {unknown}; feet are {list(feet)}')
        if len(set(cnames)) != len(cnames):
            raise InputError(f'contacts names a foot twice: {cnames}')
        k = len(cnames)
        for field, n in (('in_contact', len(contacts.in_contact)),
                         ('normals', len(contacts.normals)),
                         ('friction_coefficients', len(contacts.friction_coefficients))):
            if n != k and not (n == 0 and field != 'in_contact'):
                raise InputError(f'contacts has {k} names but {n} {field}'
                                 + ('' if field == 'in_contact' else ' (0 = use the default)'))
        stance = [n for n, c in zip(cnames, contacts.in_contact) if c]
        if len(contacts.normals):
            normals = {n: (v.x, v.y, v.z) for n, v, c in
                       zip(cnames, contacts.normals, contacts.in_contact) if c}
        if len(contacts.friction_coefficients):
            mus = {n: float(m) for n, m, c in
                   zip(cnames, contacts.friction_coefficients, contacts.in_contact) if c}
    orientation = (0.0, 0.0, 0.0, 1.0)
    if imu is not None:
        if imu.orientation_covariance[0] == -1.0:
            raise InputError('imu has no orientation estimate (orientation_covariance[0] '
                             '== -1)')
        o = imu.orientation
        orientation = (o.x, o.y, o.z, o.w)
    return RobotState(joint_positions=positions, joint_velocities=velocities,
                      joint_efforts=efforts, base_orientation=orientation, stance=stance,
                      normals=normals, friction_coefficients=mus)
