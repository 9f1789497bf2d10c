"""The message-level pipeline: one report per joint state, stamps, throttles, errors."""

from __future__ import annotations

from dataclasses import replace
import math

from awp_ros_msgs.msg import ContactState, FeasibilityReport
from geometry_msgs.msg import Vector3
import numpy as np
import pytest
from scipy.optimize import linprog
from sensor_msgs.msg import Imu, JointState

from awp_ros.errors import ConfigError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.robot.config import load_config
from awp_ros.robot.parameters import PipelineParams
from awp_ros.robot.state import RobotState
from awp_ros.ros.conversions import polytope_from_msg, stamp_to_ns
from awp_ros.ros.cycle import OUTPUTS
from awp_ros.ros.pipeline import Pipeline, REFERENCE_HISTORY
from cases import contacts_msg, efforts_for, FEET, joints_msg, stamp, T0

S = FeasibilityReport


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


def _pipeline(**kw) -> Pipeline:
    return Pipeline('hyq', PipelineParams(**kw))


def test_report_equals_the_evaluator_for_the_same_state(evaluator):
    pl = _pipeline(fws_rate_hz=0.0)
    pl.on_contacts(contacts_msg(T0, stance=['lf_foot', 'rf_foot', 'rh_foot'], mu=[0.5] * 4))
    cycle = pl.on_joint_state(joints_msg(evaluator, T0 + 1000, dq=0.05))
    rep = cycle.report
    state = evaluator.standing_state(stance=['lf_foot', 'rf_foot', 'rh_foot'],
                                     friction_coefficient=0.5)
    state.joint_positions = {k: v + 0.05 for k, v in state.joint_positions.items()}
    ref = evaluator.evaluate(state)
    assert rep.status == S.STATUS_OK, rep.status_message
    assert stamp_to_ns(rep.header.stamp) == T0 + 1000
    assert rep.header.frame_id == 'com_world_aligned'
    for name in ('awp', 'fwp', 'fws'):
        assert getattr(rep, f'{name}_margin') == pytest.approx(getattr(ref, name).margin,
                                                               abs=1e-9)
    assert list(rep.stance_feet) == ['lf_foot', 'rf_foot', 'rh_foot']
    assert stamp_to_ns(rep.fws_stamp) == T0 + 1000 and cycle.fws_computed
    assert rep.compute_time > 0.0
    out = cycle.messages()
    assert set(out) == set(OUTPUTS)
    assert all(stamp_to_ns(m.header.stamp) == T0 + 1000 for k, m in out.items()
               if k != 'markers')
    assert all(stamp_to_ns(m.header.stamp) == T0 + 1000 for m in out['markers'].markers)


def test_every_joint_state_gets_a_report_whatever_is_wrong(evaluator):
    pl = _pipeline(contacts_timeout_s=0.5)
    js = joints_msg(evaluator, T0)
    first = pl.on_joint_state(js)
    assert first.report.status == S.STATUS_STALE_INPUT
    assert 'no contacts message received yet' in first.report.status_message
    assert first.messages().keys() == {'report', 'markers'}    # markers show the reason
    pl.on_contacts(contacts_msg(T0 - 2 * 10**9))
    stale = pl.on_joint_state(joints_msg(evaluator, T0 + 10**6))
    assert stale.report.status == S.STATUS_STALE_INPUT and 'contacts is stale' in \
        stale.report.status_message
    pl.on_contacts(contacts_msg(T0))
    bad = joints_msg(evaluator, T0 + 2 * 10**6)
    bad.position[3] = math.nan
    rep = pl.on_joint_state(bad).report
    assert rep.status == S.STATUS_INVALID_INPUT and 'lh_haa_joint' in rep.status_message
    assert math.isnan(rep.fwp_margin) and not rep.feasible
    pl.on_contacts(stamp(ContactState(names=['lf_hand'], in_contact=[True]), T0))
    rep = pl.on_joint_state(joints_msg(evaluator, T0 + 3 * 10**6)).report
    assert rep.status == S.STATUS_INVALID_INPUT and 'lf_hand' in rep.status_message
    pl.on_contacts(contacts_msg(T0))
    good = pl.on_joint_state(joints_msg(evaluator, T0 + 4 * 10**6)).report
    assert good.status == S.STATUS_OK and good.feasible


def test_a_stamp_going_back_warns_and_restarts_the_throttles(evaluator):
    pl = _pipeline()
    pl.on_contacts(contacts_msg(T0))
    assert pl.on_joint_state(joints_msg(evaluator, T0 + 10**6)).markers_due
    assert not pl.on_joint_state(joints_msg(evaluator, T0 + 2 * 10**6)).markers_due
    back = pl.on_joint_state(joints_msg(evaluator, T0))
    assert back.report.status == S.STATUS_WARNING and 'went back' in back.report.status_message
    assert back.markers_due and back.fws_computed


def test_throttles_follow_stamps_and_a_stance_change_forces_the_fws(evaluator):
    pl = _pipeline(marker_rate_hz=30.0, fws_rate_hz=10.0)
    pl.on_contacts(contacts_msg(T0))
    markers = fws = 0
    fws_stamps = set()
    for i in range(1000):                                 # 1 s of 1 kHz joint states
        if i % 10 == 0:                                   # 100 Hz contacts
            pl.on_contacts(contacts_msg(T0 + i * 10**6, stance=FEET if i < 550 else FEET[:3]))
        c = pl.on_joint_state(joints_msg(evaluator, T0 + i * 10**6))
        markers += c.markers_due
        fws += c.fws_computed
        fws_stamps.add(stamp_to_ns(c.report.fws_stamp))
        assert (c.fws() is not None) == c.fws_computed
        assert (c.markers() is not None) == c.markers_due
    assert markers == 30
    # By rate at 0, 100, ..., 500 ms, the stance change at 550 ms, then by rate again a
    # period after it: 650, ..., 950 ms.
    assert fws == 11
    expected = [0, 100, 200, 300, 400, 500, 550, 650, 750, 850, 950]
    assert sorted(fws_stamps) == [T0 + t * 10**6 for t in expected]
    assert _pipeline(marker_rate_hz=0.0).on_joint_state(joints_msg(evaluator, T0)).markers() \
        is None


def test_runtime_config_change_applies_to_the_next_message(evaluator):
    pl = _pipeline(fws_rate_hz=0.0)
    pl.on_contacts(contacts_msg(T0))
    before = pl.on_joint_state(joints_msg(evaluator, T0 + 1)).report
    limits = {j: (-75.0, 75.0) for j in evaluator.model.joint_names}
    from dataclasses import replace
    pl.set_config(replace(pl.config, friction_coefficient=0.3, torque_limits=limits))
    after = pl.on_joint_state(joints_msg(evaluator, T0 + 2)).report
    ref = FeasibilityEvaluator(pl.config).evaluate(
        FeasibilityEvaluator(pl.config).standing_state())
    assert after.fwp_margin == pytest.approx(ref.fwp.margin, abs=1e-9)
    assert after.awp_margin < before.awp_margin
    with pytest.raises(ConfigError, match='marker_frame_id'):
        pl.set_params(PipelineParams(marker_frame_id='odom'))
    with pytest.raises(ConfigError, match='fws_rate_hz'):
        PipelineParams(fws_rate_hz=-1.0)


def test_imu_orientation_rotates_the_base_and_needs_a_message(evaluator):
    pl = _pipeline(use_imu=True, marker_frame_id='base_link')
    pl.on_contacts(contacts_msg(T0))
    rep = pl.on_joint_state(joints_msg(evaluator, T0 + 1)).report
    assert rep.status == S.STATUS_STALE_INPUT and 'no imu' in rep.status_message
    imu = stamp(Imu(), T0)
    imu.orientation.y, imu.orientation.w = math.sin(0.1), math.cos(0.1)   # pitch 0.2 rad
    # At rest the IMU (frame '' = the base link) reads the specific force R^T (0, 0, g).
    imu.linear_acceleration.x = -math.sin(0.2) * 9.81
    imu.linear_acceleration.z = math.cos(0.2) * 9.81
    pl.on_imu(imu)
    cycle = pl.on_joint_state(joints_msg(evaluator, T0 + 10**8))
    ref = evaluator.evaluate(evaluator.standing_state(
        base_orientation=[0.0, math.sin(0.1), 0.0, math.cos(0.1)]))
    assert cycle.report.fwp_margin == pytest.approx(ref.fwp.margin, abs=1e-9)
    assert cycle.report.fwp_margin != pytest.approx(
        evaluator.evaluate(evaluator.standing_state()).fwp.margin, abs=1e-6)
    assert cycle.markers().markers[1].header.frame_id == 'base_link'


def test_from_parameters_reads_a_params_file_mapping(repo):
    import yaml
    doc = yaml.safe_load((repo / 'config' / 'hyq.yaml').read_text())
    doc['/**']['ros__parameters'].update(fws_rate_hz=5, marker_rate_hz=15.0)
    pl = Pipeline.from_parameters(doc)
    assert pl.config.robot_name == 'hyq' and pl.params.fws_rate_hz == 5.0
    assert pl.params.marker_rate_hz == 15.0 and pl.root_link == 'base_link'
    with pytest.raises(ConfigError, match='use_imu must be true or false'):
        PipelineParams.from_dict({'use_imu': 'yes'})
    assert np.isclose(pl.config.friction_coefficient, 0.7)


def test_inputs_are_paired_by_stamp_as_in_the_recorded_order(evaluator):
    """A lagging node has taken contacts newer than the joint state it evaluates."""
    pl = _pipeline(use_imu=True, motion='quasi_static')     # the IMU's orientation only
    ms = 10**6
    for i, stance in enumerate([FEET, FEET[:2], FEET[:3]]):      # at 0, 10 and 20 ms
        pl.on_contacts(contacts_msg(T0 + 10 * i * ms, stance=stance))
    for i in range(3):
        imu = stamp(Imu(), T0 + 10 * i * ms)
        imu.orientation.x, imu.orientation.w = math.sin(0.05 * i), math.cos(0.05 * i)
        pl.on_imu(imu)
    stances = []
    for t in (5, 12, 25, 26):
        rep = pl.on_joint_state(joints_msg(evaluator, T0 + t * ms)).report
        assert rep.status == S.STATUS_OK, rep.status_message
        stances.append(len(rep.stance_feet))
    assert stances == [4, 2, 3, 3]
    roll = evaluator.evaluate(evaluator.standing_state(
        stance=FEET[:3], base_orientation=[math.sin(0.1), 0.0, 0.0, math.cos(0.1)]))
    assert rep.fwp_margin == pytest.approx(roll.fwp.margin, abs=1e-9)
    # Every buffered input is newer than the joint state: the earliest one is used.
    pl = _pipeline()
    pl.on_contacts(contacts_msg(T0 + 3 * ms, stance=FEET[:3]))
    pl.on_contacts(contacts_msg(T0 + 4 * ms, stance=FEET[:2]))
    assert len(pl.on_joint_state(joints_msg(evaluator, T0)).report.stance_feet) == 3


def pyramid_rows(n, mu, sides):
    """Rows ``a . f <= 0`` of the N-sided pyramid (t1 = world x on the contact plane)."""
    t1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    th = 2 * np.pi * np.arange(sides) / sides
    return np.cos(th)[:, None] * t1 + np.sin(th)[:, None] * t2 - mu * np.cos(np.pi / sides) * n


@pytest.mark.parametrize('sides', [3, 6, 8])
def test_pyramid_sides_from_the_config_reach_reports_polytopes_and_markers(evaluator, sides):
    config = replace(load_config('hyq'), pyramid_sides=sides)
    pl = Pipeline(config, PipelineParams(fws_rate_hz=0.0))
    normals = {'lf_foot': [0.3, 0.0, 1.0], 'rf_foot': [0.0, -0.25, 1.0]}
    mus = [0.45, 0.9, 0.6, 0.75]
    msg = ContactState(names=FEET, in_contact=[True] * 4, friction_coefficients=mus,
                       normals=[Vector3(**dict(zip('xyz', normals.get(f, [0.0, 0.0, 1.0]))))
                                for f in FEET])
    pl.on_contacts(stamp(msg, T0))
    q = evaluator.model.standing_q + 0.03
    cycle = pl.on_joint_state(joints_msg(evaluator, T0 + 1000, dq=0.03))
    assert cycle.report.status == S.STATUS_WARNING        # the non-unit normals
    unit = {f: (np.array(n) / np.linalg.norm(n)).tolist() for f, n in normals.items()}
    state = RobotState(joint_positions=dict(zip(evaluator.model.joint_names, q.tolist())),
                       normals=unit, friction_coefficients=dict(zip(FEET, mus)))
    ref = FeasibilityEvaluator(config).evaluate(state)
    four = evaluator.evaluate(state)
    for name in ('awp', 'fwp', 'fws'):
        got = getattr(cycle.report, f'{name}_margin')
        assert got == pytest.approx(getattr(ref, name).margin, abs=1e-9), name
        if name != 'awp':                                   # the sides matter
            assert abs(got - getattr(four, name).margin) > 1e-3, name
    # Friction-bounded polytopes of the message: the message's force polytope cut by the
    # N-sided pyramid of each foot's normal and mu (an LP per direction).
    rng = np.random.default_rng(sides)
    for leg, foot, mu in zip(cycle.leg_polytopes().legs, FEET, mus):
        n = np.array(unit.get(foot, [0.0, 0.0, 1.0]))
        F, Q = polytope_from_msg(leg.force_polytope), polytope_from_msg(leg.friction_polytope)
        rows = np.vstack([pyramid_rows(n, mu, sides), -n])
        for d in rng.normal(size=(5, 3)):
            lp = linprog(-d, A_ub=np.vstack([F.A, rows]),
                         b_ub=np.concatenate([F.b, np.zeros(len(rows))]),
                         bounds=[(None, None)] * 3, method='highs')
            assert lp.status == 0
            assert np.max(Q.vertices @ d) == pytest.approx(-lp.fun, rel=1e-7, abs=1e-6)
    # The drawn pyramids have N sides: 2 N triangles (both faces) per leg.
    pyramids = [m for m in cycle.markers().markers if m.ns.startswith('friction_pyramid')]
    assert len(pyramids) == 4
    assert all(len(m.points) == 6 * sides for m in pyramids)


def test_stale_timeout_zero_disables_the_staleness_check(evaluator):
    pl = _pipeline(stale_timeout_s=0.0)
    pl.on_contacts(contacts_msg(T0))
    rep = pl.on_joint_state(joints_msg(evaluator, T0 + 10 * 10**9)).report   # 10 s later
    assert rep.status == S.STATUS_OK, rep.status_message
    ref = evaluator.evaluate(evaluator.standing_state())
    assert rep.fwp_margin == pytest.approx(ref.fwp.margin, abs=1e-9)


def test_a_node_lagging_far_behind_pairs_each_joint_state_with_its_imu(evaluator):
    # A node 100 joint states (0.2 s at 500 Hz) behind has taken every IMU reading of its
    # lag before it evaluates the first joint state: each joint state still gets the
    # motion of the reading at its stamp, the reports equal those of the recorded order.
    # (The estimator's IMU history was 32 readings: beyond a 64 ms lag the base was level
    # and unaccelerated, silently.)
    ms, n = 10**6, 100

    def imu(i):
        msg = stamp(Imu(), T0 + 2 * i * ms)
        roll = 0.05 * math.sin(0.05 * i)
        msg.orientation.x, msg.orientation.w = math.sin(roll / 2), math.cos(roll / 2)
        msg.angular_velocity.x = 1.25 * math.cos(0.05 * i)
        a = msg.linear_acceleration
        a.x, a.y, a.z = 1.5 * math.sin(0.03 * i), -1.0, 9.81 + 0.5 * math.cos(0.04 * i)
        return msg

    def wrench(rep):
        f, t = rep.wrench.force, rep.wrench.torque
        return [f.x, f.y, f.z, t.x, t.y, t.z]

    in_order, lagging = _pipeline(use_imu=True), _pipeline(use_imu=True)
    for pl in (in_order, lagging):
        pl.on_contacts(contacts_msg(T0))
    expected = []
    for i in range(n):
        in_order.on_imu(imu(i))
        expected.append(in_order.on_joint_state(
            joints_msg(evaluator, T0 + 2 * i * ms, dq=0.002 * i)).report)
    for i in range(n):
        lagging.on_imu(imu(i))
    for i, ref in enumerate(expected):
        rep = lagging.on_joint_state(joints_msg(evaluator, T0 + 2 * i * ms, dq=0.002 * i)).report
        assert rep.status == ref.status <= S.STATUS_WARNING, rep.status_message
        assert rep.status_message == ref.status_message
        assert wrench(rep) == wrench(ref), i
        assert rep.fwp_margin == ref.fwp_margin
    # The readings' motion is in the wrench: tens of N sideways (none when standing still).
    assert max(math.hypot(*wrench(r)[:2]) for r in expected) > 20.0


# -- real robots' conventions: on-change contacts, no contacts, split joint states --------


def test_a_contacts_message_holds_until_the_next_one_unless_a_timeout_is_set(evaluator):
    pl = _pipeline()
    pl.on_contacts(contacts_msg(T0, stance=['lf_foot', 'rf_foot', 'rh_foot']))
    for dt_s in (0.001, 0.6, 30.0):            # an on-change publisher: one message
        rep = pl.on_joint_state(joints_msg(evaluator, T0 + int(dt_s * 1e9))).report
        assert rep.status == S.STATUS_OK, rep.status_message
        assert list(rep.stance_feet) == ['lf_foot', 'rf_foot', 'rh_foot']
    pl = _pipeline(contacts_timeout_s=0.5)
    pl.on_contacts(contacts_msg(T0))
    rep = pl.on_joint_state(joints_msg(evaluator, T0 + 6 * 10**8)).report
    assert rep.status == S.STATUS_STALE_INPUT
    assert 'contacts is stale: its stamp is 0.600 s older' in rep.status_message
    assert 'contacts_timeout_s 0.5' in rep.status_message


def test_contact_source_all_needs_no_contacts_topic(evaluator):
    pl = _pipeline(contact_source='all', fws_rate_hz=0.0)
    pl.on_contacts(contacts_msg(T0, stance=[]))            # ignored
    rep = pl.on_joint_state(joints_msg(evaluator, T0)).report
    assert rep.status == S.STATUS_OK, rep.status_message
    assert list(rep.stance_feet) == FEET
    ref = evaluator.evaluate(evaluator.standing_state())
    assert rep.fwp_margin == pytest.approx(ref.fwp.margin, abs=1e-9)


def test_contact_source_effort_takes_the_stance_from_the_efforts(evaluator):
    joints = dict(zip(evaluator.model.joint_names, evaluator.model.standing_q.tolist()))
    forces = {'lf_foot': [0.0, 0.0, 280.0], 'rf_foot': [5.0, 0.0, 290.0],
              'lh_foot': [0.0, 0.0, 3.0], 'rh_foot': [0.0, -5.0, 270.0]}
    tau = efforts_for(evaluator, joints, forces)
    pl = _pipeline(contact_source='effort', fws_rate_hz=0.0)
    msg = joints_msg(evaluator, T0)
    msg.effort = [tau[n] for n in msg.name]
    rep = pl.on_joint_state(msg).report
    assert rep.status == S.STATUS_OK, rep.status_message
    stance = ['lf_foot', 'rf_foot', 'rh_foot']
    assert list(rep.stance_feet) == stance
    ref = evaluator.evaluate(RobotState(joint_positions=joints, stance=stance,
                                        joint_efforts=tau))
    for name in ('awp', 'fwp', 'fws'):
        assert getattr(rep, f'{name}_margin') == pytest.approx(getattr(ref, name).margin,
                                                               abs=1e-9)
    np.testing.assert_allclose(pl.normal_forces, [280.0, 290.0, 3.0, 270.0], atol=1e-4)
    msg.effort = []
    rep = pl.on_joint_state(stamp(msg, T0 + 10**6)).report
    assert rep.status == S.STATUS_INVALID_INPUT and 'carry no efforts' in rep.status_message


def test_joint_states_from_two_publishers_are_merged_without_warnings(evaluator):
    pl = _pipeline(fws_rate_hz=0.0)
    pl.on_contacts(contacts_msg(T0))
    names = list(evaluator.model.joint_names)
    q = evaluator.model.standing_q + 0.02
    front = [i for i, n in enumerate(names) if n.startswith(('lf', 'rf'))]
    hind = [i for i, n in enumerate(names) if n.startswith(('lh', 'rh'))]

    def part(idx, ns, extra=()):
        return stamp(JointState(name=[names[i] for i in idx] + list(extra),
                                position=[float(q[i]) for i in idx] + [0.5] * len(extra)), ns)

    first = pl.on_joint_state(part(front, T0 + 10**6)).report
    assert first.status == S.STATUS_STALE_INPUT and 'lh_haa_joint' in first.status_message
    reports = []
    for k in range(1, 6):                   # hind stamped slightly before front: out of order
        reports.append(pl.on_joint_state(part(hind, T0 + k * 10**6 + 10**6 - 2000,
                                              extra=['arm_joint', 'wheel'])).report)
        reports.append(pl.on_joint_state(part(front, T0 + (k + 1) * 10**6 - 1000)).report)
    ref = evaluator.evaluate(RobotState(joint_positions=dict(zip(names, q.tolist()))))
    for rep in reports:
        assert rep.status == S.STATUS_OK, rep.status_message      # no 'went back', no note
        assert rep.fwp_margin == pytest.approx(ref.fwp.margin, abs=1e-9)
    assert pl.extra_joints == {'arm_joint', 'wheel'}
    quiet = Pipeline('hyq', PipelineParams(ignored_joints=('arm_joint', 'wheel')))
    quiet.on_contacts(contacts_msg(T0))
    quiet.on_joint_state(part(range(len(names)), T0, extra=['arm_joint', 'wheel']))
    assert quiet.extra_joints == set()


def test_keep_references_sets_how_many_evaluated_states_answer_wrench_references():
    pl = Pipeline('hyq', PipelineParams(fws_rate_hz=1.0))
    assert pl._evaluated.maxlen == REFERENCE_HISTORY          # the library default: all
    for i in range(3):
        pl.on_contacts(contacts_msg(T0 + i * 10**7, FEET))
        pl.on_joint_state(joints_msg(pl.evaluator, T0 + i * 10**7))
    pl.keep_references(1)                                     # the newest is kept
    assert [stamp_to_ns(e[0]) for e in pl._evaluated] == [T0 + 2 * 10**7]
    pl.keep_references(REFERENCE_HISTORY)
    pl.on_joint_state(joints_msg(pl.evaluator, T0 + 3 * 10**7))
    assert [stamp_to_ns(e[0]) for e in pl._evaluated] == [T0 + 2 * 10**7, T0 + 3 * 10**7]
