"""Offline replay (awp_replay -o), live playback (awp_replay --play), and bad bags."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
import subprocess
import sys
from types import SimpleNamespace

import pytest

from awp_ros.bags.message_types import typestore
from awp_ros.bags.progress import Progress
from awp_ros.bags.reader import BagMessage, TopicInfo
from awp_ros.bags.replay import pipeline_cycles, replay_bag
from awp_ros.bags.summary import summarize_reports
from awp_ros.bags.writer import BagWriter
from awp_ros.cli.replay import main as replay_main, parse_override
from awp_ros.gait.bag import write_gait_bag
from awp_ros.gait.generator import generate_gait
from awp_ros.gait.params import GaitParams
from awp_ros.node.launcher import stop_node
from awp_ros.robot.config import load_config, load_parameters
from awp_ros.ros.pipeline import Pipeline
from cases import REPORT_RECORDER

BIN = Path(sys.executable).parent
REPORT = '/awp_node/report'


@pytest.fixture(scope='module')
def gait_bag(tmp_path_factory):
    """Return a 1.6 s bag: stand, two trot cycles (2-leg phases, roll in the imu), stand."""
    gait = generate_gait(load_config('hyq'), GaitParams(
        sequence=('trot',), trot_cycles=2, stand_s=0.2, trot_ramp_s=0.3))
    path = tmp_path_factory.mktemp('bags') / 'trot.mcap'
    write_gait_bag(gait, path, imu_rate_hz=100.0)
    return path


@pytest.fixture(scope='module')
def replayed(gait_bag, tmp_path_factory):
    out = tmp_path_factory.mktemp('out') / 'replayed.mcap'
    # Quasi-static: awp_eval below rebuilds each state from the bag's messages alone.
    params, base_dir = load_parameters('hyq', {'use_imu': True, 'motion': 'quasi_static',
                                               'hull_tolerance': 0.0})
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    summary = replay_bag(gait_bag, out, pipeline=pipeline, progress=False)
    return out, summary


@pytest.fixture(scope='module')
def replayed_measured(gait_bag, tmp_path_factory):
    """Replay with the defaults and use_imu: the measured motion (IMU, joint accelerations)."""
    out = tmp_path_factory.mktemp('out') / 'measured.mcap'
    params, base_dir = load_parameters('hyq', {'use_imu': True})
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    summary = replay_bag(gait_bag, out, pipeline=pipeline, progress=False)
    return out, summary


def _read(path, topics=None):
    """Return topic -> [(log time, message)], read with rosbags' own reader and deserialiser."""
    from rosbags.highlevel import AnyReader

    out: dict = {}
    with AnyReader([Path(path)], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        for conn, t, raw in reader.messages(connections=conns):
            out.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    return out


def _ns(stamp) -> int:
    return stamp.sec * 10**9 + stamp.nanosec


def test_one_report_per_joint_state_stamped_and_logged_like_it(replayed, gait_bag):
    out, summary = replayed
    msgs = _read(out)
    joints = msgs['/joint_states']
    reports = msgs[REPORT]
    assert len(reports) == len(joints) == summary.reports == 801
    for (tj, js), (tr, rep) in zip(joints, reports):
        assert tr == tj and _ns(rep.header.stamp) == _ns(js.header.stamp)
        assert rep.header.frame_id == 'com_world_aligned'
    assert summary.valid == 801 and summary.invalid == 0
    assert set(msgs) >= {'/contacts', '/imu', '/awp_node/awp', '/awp_node/fwp',
                         '/awp_node/fws', '/awp_node/leg_polytopes', '/awp_node/markers'}
    assert len(msgs['/awp_node/awp']) == 801
    assert 0 < len(msgs['/awp_node/markers']) < 801           # throttled to 30 Hz


def test_pipeline_cycles_give_the_replayed_reports(replayed_measured, gait_bag):
    """``pipeline_cycles`` feeds the inputs as ``replay_bag`` does: the same reports, in order."""
    out, _ = replayed_measured
    params, base_dir = load_parameters('hyq', {'use_imu': True})
    cycles = pipeline_cycles(Pipeline.from_parameters(params, base_dir=base_dir), gait_bag)
    reports = [c.report for c in cycles]
    replayed = [rep for _, rep in _read(out, [REPORT])[REPORT]]
    assert len(reports) == len(replayed) == 801
    for mine, theirs in zip(reports, replayed):
        assert _ns(mine.header.stamp) == _ns(theirs.header.stamp)
        assert list(mine.stance_feet) == list(theirs.stance_feet)
        assert (mine.feasible, mine.fwp_margin) == (theirs.feasible, theirs.fwp_margin)
        assert mine.fws_margin == theirs.fws_margin or \
            math.isnan(mine.fws_margin) and math.isnan(theirs.fws_margin)


def test_replayed_margins_equal_awp_eval_on_sampled_states(replayed, gait_bag, capsys):
    """Rebuild the state of sampled cycles from the input bag and run awp_eval on it."""
    from awp_ros.cli.eval import main as eval_main

    out, _ = replayed
    msgs = _read(out)
    reports = {_ns(r.header.stamp): r for _, r in msgs[REPORT]}
    events = sorted([(t, 'c', m) for t, m in msgs['/contacts']]
                    + [(t, 'i', m) for t, m in msgs['/imu']]
                    + [(t, 'j', m) for t, m in msgs['/joint_states']], key=lambda e: e[0])
    contacts = imu = None
    states = []
    for _, kind, m in events:
        if kind == 'c':
            contacts = m
        elif kind == 'i':
            imu = m
        else:
            states.append((m, contacts, imu))
    stance_sizes = set()
    checked_fws = 0
    for js, cs, im in states[::53]:
        rep = reports[_ns(js.header.stamp)]
        doc = {'robot': 'hyq',
               'joint_positions': dict(zip(js.name, js.position.tolist())),
               'joint_velocities': dict(zip(js.name, js.velocity.tolist())),
               'base_orientation': [im.orientation.x, im.orientation.y, im.orientation.z,
                                    im.orientation.w],
               'stance': [n for n, c in zip(cs.names, cs.in_contact) if c]}
        path = out.parent / 'state.json'
        path.write_text(json.dumps(doc))
        assert eval_main([str(path), '--no-halfspaces']) == 0
        ref = json.loads(capsys.readouterr().out)
        stance_sizes.add(len(doc['stance']))
        assert list(rep.stance_feet) == doc['stance']
        for name in ('awp', 'fwp'):
            assert getattr(rep, f'{name}_margin') == pytest.approx(ref[name]['margin'],
                                                                   rel=1e-9, abs=1e-9)
            assert getattr(rep, f'{name}_dimension') == ref[name]['dimension']
            assert getattr(rep, f'{name}_affine_residual') == pytest.approx(
                ref[name]['affine_residual'], rel=1e-9, abs=1e-9)
            assert getattr(rep, f'{name}_feasible') == ref[name]['feasible']
        if rep.fws_stamp == rep.header.stamp:
            assert rep.fws_margin == pytest.approx(ref['fws']['margin'], rel=1e-9, abs=1e-9)
            checked_fws += 1
    assert stance_sizes == {2, 4}
    assert checked_fws >= 1


def test_summary_counts_and_margin_statistics(replayed):
    _, s = replayed
    two_leg = s.fwp_infeasible
    assert s.reports == s.valid + s.invalid
    assert 0 < two_leg < s.reports          # the trot's 2-leg phases are off the FWP hull
    st = s.margins['fwp_margin']
    assert st['min'] <= st['p5'] <= st['median'] <= st['max'] and st['n'] == s.valid
    text = s.to_text()
    assert 'valid: 801' in text and 'fwp_margin' in text and 'joint states/s' in text
    assert s.inputs == {'joint_states': 801, 'contacts': 801, 'imu': 161}


def test_summarize_counts_invalid_and_infeasible_reports():
    def rep(status, feasible, fwp, margin, fws_now):
        stamp = SimpleNamespace(sec=1, nanosec=2)
        return SimpleNamespace(status=status, feasible=feasible, fwp_feasible=fwp,
                               awp_margin=margin, fwp_margin=margin,
                               fws_margin=margin if fws_now else math.nan,
                               header=SimpleNamespace(stamp=stamp),
                               fws_stamp=stamp if fws_now else SimpleNamespace(sec=0,
                                                                               nanosec=0))
    s = summarize_reports([rep(0, True, True, 10.0, True), rep(1, False, True, -2.0, False),
                           rep(2, False, False, math.nan, False), rep(3, False, False, 0, 0)])
    assert (s.reports, s.valid, s.invalid, s.infeasible, s.fwp_infeasible) == (4, 2, 2, 1, 0)
    assert s.statuses == {'ok': 1, 'warning': 1, 'invalid_input': 1, 'stale_input': 1}
    assert s.margins['fwp_margin']['min'] == -2.0 and s.margins['fwp_margin']['max'] == 10.0
    assert s.margins['fws_margin']['n'] == 1


def test_progress_bar_shows_rate_and_eta():
    stream = io.StringIO()
    bar = Progress(200, label='replay', stream=stream, interval_s=0.0, log_interval_s=0.0)
    bar.start -= 2.0                      # as if 2 s had passed
    bar.update(100)
    line = stream.getvalue().splitlines()[-1]
    assert '50.0%' in line and '100/200' in line and 'msgs/s' in line and 'ETA 00:02' in line


def test_cli_replays_with_remapped_topics_and_prints_the_summary(tmp_path, capsys):
    gait = generate_gait(load_config('hyq'), GaitParams(sequence=('stand',), stand_s=0.1))
    src = write_gait_bag(gait, tmp_path / 'in', storage='sqlite3', imu_rate_hz=0,
                         topics={'joint_states': '/robot/js', 'contacts': '/robot/feet'})
    out = tmp_path / 'out.db3'
    code = replay_main([str(src), '-o', str(out), '--joint-states', '/robot/js',
                        '--contacts', '/robot/feet', '--node-name', 'monitor',
                        '--outputs', 'report', '-q'])
    assert code == 0
    assert 'reports: 101' in capsys.readouterr().out      # two stands of 0.1 s at 500 Hz
    msgs = _read(out)
    assert len(msgs['/monitor/report']) == 101 and '/monitor/awp' not in msgs
    assert '/robot/js' in msgs


def test_parse_override_reads_values_as_yaml():
    assert parse_override('use_imu=true') == ('use_imu', True)
    assert parse_override('fws_rate_hz:=20') == ('fws_rate_hz', 20)
    assert parse_override('contact_normal=[0, 0, 1]') == ('contact_normal', [0, 0, 1])


# -- bad bags ---------------------------------------------------------------------------------


def _foreign_bag(path: Path, topic: str) -> Path:
    """Write a bag whose ``topic`` carries ``my_pkg/msg/Thing`` (defined in the bag only)."""
    info = TopicInfo('my_pkg/msg/Thing', 0, 'int32 a\n', 'RIHS01_' + '1' * 64)
    with BagWriter(path, definitions={topic: info}) as writer:
        writer.write(BagMessage(topic, 'my_pkg/msg/Thing', 1, b'\x00\x01\x00\x00\x07\x00\x00\x00'))
    return path


def test_bad_bags_fail_with_a_clear_message_and_exit_code_2(gait_bag, tmp_path, capsys):
    cases = []
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(gait_bag.read_bytes()[:50_000])
    cases.append(([str(cut)], 'truncated or corrupt'))
    cases.append(([str(tmp_path / 'missing.mcap')], 'does not exist'))
    cases.append(([str(gait_bag), '--contacts', '/feet'],
                  "no contacts topic '/feet'; its topics are"))
    cases.append(([str(_foreign_bag(tmp_path / 'thing.mcap', '/joint_states'))],
                  "unknown message type: the joint_states topic '/joint_states' has type "
                  "'my_pkg/msg/Thing'"))
    for i, (args, message) in enumerate(cases):
        assert replay_main(args + ['-o', str(tmp_path / f'o{i}.mcap'), '-q']) == 2, message
        err = capsys.readouterr().err
        assert err.startswith('awp_replay: error: ') and message in err, err
    assert not any(tmp_path.glob('o*.mcap'))


def test_play_refuses_unknown_message_types(tmp_path, ros_env):
    bag = _foreign_bag(tmp_path / 'thing.mcap', '/thing')
    proc = subprocess.run([str(BIN / 'awp_replay'), '--play', str(bag)], env=ros_env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert "unknown message type 'my_pkg/msg/Thing'" in proc.stderr


# -- live ---------------------------------------------------------------------------------------


def test_play_into_a_running_node_gives_the_offline_reports(replayed_measured, gait_bag,
                                                            tmp_path, ros_env, repo):
    """awp_node (console script) + awp_replay --play + a recorder: three processes."""
    out, summary = replayed_measured
    offline = {_ns(r.header.stamp): r for _, r in _read(out, [REPORT])[REPORT]}
    node = subprocess.Popen([str(BIN / 'awp_node'), '--ros-args', '--params-file',
                             str(repo / 'config' / 'hyq.yaml'), '-p', 'use_imu:=true'],
                            env=ros_env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    recorder = subprocess.Popen([sys.executable, '-c', REPORT_RECORDER, str(len(offline)), '90'],
                                env=ros_env, stdout=subprocess.PIPE, text=True)
    try:
        assert recorder.stdout.readline().strip() == 'ready'
        play = subprocess.run([str(BIN / 'awp_replay'), '--play', str(gait_bag),
                               '--rate', '0.5', '--wait', '30', '-q'], env=ros_env,
                              capture_output=True, text=True, timeout=120)
        assert play.returncode == 0, play.stderr
        assert 'published 1763 messages' in play.stderr
        lines, _ = recorder.communicate(timeout=120)
    finally:
        stop_node(recorder)
        stop_node(node)
    live = [json.loads(line) for line in lines.splitlines() if line.startswith('{')]
    assert len(live) == len(offline)
    for r in live:
        ref = offline[r['stamp']]
        assert r['status'] == ref.status
        assert r['stance'] == list(ref.stance_feet), r['stamp']
        assert r['awp'] == pytest.approx(ref.awp_margin, rel=1e-9)
        assert r['fwp'] == pytest.approx(ref.fwp_margin, rel=1e-9)
        assert r['fwp_res'] == pytest.approx(ref.fwp_affine_residual, rel=1e-9, abs=1e-9)


def test_every_report_outside_the_fws_carries_this_cycles_margin_on_the_default_bag():
    """
    The default bag with its IMU (the lurch's wrenches leave the FWS), the FWS at 10 Hz.

    Every report of three or more stance legs whose wrench is outside the FWS carries the
    FWS's margin and witness of its own joint state (``fws_stamp`` its stamp), equal to a full
    recomputation of that joint state's FWS (its H-rep's least-distance program); the others
    carry the latest FWS's.
    """
    from awp_ros.evaluation.evaluator import compute_fws
    from awp_ros.gait.bag import default_bag_path
    params, base_dir = load_parameters('hyq', {'use_imu': True})
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    outside = inside = 0
    for cycle in pipeline_cycles(pipeline, default_bag_path()):
        rep, r = cycle.report, cycle.result
        if len(rep.stance_feet) < 3 or cycle.fws_computed:
            continue
        if r.fws_feasible_per_cycle:                   # the feasible region: inside
            inside += 1
            assert r.fws_margin_per_cycle is None
            continue
        outside += 1
        assert _ns(rep.fws_stamp) == _ns(rep.header.stamp)
        S, full, _, _, _ = compute_fws(*pipeline.evaluator.fws_job(r))
        assert full.margin < 0.0 and not rep.fws_feasible
        assert rep.fws_margin == pytest.approx(full.margin, abs=1e-7 * (1.0 - full.margin))
        assert rep.fws_margin_in_hull == rep.fws_margin and rep.fws_dimension == 6
        assert list(rep.fws_normal) == pytest.approx(list(full.normal), abs=1e-6)
    assert outside >= 50 and inside >= 3000, (outside, inside)
