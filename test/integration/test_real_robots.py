"""
Robots the project ships no config for, with the publishers real robots have, over real DDS.

The robot is Unitree's A1 from example-robot-data with a config of the two required keys
only (``urdf``, ``feet``), written here: it must run in ``awp_node``, ``awp_eval``,
``awp_replay`` and ``awp_demo``. Then the conventions of real robots: no contacts topic
(``contact_source: effort``, with joint efforts made by inverse dynamics from known contact
forces), joint states split over two publishers (merged, no false loss warning), contacts
published once, on change, by a transient-local publisher (never stale), and inputs that
never arrive (another type, incompatible QoS, no publisher), which ``/diagnostics`` names
with the topic.
"""

from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
import yaml

from awp_ros.bags.message_types import JOINT_STATE, serialize
from awp_ros.bags.reader import BagMessage, read_bag
from awp_ros.bags.writer import BagWriter
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.node.launcher import start_node, stop_node
from awp_ros.robot.config import load_config
from awp_ros.robot.state import RobotState
from awp_ros.ros.conversions import stamp_to_ns
from cases import DdsPeer, efforts_for, stamp, stop_peers

BIN = Path(sys.executable).parent
S = FeasibilityReport
FEET = ['FL_foot', 'FR_foot', 'RL_foot', 'RR_foot']
# a1.srdf's "standing" state, written here by hand.
STANDING = {f'{leg}_{j}_joint': v for leg in ('FL', 'FR', 'RL', 'RR')
            for j, v in (('hip', 0.0), ('thigh', 0.8), ('calf', -1.81))}
QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                 reliability=ReliabilityPolicy.RELIABLE)
T0 = 1_700_000_000 * 10**9


@pytest.fixture(scope='module')
def a1_yaml(tmp_path_factory) -> Path:
    """Return an A1 config with the required keys only (no robot_name, posture, limits)."""
    path = tmp_path_factory.mktemp('a1') / 'a1.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': {
        'urdf': 'example-robot-data://a1_description/urdf/a1.urdf', 'feet': FEET}}}))
    return path


@pytest.fixture(scope='module')
def a1(a1_yaml) -> FeasibilityEvaluator:
    return FeasibilityEvaluator(load_config(a1_yaml))


class Peer(DdsPeer):
    """The test's DDS participant: publishers on demand, the node's reports and diagnostics."""

    def __init__(self, env: dict) -> None:
        super().__init__(env, 'awp_real_robot_peer')
        self.reports: list = []
        self.diag: list = []
        self.node.create_subscription(FeasibilityReport, 'awp_node/report',
                                      self.keep(self.reports), QOS)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self.keep(self.diag),
                                      QOS)
        self.start()

    def publisher(self, mtype, topic: str, qos: QoSProfile = QOS):
        return self.node.create_publisher(mtype, topic, qos)

    def inputs(self) -> DiagnosticStatusView:
        """Return the node's latest 'inputs' status (message, values) or an empty one."""
        with self.lock:
            arrays = list(self.diag)
        for arr in reversed(arrays):
            for st in arr.status:
                if st.name == 'awp_node: inputs':
                    return DiagnosticStatusView(st.message, {kv.key: kv.value
                                                             for kv in st.values})
        return DiagnosticStatusView('', {})

    def wait(self, predicate, what: str, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return
            time.sleep(0.02)
        raise AssertionError(f'timed out after {timeout} s waiting for {what}; inputs '
                             f'diagnostics: {self.inputs()}')

    def wait_subscribed(self, pub) -> None:
        self.wait(lambda: pub.get_subscription_count() > 0, f'a subscriber on {pub.topic_name}')
        time.sleep(0.3)


class DiagnosticStatusView:
    """The message and values of one DiagnosticStatus."""

    def __init__(self, message: str, values: dict) -> None:
        self.message = message
        self.values = values

    def __repr__(self) -> str:
        return f'{self.message!r} {self.values}'


@pytest.fixture
def a1_node(ros_env, a1_yaml):
    """Start awp_node on the minimal A1 config with extra --ros-args; yield (start, peer)."""
    started = []

    def start(*args: str) -> Peer:
        proc = start_node(env=ros_env, robot=None, params_file=a1_yaml, ros_args=(
            '-p', 'diagnostics_period_s:=0.1', '-p', 'marker_worker:=false') + args)
        peer = Peer(ros_env)
        started.append((proc, peer))
        peer.wait(lambda: peer.node.count_publishers('/awp_node/report') > 0,
                  'awp_node on DDS')
        return peer

    yield start
    stop_peers(started)


def joints(a1, q: dict, ns: int, names=None, efforts: dict | None = None) -> JointState:
    names = list(a1.model.joint_names) if names is None else list(names)
    msg = JointState(name=names, position=[q[n] for n in names])
    if efforts is not None:
        msg.effort = [efforts[n] for n in names]
    return stamp(msg, ns)


def contacts(ns: int, stance) -> ContactState:
    return stamp(ContactState(names=FEET, in_contact=[f in stance for f in FEET]), ns)


def eval_cli(a1_yaml: Path, doc: dict) -> dict:
    res = subprocess.run([str(BIN / 'awp_eval'), '--robot', str(a1_yaml)],
                         input=json.dumps(doc), capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout)


def test_a_minimal_a1_config_runs_in_the_node_and_awp_eval(a1_node, a1_yaml, a1):
    peer = a1_node()
    js = peer.publisher(JointState, 'joint_states')
    cs = peer.publisher(ContactState, 'contacts')
    peer.wait_subscribed(js)
    stance = ['FL_foot', 'FR_foot', 'RR_foot']
    cs.publish(contacts(T0, stance))
    peer.wait(lambda: peer.inputs().values.get('contacts received (total)') == '1',
              'the contacts')
    js.publish(joints(a1, STANDING, T0 + 1000))
    peer.wait(lambda: peer.reports, 'a report')
    rep = peer.reports[0]
    assert rep.status == S.STATUS_OK, rep.status_message
    assert list(rep.stance_feet) == stance
    ref = eval_cli(a1_yaml, {'joint_positions': STANDING, 'stance': stance})
    assert ref['robot'] == 'a1'                       # the default name: the URDF's
    for name in ('awp', 'fwp', 'fws'):
        assert getattr(rep, f'{name}_margin') == pytest.approx(ref[name]['margin'], abs=1e-7)
    assert rep.mass == pytest.approx(ref['mass'], rel=1e-12)


def test_awp_demo_generates_the_a1_gait_and_awp_replay_replays_it(ros_env, a1_yaml, tmp_path):
    out = tmp_path / 'demo'
    res = subprocess.run([str(BIN / 'awp_demo'), '--robot', str(a1_yaml), '-o', str(out),
                          '--duration', '1.0', '--quiet'], env=ros_env, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
    bag = out / 'a1_gait.mcap'                       # generated: HyQ's bag is not A1's
    first = next(iter(read_bag(bag, topics=['/joint_states'])))
    assert set(deserialize_message(first.data, JointState).name) == set(STANDING)
    replayed = tmp_path / 'replay.mcap'
    res = subprocess.run([str(BIN / 'awp_replay'), str(bag), '-o', str(replayed), '--robot',
                          str(a1_yaml), '--outputs', 'report', '--json', '-q',
                          '-p', 'fws_rate_hz=0.0'],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    summary = json.loads(res.stdout)
    n = sum(1 for _ in read_bag(bag, topics=['/joint_states']))
    assert summary['reports'] == n
    assert set(summary['statuses']) <= {'ok', 'warning'}, summary['statuses']
    # A wrong foot name is refused in one line, before anything starts.
    bad = tmp_path / 'bad.yaml'
    bad.write_text(a1_yaml.read_text().replace('FL_foot', 'FL_fot'))
    res = subprocess.run([str(BIN / 'awp_demo'), '--robot', str(bad), '-o', str(out)],
                         env=ros_env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and res.stderr.count('\n') == 1, res.stderr
    assert "foot frame 'FL_fot' not in the URDF" in res.stderr
    # HyQ's bag into the A1 node: refused in one line.
    res = subprocess.run([str(BIN / 'awp_demo'), '--robot', str(a1_yaml), '--bag',
                          str(Path(__file__).resolve().parents[2] / 'config' / 'hyq_gait.mcap'),
                          '-o', str(out)], env=ros_env, capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 2 and 'is not a bag of robot' in res.stderr, res.stderr


def test_a_bag_without_contacts_replays_with_the_stance_from_efforts(a1_yaml, a1, tmp_path):
    forces = {'FL_foot': [0, 0, 40.0], 'FR_foot': [0, 0, 45.0], 'RR_foot': [0, 0, 35.0]}
    tau = efforts_for(a1, STANDING, forces)
    bag = tmp_path / 'no_contacts.mcap'
    with BagWriter(bag) as writer:
        for k in range(5):
            msg = joints(a1, STANDING, T0 + k * 10**6, efforts=tau)
            writer.write(BagMessage('/joint_states', JOINT_STATE, T0 + k * 10**6,
                                    serialize(msg, JOINT_STATE)))
    out = tmp_path / 'out.mcap'
    res = subprocess.run([str(BIN / 'awp_replay'), str(bag), '-o', str(out), '--robot',
                          str(a1_yaml), '-p', 'contact_source=effort', '--contacts', '',
                          '--json', '-q', '--outputs', 'report'],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)['statuses'] == {'ok': 5}


def test_contact_source_effort_gives_the_stance_and_margins_of_the_known_forces(a1_node, a1):
    peer = a1_node('-p', 'contact_source:=effort', '-p', 'fws_rate_hz:=0.0')
    js = peer.publisher(JointState, 'joint_states')
    peer.wait_subscribed(js)
    stance = ['FL_foot', 'FR_foot', 'RR_foot']
    forces = {'FL_foot': [2.0, 0.0, 40.0], 'FR_foot': [0.0, -1.0, 45.0],
              'RL_foot': [0.0, 0.0, 3.0], 'RR_foot': [0.0, 0.0, 35.0]}   # RL: 3 N < 20 N
    tau = efforts_for(a1, STANDING, forces)
    js.publish(joints(a1, STANDING, T0, efforts=tau))
    peer.wait(lambda: peer.reports, 'a report')
    rep = peer.reports[0]
    assert rep.status == S.STATUS_OK, rep.status_message
    assert list(rep.stance_feet) == stance
    ref = a1.evaluate(RobotState(joint_positions=STANDING, stance=stance, joint_efforts=tau))
    for name in ('awp', 'fwp', 'fws'):
        assert getattr(rep, f'{name}_margin') == pytest.approx(getattr(ref, name).margin,
                                                               abs=1e-7)
    assert rep.measured_forces and rep.slip_foot == ref.measured.slip_foot
    # No contacts topic: the node neither subscribes to one nor waits for it.
    assert peer.node.count_subscribers('/contacts') == 0
    peer.wait(lambda: 'contacts received (total)' not in peer.inputs().values
              and peer.inputs().values, 'inputs diagnostics without contacts')


def test_joint_states_from_two_publishers_are_merged_without_loss_warnings(a1_node, a1):
    peer = a1_node('-p', 'contact_source:=all', '-p', 'fws_rate_hz:=0.0')
    legs = peer.publisher(JointState, 'joint_states')
    arm = peer.publisher(JointState, 'joint_states')
    peer.wait_subscribed(legs)
    peer.wait(lambda: peer.inputs().values.get('joint_states publishers (matched)') == '2',
              'two matched publishers')
    names = list(a1.model.joint_names)
    front = [n for n in names if n.startswith('F')]
    hind = [n for n in names if n.startswith('R')]
    q = {n: v + 0.03 for n, v in STANDING.items()}
    sent = 0
    for k in range(40):
        legs.publish(joints(a1, q, T0 + k * 2 * 10**6, names=front))
        extra = {'z1_arm_joint': 0.4}
        arm.publish(stamp(JointState(name=hind + list(extra),
                                     position=[q[n] for n in hind] + list(extra.values())),
                          T0 + k * 2 * 10**6 + 10**6))
        sent += 2
    peer.wait(lambda: len(peer.reports) == sent, f'{sent} reports')
    reports = sorted(peer.reports, key=lambda r: stamp_to_ns(r.header.stamp))
    assert reports[0].status == S.STATUS_STALE_INPUT        # only the front joints yet
    assert 'no message has named joints' in reports[0].status_message
    ref = a1.evaluate(RobotState(joint_positions=q))
    for rep in reports[1:]:
        assert rep.status == S.STATUS_OK, rep.status_message     # no 'never arrived'
        assert rep.fwp_margin == pytest.approx(ref.fwp.margin, abs=1e-7)
    peer.wait(lambda: peer.inputs().values.get('joint_states ignored joints (not in the '
                                               'model)') == 'z1_arm_joint', 'the extra joint')
    # The diagnostics of a period may predate the last messages: wait for the full count.
    peer.wait(lambda: peer.inputs().values.get('joint_states received (total)') == str(sent),
              f'{sent} joint states counted')
    v = peer.inputs().values
    assert v['joint_states sequence gaps (total)'] == '0', v


def test_on_change_contacts_of_a_transient_local_publisher_never_go_stale(ros_env, a1_node,
                                                                          a1):
    # The contacts are published once, before the node exists, and kept by the publisher.
    early = Peer(ros_env)
    latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    cs = early.publisher(ContactState, 'contacts', latched)
    stance = ['FL_foot', 'RL_foot', 'RR_foot']
    cs.publish(contacts(T0, stance))
    try:
        peer = a1_node('-p', 'contacts_durability:=transient_local')
        js = peer.publisher(JointState, 'joint_states')
        peer.wait_subscribed(js)
        peer.wait(lambda: peer.inputs().values.get('contacts received (total)') == '1',
                  'the latched contacts')
        stamps = [T0 + int(s * 1e9) for s in (0.001, 0.6, 2.0, 5.0)]   # beyond 0.5 s
        for ns in stamps:
            js.publish(joints(a1, STANDING, ns))
        peer.wait(lambda: len(peer.reports) == len(stamps), 'the reports')
        for rep in peer.reports:
            assert rep.status == S.STATUS_OK, rep.status_message
            assert list(rep.stance_feet) == stance
        # On change: a new contacts message, then joint states long after it.
        cs.publish(contacts(T0 + 6 * 10**9, FEET))
        peer.wait(lambda: peer.inputs().values.get('contacts received (total)') == '2',
                  'the changed contacts')
        js.publish(joints(a1, STANDING, T0 + 9 * 10**9))
        peer.wait(lambda: len(peer.reports) == len(stamps) + 1, 'the last report')
        assert list(peer.reports[-1].stance_feet) == FEET
        assert peer.reports[-1].status == S.STATUS_OK
        assert 'stale' not in peer.inputs().message
    finally:
        early.close()


def test_another_type_a_qos_mismatch_and_no_publisher_are_named_in_diagnostics(a1_node, a1):
    peer = a1_node('-p', 'use_imu:=true', '-r', 'imu:=/robot/imu')
    best_effort = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                             reliability=ReliabilityPolicy.BEST_EFFORT)
    js = peer.publisher(JointState, 'joint_states', best_effort)
    odom = peer.publisher(Odometry, '/robot/imu')
    for _ in range(5):
        js.publish(joints(a1, STANDING, T0))
        odom.publish(Odometry())
    peer.wait(lambda: 'incompatible QoS' in peer.inputs().message
              and 'another type' in peer.inputs().message, 'the input problems')
    message = peer.inputs().message
    assert message.startswith('no joint_states received yet: /joint_states has 1 publisher '
                              'with incompatible QoS (RELIABILITY'), message
    assert 'set qos_reliability:=best_effort' in message
    assert ('/robot/imu has publishers of another type (1 of type nav_msgs/msg/Odometry); '
            'this node subscribes with sensor_msgs/msg/Imu') in message
    assert '/contacts has no publisher' in message
    assert not peer.reports                      # nothing arrived, nothing was answered


def test_a_typo_in_the_node_config_is_named_until_a_key_is_set(ros_env, a1_yaml, a1,
                                                               tmp_path):
    typo = tmp_path / 'a1_typo.yaml'
    params = yaml.safe_load(a1_yaml.read_text())
    params['/**']['ros__parameters']['friction_coeficient'] = 0.3
    typo.write_text(yaml.safe_dump(params))
    proc = start_node(env=ros_env, robot=None, params_file=typo,
                      ros_args=('-p', 'diagnostics_period_s:=0.1', '-p', 'marker_worker:=false'))
    peer = Peer(ros_env)
    try:
        peer.wait(lambda: peer.node.count_publishers('/awp_node/report') > 0, 'awp_node')
        js = peer.publisher(JointState, 'joint_states')
        cs = peer.publisher(ContactState, 'contacts')
        peer.wait_subscribed(js)
        cs.publish(contacts(T0, FEET))
        js.publish(joints(a1, STANDING, T0 + 1000))
        peer.wait(lambda: peer.reports, 'a report')
        rep = peer.reports[0]
        assert rep.status == S.STATUS_ERROR
        assert ("unknown parameter: 'friction_coeficient' (did you mean "
                "'friction_coefficient'?)") in rep.status_message
        # The intended key, set at runtime (without the ros2 CLI), builds the model.
        res = subprocess.run([str(BIN / 'awp_param'), 'set', '/awp_node',
                              'friction_coefficient', '0.3'], env=ros_env,
                             capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        # The contacts sent before the model existed are used: no new contacts message.
        js.publish(joints(a1, STANDING, T0 + 2000))
        peer.wait(lambda: len(peer.reports) == 2, 'the second report')
        rep = peer.reports[1]
        assert rep.status == S.STATUS_OK, rep.status_message
        state = RobotState(joint_positions=STANDING, friction_coefficient=0.3)
        assert rep.fwp_margin == pytest.approx(a1.evaluate(state).fwp.margin, abs=1e-7)
    finally:
        peer.close()
        log = stop_node(proc)
    assert 'Traceback' not in log, log
