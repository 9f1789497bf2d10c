"""
Measure the CPU of the node's ROS side alone: a relay that answers every joint state, no pipeline.

::

    PYTHONPATH=. .venv/bin/python examples/experiments/ros_glue_floor.py [--rate 1000]

(``--duration``: the drive [s], default 20.) The measurement behind the README's "Real-time
performance" paragraph on the node's CPU. Three
processes on this machine, as in ``python -m awp_ros.soak``: the soak's driver (``python -m
awp_ros.soak --drive``: gait joint states at ``--rate``, no contacts), a relay and a sink. The
relay does per joint state what ``awp_node`` does around its pipeline and nothing else: it
takes the serialized message from its subscription (:class:`awp_ros.node.input_drain.InputDrain`,
the node's loop of takes and waits), reads it (:class:`awp_ros.ros.cdr.JointStateBytes`) and
publishes a fixed serialized ``FeasibilityReport`` (a real one, of a four-leg joint state of the
default bag) on the node's report topic; the sink takes the reports. The relay's CPU [% of one
core] is read from ``/proc/<pid>/stat`` over the middle half of the drive (all its threads: the
Python thread and Fast DDS's). DDS stays on this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=
LOCALHOST``, ``--domain``, default 57). It prints one JSON object: relayed and received counts,
the relay's CPU and per joint state [ms].
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[2]
#: The topics (the soak's driver publishes ``<namespace>/joint_states``).
NAMESPACE = '/glue_floor'


def report_bytes_of_bag() -> bytes:
    """Return the serialized report of the first four-leg joint state of the default bag."""
    from awp_ros_msgs.msg import ContactState
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState

    from awp_ros.bags.reader import read_bag
    from awp_ros.robot.config import load_parameters
    from awp_ros.ros.pipeline import Pipeline
    params, base_dir = load_parameters('hyq')
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    types = {'/joint_states': JointState, '/contacts': ContactState}
    for m in read_bag(str(REPO / 'config' / 'hyq_gait.mcap'), topics=list(types)):
        msg = deserialize_message(m.data, types[m.topic])
        if m.topic == '/contacts':
            pipeline.on_contacts(msg)
            continue
        cycle = pipeline.on_joint_state(msg)
        if cycle.result is not None and len(cycle.result.stance) == 4:
            return bytes(cycle.report_bytes)
    raise RuntimeError('no four-leg joint state in the default bag')


def _qos(depth: int):
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE)


def relay(count: int, report_path: str, depth: int) -> int:
    """Answer ``count`` joint states with the report's bytes (the relay process)."""
    import rclpy
    from awp_ros_msgs.msg import FeasibilityReport
    from sensor_msgs.msg import JointState

    from awp_ros.node.input_drain import InputDrain
    from awp_ros.ros.cdr import JointStateBytes
    report = Path(report_path).read_bytes()
    rclpy.init()
    node = rclpy.create_node('glue_floor_relay')
    pub = node.create_publisher(FeasibilityReport, f'{NAMESPACE}/awp_node/report', _qos(depth))
    done = [0]

    def handle(data: bytes, info: dict) -> None:
        JointStateBytes.parse(data)
        pub.publish(report)
        done[0] += 1
    sub = node.create_subscription(JointState, f'{NAMESPACE}/joint_states', lambda _: None,
                                   _qos(depth), raw=True)
    drain = InputDrain([], (sub, handle), node.context, budget_s=0.02)
    while rclpy.ok() and done[0] < count:
        drain.run()
    print(json.dumps({'relayed': done[0]}), flush=True)
    drain.close()
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def sink(count: int, depth: int, timeout_s: float) -> int:
    """Take ``count`` reports or give up after ``timeout_s`` (the sink process)."""
    import rclpy
    from awp_ros_msgs.msg import FeasibilityReport
    rclpy.init()
    node = rclpy.create_node('glue_floor_sink')
    got = [0]
    node.create_subscription(FeasibilityReport, f'{NAMESPACE}/awp_node/report',
                             lambda _: got.__setitem__(0, got[0] + 1), _qos(depth), raw=True)
    end = time.monotonic() + timeout_s
    while got[0] < count and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.1)
    print(json.dumps({'received': got[0]}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def _cpu_ticks(pid: int) -> int:
    """Return the user + system clock ticks of a process (all its threads)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return int(fields[11]) + int(fields[12])


def measure(rate_hz: float = 1000.0, duration_s: float = 20.0, domain: int = 57) -> dict:
    """Run driver, relay and sink (module docstring); return the counts and the relay's CPU."""
    from awp_ros.node.dds import use_deep_queues
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_DOMAIN_ID=str(domain), OPENBLAS_NUM_THREADS='1',
               PYTHONPATH=os.pathsep.join(filter(None, [str(REPO),
                                                        os.environ.get('PYTHONPATH')])))
    use_deep_queues(env)
    count = int(round(rate_hz * duration_s))
    depth = count + 1000
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp, 'report.bin')
        report.write_bytes(report_bytes_of_bag())
        me = [sys.executable, str(Path(__file__).resolve())]
        run = {'env': env, 'stdout': subprocess.PIPE, 'text': True}
        sink_p = subprocess.Popen(me + ['--sink', str(count), '--depth', str(depth),
                                        '--timeout', str(duration_s + 60.0)], **run)
        relay_p = subprocess.Popen(me + ['--relay', str(count), '--report', str(report),
                                         '--depth', str(depth)], **run)
        time.sleep(2.0)
        driver = subprocess.Popen([sys.executable, '-m', 'awp_ros.soak', '--drive',
                                   '--rate', str(rate_hz), '--duration', str(duration_s),
                                   '--namespace', NAMESPACE, '--topics', 'joint_states',
                                   '--depth', str(depth)], **run)
        try:
            # The drive starts once the driver's publisher matches: wait for the first quarter.
            while relay_p.poll() is None and driver.poll() is None and \
                    _cpu_ticks(relay_p.pid) == 0:
                time.sleep(0.05)
            time.sleep(3.0 + 0.25 * duration_s)
            tick = os.sysconf('SC_CLK_TCK')
            t0, c0 = time.monotonic(), _cpu_ticks(relay_p.pid)
            time.sleep(0.5 * duration_s)
            t1, c1 = time.monotonic(), _cpu_ticks(relay_p.pid)
            outs = [json.loads(p.communicate(timeout=duration_s + 120.0)[0].strip()
                               .splitlines()[-1]) for p in (driver, relay_p, sink_p)]
        finally:
            for p in (driver, relay_p, sink_p):
                if p.poll() is None:
                    p.kill()
    cpu = 100.0 * (c1 - c0) / tick / (t1 - t0)
    return {'rate_hz': rate_hz, 'duration_s': duration_s, 'sent': outs[0]['sent'],
            'relayed': outs[1]['relayed'], 'received': outs[2]['received'],
            'relay_cpu_percent': round(cpu, 1),
            'relay_ms_per_joint_state': round(10.0 * cpu / rate_hz, 4),
            'load_average': os.getloadavg()}


def main(argv: list[str] | None = None) -> int:
    """Run the measurement, or one of its processes (``--relay``, ``--sink``)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate', type=float, default=1000.0, help='joint states [Hz]')
    parser.add_argument('--duration', type=float, default=20.0, help='drive time [s]')
    parser.add_argument('--domain', type=int, default=57, help='ROS_DOMAIN_ID of the run')
    parser.add_argument('--relay', type=int, help=argparse.SUPPRESS)
    parser.add_argument('--sink', type=int, help=argparse.SUPPRESS)
    parser.add_argument('--report', help=argparse.SUPPRESS)
    parser.add_argument('--depth', type=int, default=100000, help=argparse.SUPPRESS)
    parser.add_argument('--timeout', type=float, default=120.0, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.relay is not None:
        return relay(args.relay, args.report, args.depth)
    if args.sink is not None:
        return sink(args.sink, args.depth, args.timeout)
    print(json.dumps(measure(args.rate, args.duration, args.domain)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
