"""
The CoM region outputs of a cycle: PolygonStamped messages and report margins.

Through the pipeline (real messages), for 4 down to 0 stance legs: the polygons carry the
result's regions (the core's slices) as points in the wrench frame, the reports their
margins (NaN when empty). On level ground and quasi-static, the support region is checked
against the feet themselves: their hull, the segment between two feet, the one foot.
"""

from __future__ import annotations

import math

from awp_ros_msgs.msg import FeasibilityReport
from geometry_msgs.msg import PolygonStamped, WrenchStamped
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from scipy.spatial import ConvexHull

from awp_ros.bags.message_types import OUTPUT_TYPES, serialize, typestore
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.robot.parameters import PipelineParams
from awp_ros.ros.conversions import region_polygon_msg, stamp_to_ns
from awp_ros.ros.cycle import OUTPUTS
from awp_ros.ros.pipeline import Pipeline
from cases import contacts_msg, FEET, joints_msg, stamp, T0

S = FeasibilityReport
F32 = 1e-6      # [m] Point32 holds float32 coordinates


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


def points(msg: PolygonStamped) -> np.ndarray:
    out = np.array([[p.x, p.y, p.z] for p in msg.polygon.points]).reshape(-1, 3)
    assert np.all(out[:, 2] == 0.0)                  # the CoM height
    return out[:, :2]


def run(evaluator, stance, **params):
    pl = Pipeline('hyq', PipelineParams(**params))
    pl.on_contacts(contacts_msg(T0, stance=stance))
    return pl, pl.on_joint_state(joints_msg(evaluator, T0 + 1000))


@pytest.mark.parametrize('stance, dimension', [(FEET, 2), (FEET[:3], 2),
                                               (['lf_foot', 'rh_foot'], 1),
                                               (['rf_foot'], 0), ([], -1)])
def test_region_polygons_and_margins_for_each_stance(evaluator, stance, dimension):
    _, cycle = run(evaluator, stance, fws_rate_hz=0.0)
    r, rep = cycle.result, cycle.report
    assert rep.status in (S.STATUS_OK, S.STATUS_WARNING)
    out = cycle.messages()
    assert {'feasible_region', 'support_region'} <= set(out) <= set(OUTPUTS)
    for name in ('feasible_region', 'support_region'):
        msg = out[name]
        region = getattr(r, name)
        assert msg.header.frame_id == 'com_world_aligned'
        assert stamp_to_ns(msg.header.stamp) == T0 + 1000
        np.testing.assert_allclose(points(msg), region.vertices, atol=F32)
        # Real serialised bytes, with the length the bags store.
        back = deserialize_message(serialize_message(msg), PolygonStamped)
        np.testing.assert_allclose(points(back), region.vertices, atol=F32)
        raw = serialize(msg, OUTPUT_TYPES[name])
        assert len(typestore().deserialize_cdr(raw, OUTPUT_TYPES[name]).polygon.points) == \
            region.vertices.shape[0]
    for name in ('feasible_region', 'support_region', 'fwp_region'):
        region, value = getattr(r, name), getattr(rep, f'{name}_margin')
        if region.is_empty:
            assert math.isnan(value)
        else:
            assert value == region.margin
    assert math.isnan(rep.capture_point_margin)               # no base velocity
    feet = np.array([leg.position[:2] for leg in r.legs.values()]).reshape(-1, 2)
    sup = r.support_region
    assert sup.dimension == dimension
    if dimension == 2:
        hull = feet[ConvexHull(feet).vertices]
        assert sup.vertices.shape == hull.shape
        assert all(np.min(np.linalg.norm(hull - v, axis=1)) < 1e-9 for v in sup.vertices)
    elif dimension == 1:       # the CoM must be on the line between the two feet
        assert {tuple(np.round(v, 9)) for v in sup.vertices} == \
            {tuple(np.round(v, 9)) for v in feet}
        assert rep.support_region_margin < 0.0
    elif dimension == 0:       # above the one foot
        np.testing.assert_allclose(sup.vertices[0], feet[0], atol=1e-9)
        assert rep.support_region_margin == pytest.approx(-np.linalg.norm(feet[0]))
    else:
        assert points(out['support_region']).shape == (0, 2)
        assert math.isnan(rep.support_region_margin) and math.isnan(rep.feasible_region_margin)


def test_feasible_region_is_sent_every_cycle_and_the_fws_at_its_rate(evaluator):
    pl, first = run(evaluator, FEET, fws_rate_hz=10.0)
    assert first.fws_computed and first.feasible_region() is not None
    pl.on_contacts(contacts_msg(T0 + 2 * 10**6))
    second = pl.on_joint_state(joints_msg(evaluator, T0 + 2 * 10**6, dq=0.03))
    # The FWS waits for its rate; the feasible region (by projection) is this cycle's.
    assert not second.fws_computed and second.feasible_region() is not None
    assert second.support_region() is not None
    rep = second.report
    assert stamp_to_ns(rep.fws_stamp) == T0 + 1000
    assert rep.feasible_region_margin == second.result.feasible_region.margin
    assert rep.feasible_region_margin != first.result.feasible_region.margin
    points = second.feasible_region().polygon.points
    np.testing.assert_allclose([[q.x, q.y] for q in points],
                               second.result.feasible_region.vertices, atol=1e-6)
    assert rep.support_region_margin == second.result.support_region.margin
    assert rep.support_region_margin != first.report.support_region_margin
    # The reference wrench report: the regions at the planned wrench.
    w = first.result.wrench + np.array([0.0, 0.0, 0.0, 40.0, 0.0, 0.0])
    msg = stamp(WrenchStamped(), T0 + 1000)
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = w[:3].tolist()
    msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z = w[3:].tolist()
    ref = pl.on_wrench_reference(msg)
    want = evaluator.with_wrench(first.result, w)
    assert ref.support_region_margin == pytest.approx(want.support_region.margin, abs=1e-12)
    assert ref.feasible_region_margin == pytest.approx(want.feasible_region.margin,
                                                       abs=1e-12)
    assert ref.support_region_margin != pytest.approx(first.report.support_region_margin,
                                                      abs=1e-4)


def test_unevaluated_cycles_send_no_polygon(evaluator):
    pl = Pipeline('hyq', PipelineParams())
    cycle = pl.on_joint_state(joints_msg(evaluator, T0))       # no contacts yet
    assert cycle.report.status == S.STATUS_STALE_INPUT
    assert cycle.feasible_region() is None and cycle.support_region() is None
    for name in ('feasible_region', 'support_region', 'fwp_region', 'capture_point'):
        assert math.isnan(getattr(cycle.report, f'{name}_margin'))
    empty = region_polygon_msg(cycle.header, None)
    assert empty.polygon.points == []


def test_capture_point_only_with_odometry(evaluator):
    for odometry in (False, True):
        pl = Pipeline('hyq', PipelineParams(fws_rate_hz=0.0, use_odometry=odometry,
                                            motion='measured'))
        for k in range(3):                      # joint states 2 ms apart, robot moving +x
            ns = T0 + k * 2 * 10**6
            pl.on_contacts(contacts_msg(ns))
            odom = stamp(Odometry(), ns)
            odom.pose.pose.orientation.w = 1.0
            odom.twist.twist.linear.x = 0.3
            pl.on_odometry(odom)
            cycle = pl.on_joint_state(joints_msg(evaluator, ns + 1000))
        r, rep = cycle.result, cycle.report
        assert rep.status == S.STATUS_OK, rep.status_message
        if not odometry:                        # the base's linear velocity is unknown
            assert r.com_velocity is None and math.isnan(rep.capture_point_margin)
            continue
        np.testing.assert_allclose(r.com_velocity, [0.3, 0.0, 0.0], atol=1e-9)
        h = -np.mean([leg.position[2] for leg in r.legs.values()])
        np.testing.assert_allclose(r.capture_point, [0.3 * math.sqrt(h / 9.81), 0.0],
                                   atol=1e-9)
        assert rep.capture_point_margin == r.capture_point_margin
        assert 0.0 < rep.capture_point_margin < rep.feasible_region_margin
