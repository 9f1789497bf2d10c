"""
Faults around a running awp_node: inputs that come late, stop, restart; two robots.

Every node runs as its own process (the ``awp_node`` console script); joint states and
contacts come from driver processes (``python -m awp_ros.soak --drive``: gait postures at a
fixed rate, stamps saved to a file) or from the test process; reports are matched to the
sent stamps, so "every joint state gets exactly one report" is checked, not assumed.
"""

from __future__ import annotations

import json
import subprocess
import time

from awp_ros_msgs.msg import FeasibilityReport
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
import numpy as np
import pytest
from sensor_msgs.msg import JointState

from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.node.launcher import start_node, stop_node
from awp_ros.soak.driver import driver_command
from awp_ros.soak.probe import Probe, wait_until

S = FeasibilityReport


def _ns(stamp) -> int:
    return stamp.sec * 10**9 + stamp.nanosec


def _values(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


@pytest.fixture
def nodes(ros_env):
    """Start awp_node processes; stop them at the end and check they never crashed."""
    started = []

    def start(robot: str, namespace: str = '', **params):
        proc = start_node(env=ros_env, robot=robot, namespace=namespace,
                          params={'diagnostics_period_s': 0.25, **params})
        started.append(proc)
        return proc

    yield start
    for proc in started:
        assert proc.poll() is None, 'awp_node exited: ' + stop_node(proc)
        log = stop_node(proc)
        assert 'Traceback' not in log, log


@pytest.fixture
def probe(ros_env):
    p = Probe(int(ros_env['ROS_DOMAIN_ID']), 'awp_faults_peer')
    yield p
    p.close()


def _drive(ros_env, tmp_path, name: str, *, rate: float, duration: float,
           robot: str = 'hyq', namespace: str = '', topics: str = 'both'):
    """Start a driver process; return (process, path of its stamps file)."""
    stamps = tmp_path / f'{name}.npy'
    cmd = driver_command(rate, duration, robot=robot, namespace=namespace,
                         stamps_out=str(stamps), topics=topics, depth=10000)
    proc = subprocess.Popen(cmd, env=ros_env, stdout=subprocess.PIPE, text=True)
    return proc, stamps


def _finish(proc, stamps_path, timeout: float = 90.0) -> np.ndarray:
    out, _ = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, out
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary['all_acked']
    return np.load(stamps_path)


def _reports_for(probe: Probe, reports: list, stamps: np.ndarray, timeout: float = 30.0
                 ) -> list:
    """Wait until every stamp has a report; return the reports of those stamps, in order."""
    wanted = set(stamps.tolist())

    def done() -> bool:
        with probe.lock:
            return wanted <= {_ns(r.header.stamp) for r in reports}
    wait_until(done, timeout, f'{len(wanted)} reports')
    time.sleep(0.3)                                # a duplicate would arrive by now
    with probe.lock:
        got = [r for r in reports if _ns(r.header.stamp) in wanted]
    assert len(got) == len(wanted), 'a joint state got more than one report'
    return got


def _inputs_status(probe: Probe, diag: list, start: int, predicate, what: str,
                   name: str = 'awp_node: inputs') -> DiagnosticStatus:
    hit = []

    def found() -> bool:
        with probe.lock:
            arrays = diag[start:]
        hit[:] = [st for arr in arrays for st in arr.status
                  if st.name == name and predicate(st)]
        return bool(hit)
    wait_until(found, 15.0, what)
    return hit[0]


def test_node_started_before_its_inputs_waits_then_answers_each(nodes, probe, ros_env,
                                                                tmp_path):
    proc = nodes('hyq')
    reports = probe.subscribe(FeasibilityReport, 'awp_node/report', depth=10000)
    diag = probe.subscribe(DiagnosticArray, '/diagnostics', depth=1000)
    wait_until(lambda: probe.node.count_publishers('awp_node/report'), 60, 'awp_node')
    # No publisher of joint states or contacts exists: the node waits and says so.
    st = _inputs_status(probe, diag, 0, lambda st: st.level == DiagnosticStatus.ERROR,
                        'ERROR before any input')
    assert st.message.startswith('no joint_states received yet: /joint_states has no '
                                 'publisher'), st.message
    assert probe.node.count_publishers('joint_states') == 0
    time.sleep(1.0)
    assert proc.poll() is None and not reports
    # The inputs appear (a new process) and every joint state is answered.
    driver, path = _drive(ros_env, tmp_path, 'late', rate=200, duration=1.5)
    stamps = _finish(driver, path)
    got = _reports_for(probe, reports, stamps)
    assert [_ns(r.header.stamp) for r in got] == stamps.tolist()
    assert {r.status for r in got} <= {S.STATUS_OK, S.STATUS_WARNING}
    start = len(diag)
    _inputs_status(probe, diag, start, lambda st: st.level != DiagnosticStatus.ERROR
                   and int(_values(st)['joint_states received (total)']) == len(stamps),
                   'the inputs counted')


def test_joint_state_publisher_stops_and_restarts(nodes, probe, ros_env, tmp_path):
    nodes('hyq')
    reports = probe.subscribe(FeasibilityReport, 'awp_node/report', depth=10000)
    diag = probe.subscribe(DiagnosticArray, '/diagnostics', depth=1000)
    wait_until(lambda: probe.node.count_publishers('awp_node/report'), 60, 'awp_node')
    first, path1 = _drive(ros_env, tmp_path, 'first', rate=200, duration=1.5)
    stamps1 = _finish(first, path1)
    got1 = _reports_for(probe, reports, stamps1)
    # The publisher is gone: diagnostics call the joint states stale (contacts hold until
    # the next one: contacts_timeout_s 0), the node keeps running.
    start = len(diag)
    st = _inputs_status(probe, diag, start, lambda st: st.level == DiagnosticStatus.WARN
                        and 'stale: joint_states' in st.message, 'stale inputs')
    assert float(_values(st)['joint_states age [s]']) > 0.5
    # A new publisher process (a restarted driver: new writer, sequence numbers from 1).
    second, path2 = _drive(ros_env, tmp_path, 'second', rate=200, duration=1.5)
    stamps2 = _finish(second, path2)
    got2 = _reports_for(probe, reports, stamps2)
    for got, stamps in ((got1, stamps1), (got2, stamps2)):
        assert [_ns(r.header.stamp) for r in got] == stamps.tolist()
        assert {r.status for r in got} <= {S.STATUS_OK, S.STATUS_WARNING}
        assert not any('never arrived' in r.status_message for r in got)
    start = len(diag)
    st = _inputs_status(probe, diag, start, lambda st: st.level == DiagnosticStatus.WARN
                        and 'stale' in st.message, 'stale again after the second driver')
    assert _values(st)['joint_states sequence gaps (total)'] == '0'


def test_contact_publisher_killed_and_restarted(nodes, probe, ros_env, tmp_path):
    nodes('hyq', contacts_timeout_s=0.5)       # periodic contacts: stale after 0.5 s
    reports = probe.subscribe(FeasibilityReport, 'awp_node/report', depth=10000)
    js_pub = probe.publisher(JointState, 'joint_states', depth=10000)
    wait_until(lambda: probe.node.count_publishers('awp_node/report')
               and js_pub.get_subscription_count(), 60, 'awp_node')
    ref = FeasibilityEvaluator('hyq')
    names, q0 = list(ref.model.joint_names), ref.model.standing_q.tolist()
    stamps: list[int] = []

    def send_for(seconds: float) -> list[int]:
        out = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = JointState(name=names, position=q0)
            ns = time.time_ns()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
            js_pub.publish(msg)
            out.append(ns)
            time.sleep(0.01)                     # 100 Hz
        stamps.extend(out)
        return out

    def send_until_evaluated(timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        while True:
            batch = set(send_for(0.2))
            time.sleep(0.1)
            with probe.lock:
                if any(r.status == S.STATUS_OK and _ns(r.header.stamp) in batch
                       for r in reports):
                    return
            assert time.monotonic() < deadline, 'no evaluation with the contacts'

    contacts, _ = _drive(ros_env, tmp_path, 'c1', rate=100, duration=60, topics='contacts')
    send_until_evaluated()
    phase1 = send_for(1.0)
    contacts.kill()                              # abrupt: no goodbye on DDS
    contacts.wait()
    time.sleep(0.6)                              # > stale_timeout_s
    phase2 = send_for(1.0)
    contacts, _ = _drive(ros_env, tmp_path, 'c2', rate=100, duration=60, topics='contacts')
    send_until_evaluated()
    phase3 = send_for(1.0)
    contacts.kill()
    contacts.wait()
    got = _reports_for(probe, reports, np.array(stamps))
    by_stamp = {_ns(r.header.stamp): r for r in got}
    assert [_ns(r.header.stamp) for r in got] == stamps          # one each, in order
    assert all(by_stamp[ns].status in (S.STATUS_OK, S.STATUS_WARNING) for ns in phase1)
    stale = [by_stamp[ns] for ns in phase2]
    assert all(r.status == S.STATUS_STALE_INPUT and 'contacts is stale' in r.status_message
               for r in stale), {r.status_message for r in stale}
    assert all(by_stamp[ns].status in (S.STATUS_OK, S.STATUS_WARNING) for ns in phase3)


def test_two_robots_side_by_side_without_cross_talk(nodes, probe, ros_env, tmp_path):
    nodes('hyq', '/hyq')
    nodes('go2', '/go2')
    feet = {'hyq': set(FeasibilityEvaluator('hyq').feet),
            'go2': set(FeasibilityEvaluator('go2').feet)}
    assert not feet['hyq'] & feet['go2']
    reports = {r: probe.subscribe(FeasibilityReport, f'/{r}/awp_node/report', depth=10000)
               for r in feet}
    diag = probe.subscribe(DiagnosticArray, '/diagnostics', depth=1000)
    wait_until(lambda: all(probe.node.count_publishers(f'/{r}/awp_node/report')
                           for r in feet), 60, 'both nodes')
    drivers = {r: _drive(ros_env, tmp_path, r, rate=150, duration=2.0, robot=r,
                         namespace=f'/{r}') for r in feet}
    stamps = {r: _finish(*drivers[r]) for r in feet}
    for robot, other in (('hyq', 'go2'), ('go2', 'hyq')):
        got = _reports_for(probe, reports[robot], stamps[robot])
        with probe.lock:
            everything = list(reports[robot])
        # Only its own joint states: nothing of the other robot's driver arrived here.
        assert len(everything) == len(stamps[robot])
        assert not set(stamps[other].tolist()) & {_ns(r.header.stamp) for r in everything}
        assert {r.status for r in got} <= {S.STATUS_OK, S.STATUS_WARNING}, \
            {r.status_message for r in got if r.status > S.STATUS_WARNING}
        assert set().union(*(set(r.stance_feet) for r in got)) <= feet[robot]
    # Each node's diagnostics carry its namespace and robot.
    for robot in feet:
        st = _inputs_status(probe, diag, 0, lambda st, r=robot: st.hardware_id == r,
                            f'{robot} diagnostics', name=f'{robot}/awp_node: evaluation')
        assert int(_values(st)['reports ok (total)']) \
            + int(_values(st)['reports warning (total)']) <= len(stamps[robot])


# -- the bookkeeping behind it (no DDS) ----------------------------------------------------


def test_sequence_gaps_count_lost_messages_and_restarts_start_over():
    from awp_ros.node.diagnostics import NodeDiagnostics
    d = NodeDiagnostics('awp_node', 'hyq', ['joint_states', 'contacts'])
    seen = [d.sequence('joint_states', s) for s in (1, 2, 3, 7, 8, 1, 2, 4, None, 5)]
    assert seen == [0, 0, 0, 3, 0, 0, 0, 1, 0, 0]     # 4-6 lost; restart at 1; 3 lost
    d.received('joint_states', 0.9)
    d.received('contacts', 0.9)
    inputs = d.build(None, wall=1.0).status[0]
    assert _values(inputs)['joint_states sequence gaps (total)'] == '4'
    assert inputs.level == DiagnosticStatus.WARN and 'missing from sequence: joint_states (4)' \
        in inputs.message


def test_contacts_pairing_of_a_lagging_node_matches_its_definition():
    # The newest contacts received whose stamp is <= the joint state's, else the earliest
    # kept (the pipeline's buffer bisects; here the definition by brute force).
    from types import SimpleNamespace as NS

    from awp_ros.ros.input_buffer import InputBuffer
    rng = np.random.default_rng(6)
    for trial in range(200):
        buf, kept = InputBuffer(maxlen=10**6), []
        t = 10**9
        for _ in range(int(rng.integers(1, 300))):
            if rng.random() < 0.5:
                ns = int(t + rng.integers(-3, 5) * 10**6 if rng.random() < 0.9
                         else rng.integers(1, 3) * 10**9)
                msg = NS(header=NS(stamp=NS(sec=ns // 10**9, nanosec=ns % 10**9)), ns=ns)
                buf.add(msg)
                kept.append(ns)
            else:
                q = int(t + rng.integers(-5, 5) * 10**6)
                older = [i for i, s in enumerate(kept) if s <= q]
                expect = None if not kept else kept[older[-1]] if older else kept[0]
                if older:
                    del kept[:older[-1]]
                got = buf.pick(q)
                assert (got is None and expect is None) or got.ns == expect, trial
            t += int(rng.integers(0, 3)) * 10**6
