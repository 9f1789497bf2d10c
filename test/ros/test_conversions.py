"""Conversions between the core's objects and the ROS messages (no DDS: serialised bytes)."""

from __future__ import annotations

from dataclasses import replace
import math

from awp_ros_msgs.msg import ContactState, FeasibilityReport, LegPolytopes
from awp_ros_msgs.msg import Polytope as PolytopeMsg
from awp_ros_msgs.msg import WrenchPolytope
from geometry_msgs.msg import Vector3
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from scipy.spatial import ConvexHull
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.evaluation.result import AXES
from awp_ros.geometry.polytope import Polytope
from awp_ros.ros.conversions import (error_report, leg_polytopes_msg, polytope_from_msg,
                                     polytope_to_msg, report_msg,
                                     robot_state_from_msgs, stamp_to_ns, wrench_polytope_msg)

FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


def _roundtrip(msg):
    return deserialize_message(serialize_message(msg), type(msg))


def _box(lo, hi) -> Polytope:
    V = np.array(np.meshgrid(*zip(lo, hi), indexing='ij')).reshape(3, -1).T
    A = np.vstack([np.eye(3), -np.eye(3)])
    b = np.concatenate([hi, -np.asarray(lo, dtype=float)])
    return Polytope(3, V, A, b, np.zeros(3), np.eye(3))


def test_box_polytope_roundtrips_through_serialised_bytes():
    P = _box([-1.0, -2.0, 0.5], [1.0, 2.0, 3.0])
    back = polytope_from_msg(_roundtrip(polytope_to_msg(P)))
    assert back.dimension == 3 and back.ambient_dim == 3
    np.testing.assert_array_equal(back.A, P.A)
    np.testing.assert_array_equal(back.b, P.b)
    np.testing.assert_array_equal(back.vertices, P.vertices)
    np.testing.assert_array_equal(back.hull_basis, np.eye(3))
    # Row-major flattening as Polytope.msg documents: element (i, j) at i * n + j.
    msg = polytope_to_msg(P)
    assert msg.halfspace_normals[3 * 4 + 1] == P.A[4, 1] == -1.0
    assert msg.vertices[3 * 7 + 2] == P.vertices[7, 2]


def test_flat_and_empty_polytopes_roundtrip():
    # A square in the plane z = 1 (dimension 2 in R^3): basis (3, 2) must keep its shape.
    U = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    V = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]], dtype=float)
    A = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]])
    flat = Polytope(2, V, A, np.array([1.0, 0, 1.0, 0]), np.array([0, 0, 1.0]), U)
    back = polytope_from_msg(_roundtrip(polytope_to_msg(flat)))
    assert back.dimension == 2
    np.testing.assert_array_equal(back.hull_basis, U)
    assert back.contains([0.5, 0.5, 1.0]) and not back.contains([0.5, 0.5, 1.1])
    empty = polytope_from_msg(_roundtrip(polytope_to_msg(Polytope.empty(6))))
    assert empty.is_empty and empty.ambient_dim == 6 and empty.hull_basis.shape == (6, 0)


def test_malformed_polytope_message_is_an_input_error():
    msg = polytope_to_msg(_box([0, 0, 0], [1, 1, 1]))
    msg.halfspace_offsets = msg.halfspace_offsets[:-1]
    with pytest.raises(InputError, match='6 halfspace normals but 5 offsets'):
        polytope_from_msg(msg)
    msg = PolytopeMsg(ambient_dimension=3, dimension=3, vertices=[1.0, 2.0],
                      hull_origin=[0.0, 0.0, 0.0], hull_basis=np.eye(3).ravel().tolist())
    with pytest.raises(InputError, match='vertices has 2 values'):
        polytope_from_msg(msg)


def test_wrench_and_leg_messages_carry_the_evaluation(evaluator):
    r = evaluator.evaluate(evaluator.standing_state(stance=['lf_foot', 'rh_foot', 'lh_foot']))
    header = Header(frame_id='com_world_aligned')
    header.stamp.sec, header.stamp.nanosec = 5, 7
    msg = _roundtrip(wrench_polytope_msg(header, 'fwp', r.stance, r.com, r.fwp.polytope))
    assert isinstance(msg, WrenchPolytope) and msg.kind == WrenchPolytope.FWP
    assert list(msg.stance_feet) == ['lf_foot', 'lh_foot', 'rh_foot']
    assert stamp_to_ns(msg.header.stamp) == 5_000_000_007
    P = polytope_from_msg(msg.polytope)
    np.testing.assert_array_equal(P.A, r.fwp.polytope.A)
    np.testing.assert_array_equal(P.b, r.fwp.polytope.b)
    legs = _roundtrip(leg_polytopes_msg(header, r))
    assert isinstance(legs, LegPolytopes)
    assert [leg.foot for leg in legs.legs] == list(r.stance)
    for leg in legs.legs:
        ref = r.legs[leg.foot]
        np.testing.assert_array_equal([leg.position.x, leg.position.y, leg.position.z],
                                      ref.position)
        Q = polytope_from_msg(leg.friction_polytope)
        np.testing.assert_array_equal(Q.vertices, ref.friction_polytope.vertices)
        # The message's vertices span the same volume as an independent qhull of them.
        F = polytope_from_msg(leg.force_polytope)
        assert ConvexHull(F.vertices).volume == pytest.approx(
            ConvexHull(ref.force_polytope.vertices).volume, rel=1e-12)


def test_report_fields_equal_the_result(evaluator):
    r = evaluator.evaluate(evaluator.standing_state())
    rep = _roundtrip(report_msg(Header(frame_id='w'), r, compute_time=0.001))
    assert rep.status == FeasibilityReport.STATUS_OK and rep.status_message == ''
    assert rep.fwp_margin == r.fwp.margin and rep.awp_margin == r.awp.margin
    assert rep.fws_margin == r.fws.margin
    np.testing.assert_array_equal(rep.fwp_normal, r.fwp.normal)
    assert rep.awp_dimension == 6 and rep.fws_affine_residual == r.fws.affine_residual
    assert rep.wrench.force.z == r.wrench[2] and rep.wrench.torque.y == r.wrench[4]
    assert rep.feasible == (r.fwp.feasible and r.fws.feasible) and rep.feasible
    # This cycle's directional margins (four legs: every cycle, by LPs), those of the FWS.
    np.testing.assert_array_equal(rep.fws_directional_plus,
                                  [r.fws_directional_per_cycle[a][0] for a in AXES])
    np.testing.assert_allclose(rep.fws_directional_minus,
                               [r.fws.directional[a][1] for a in AXES], rtol=1e-7, atol=1e-5)
    assert rep.compute_time == 0.001


def _expected_report(header, r, fws, fws_stamp, status, message, compute_time):
    """Return a report built field by field with the generated setters (the reference)."""
    msg = FeasibilityReport()
    msg.header, msg.status, msg.status_message = header, status, message
    msg.stance_feet, msg.motion = list(r.stance), int(r.motion == 'measured')
    msg.mass = r.mass
    msg.com.x, msg.com.y, msg.com.z = r.com.tolist()
    f, t = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z, t.x, t.y, t.z = r.wrench.tolist()
    for name, s in (('awp', r.awp), ('fwp', r.fwp), ('fws', fws)):
        for field in ('margin', 'margin_in_hull', 'affine_residual'):
            setattr(msg, f'{name}_{field}', math.nan if s is None else getattr(s, field))
        setattr(msg, f'{name}_normal', np.full(6, np.nan) if s is None else s.normal)
        setattr(msg, f'{name}_dimension', 0 if s is None else max(s.dimension, 0))
        setattr(msg, f'{name}_feasible', s is not None and bool(s.feasible))
    msg.feasible = msg.fwp_feasible and msg.fws_feasible
    d = r.fws_directional_per_cycle              # this cycle's (3+ legs), else the FWS's
    if d is None and fws is not None:
        d = fws.directional
    msg.fws_directional_plus = [math.nan] * 6 if d is None else [d[a][0] for a in AXES]
    msg.fws_directional_minus = [math.nan] * 6 if d is None else [d[a][1] for a in AXES]
    if fws is not None:
        msg.fws_stamp = fws_stamp
    region, capture = r.feasible_region_with(fws)
    for name, reg in (('feasible_region', region), ('support_region', r.support_region),
                      ('fwp_region', r.fwp.region)):
        setattr(msg, f'{name}_margin', math.nan if reg is None else reg.margin)
    msg.capture_point_margin = capture
    m = r.measured
    msg.measured_forces = m is not None
    msg.slip_foot = '' if m is None else m.slip_foot
    msg.slip_margin = math.nan if m is None else m.slip_margin
    msg.torque_ratio = math.nan if m is None else m.torque_ratio
    f, t = msg.external_wrench.force, msg.external_wrench.torque
    f.x, f.y, f.z, t.x, t.y, t.z = [math.nan] * 6 if m is None else m.external_wrench.tolist()
    msg.compute_time = compute_time
    return msg


def _same(a, b) -> bool:
    """Return whether two reports are equal, NaN equal to NaN."""
    return serialize_message(a) == serialize_message(b) or all(
        np.array_equal(np.asarray(x, dtype=float), np.asarray(y, dtype=float), equal_nan=True)
        if not isinstance(x, (str, list)) and not hasattr(x, 'get_fields_and_field_types')
        else (_same(x, y) if hasattr(x, 'get_fields_and_field_types') else x == y)
        for x, y in ((getattr(a, n), getattr(b, n)) for n in a.get_fields_and_field_types()))


@pytest.mark.parametrize('stance, efforts', [(None, False), (FEET[:2], False), (FEET[:3], True),
                                             ((), False)])
def test_every_report_field_is_the_results(evaluator, stance, efforts):
    st = evaluator.standing_state(stance=stance)
    st.base_twist = np.array([0.3, 0.1, 0.0, 0.0, 0.0, 0.2])
    if efforts:
        st.joint_efforts = dict.fromkeys(st.joint_positions, 5.0)
    r = evaluator.evaluate(st)
    header = Header(frame_id='wrench_frame_é')
    header.stamp.sec, header.stamp.nanosec = 12, 345
    earlier = Header().stamp
    earlier.sec = 11
    bare = replace(r, fws=None)
    for fws, fws_stamp, pending in ((r.fws, header.stamp, False), (r.fws, earlier, False),
                                    (None, None, False), (None, None, True)):
        for status, message in ((0, ''), (1, 'a warning; and another')):
            rep = report_msg(header, r if fws else bare, compute_time=0.25, fws=fws,
                             fws_stamp=fws_stamp, status=status, status_message=message,
                             fws_pending=pending)
            ref = _expected_report(header, r if fws else bare, fws,
                                   fws_stamp or header.stamp, status, message, 0.25)
            if fws_stamp is earlier and r.feasible_region_per_cycle is None:
                ref.feasible_region_margin = ref.capture_point_margin = math.nan
            if pending:
                ref.feasible = ref.fwp_feasible
            # Without an FWS of this joint state: this cycle's verdict, the CoM in the
            # feasible region (three or more legs) or the two legs' LP, else the latest
            # FWS's as above.
            region = r.feasible_region_per_cycle
            if fws_stamp is not header.stamp and region is not None and len(r.stance) >= 3:
                ref.feasible = ref.fwp_feasible and region.contains(np.zeros(2))
            if fws_stamp is not header.stamp and len(r.stance) == 2:
                assert r.two_leg_fws_feasible is not None
                ref.feasible = ref.fwp_feasible and r.two_leg_fws_feasible
            assert _same(rep, ref)


def test_error_report_has_nan_margins_and_the_reason():
    rep = _roundtrip(error_report(Header(), FeasibilityReport.STATUS_INVALID_INPUT,
                                  "joint_positions lacks joints ['lf_kfe_joint']"))
    assert rep.status == FeasibilityReport.STATUS_INVALID_INPUT
    assert 'lf_kfe_joint' in rep.status_message
    assert math.isnan(rep.fwp_margin) and np.all(np.isnan(rep.fws_normal))
    assert not rep.feasible and not rep.awp_feasible


def _joints(names, positions, velocities=()):
    return JointState(name=list(names), position=list(positions), velocity=list(velocities))


def test_robot_state_from_messages_maps_every_field():
    js = _joints(['a', 'b'], [0.1, 0.2], [1.0, 2.0])
    c = ContactState(names=['lf_foot', 'rh_foot', 'rf_foot'], in_contact=[True, True, False],
                     normals=[Vector3(z=1.0), Vector3(x=0.1, z=1.0), Vector3(z=1.0)],
                     friction_coefficients=[0.5, 0.6, 0.7])
    imu = Imu()
    imu.orientation.z, imu.orientation.w = math.sin(0.1), math.cos(0.1)
    s = robot_state_from_msgs(js, c, imu, feet=FEET)
    assert s.joint_positions == {'a': 0.1, 'b': 0.2}
    assert s.joint_velocities == {'a': 1.0, 'b': 2.0}
    assert s.stance == ['lf_foot', 'rh_foot']
    assert s.normals == {'lf_foot': (0.0, 0.0, 1.0), 'rh_foot': (0.1, 0.0, 1.0)}
    assert s.friction_coefficients == {'lf_foot': 0.5, 'rh_foot': 0.6}
    assert s.base_orientation == (0.0, 0.0, math.sin(0.1), math.cos(0.1))
    s = robot_state_from_msgs(js, None, feet=FEET, use_velocities=False)
    assert s.joint_velocities is None and s.stance == [] and s.normals == {}


@pytest.mark.parametrize('js, contacts, imu, match', [
    (_joints(['a', 'b'], [0.1]), None, None, '2 names but 1 positions'),
    (_joints(['a', 'a'], [0.1, 0.2]), None, None, r"joints twice: \['a'\]"),
    (_joints(['a'], [0.1], [1.0, 2.0]), None, None, '1 names but 2 velocities'),
    (_joints(['a'], [0.1]), ContactState(names=['lf_hand'], in_contact=[True]), None,
     "unknown feet \\['lf_hand'\\]"),
    (_joints(['a'], [0.1]), ContactState(names=['lf_foot'], in_contact=[]), None,
     '1 names but 0 in_contact'),
    (_joints(['a'], [0.1]), ContactState(names=['lf_foot'], in_contact=[True],
                                         friction_coefficients=[0.5, 0.5]), None,
     '1 names but 2 friction_coefficients'),
    (_joints(['a'], [0.1]), None, Imu(orientation_covariance=[-1.0] + [0.0] * 8),
     'no orientation estimate'),
])
def test_malformed_input_messages_raise_input_errors(js, contacts, imu, match):
    with pytest.raises(InputError, match=match):
        robot_state_from_msgs(js, contacts, imu, feet=FEET)


def test_report_regions_are_never_an_earlier_cycles(evaluator):
    # Without this cycle's projection (a singular leg), the feasible region and the capture
    # point's margin come from an FWS computed for this joint state only, else NaN.
    st = evaluator.standing_state()
    st.base_twist = np.array([0.3, 0.1, 0.0, 0.0, 0.0, 0.0])
    result = evaluator.evaluate(st)
    assert result.feasible_region_per_cycle is not None
    bare = replace(result, feasible_region_per_cycle=None, capture_margin_per_cycle=math.nan)
    now, before = Header(), Header()
    now.stamp.sec, before.stamp.sec = 7, 6
    same = report_msg(now, bare, compute_time=0.0, fws=result.fws, fws_stamp=now.stamp)
    old = report_msg(now, bare, compute_time=0.0, fws=result.fws, fws_stamp=before.stamp)
    assert same.feasible_region_margin == result.fws.region.margin
    assert same.capture_point_margin == result.fws.capture_point_margin
    assert math.isnan(old.feasible_region_margin) and math.isnan(old.capture_point_margin)
    assert old.fws_margin == same.fws_margin      # the FWS fields still carry the latest FWS
    # With this cycle's projection the region is this cycle's whatever the FWS's age.
    full = report_msg(now, result, compute_time=0.0, fws=result.fws, fws_stamp=before.stamp)
    assert full.feasible_region_margin == result.feasible_region_per_cycle.margin
