"""
A stand-alone ROS 2 peer for the two-process message tests: `pub` or `sub`.

pub: publishes one ContactState and one FeasibilityReport every 50 ms until killed.
sub: waits for one of each, prints them as a JSON line, exits 0 (exit 1 after --timeout s).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport
from geometry_msgs.msg import Vector3
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy


def contact_state() -> ContactState:
    msg = ContactState()
    msg.header.frame_id = 'world'
    msg.header.stamp.sec = 12
    msg.header.stamp.nanosec = 345
    msg.names = ['lf_foot', 'rf_foot', 'lh_foot', 'rh_foot']
    msg.in_contact = [True, False, True, True]
    msg.normals = [Vector3(x=0.0, y=0.0, z=1.0)] * 4
    msg.friction_coefficients = [0.7, 0.7, 0.5, 0.6]
    return msg


def report() -> FeasibilityReport:
    msg = FeasibilityReport()
    msg.header.frame_id = 'com_world_aligned'
    msg.header.stamp.sec = 12
    msg.status = FeasibilityReport.STATUS_WARNING
    msg.status_message = 'singular leg lf_foot'
    msg.stance_feet = ['lf_foot', 'lh_foot', 'rh_foot']
    msg.wrench.force.z = 851.3
    msg.fwp_margin = 42.5
    msg.fws_normal = [0.0, 0.0, -1.0, 0.0, 0.0, 0.0]
    msg.feasible = True
    return msg


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument('mode', choices=['pub', 'sub'])
    parser.add_argument('--timeout', type=float, default=30.0)
    args = parser.parse_args()
    rclpy.init()
    node = rclpy.create_node(f'awp_test_{args.mode}')
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    if args.mode == 'pub':
        pubs = [(node.create_publisher(ContactState, 'awp_test/contacts', qos), contact_state()),
                (node.create_publisher(FeasibilityReport, 'awp_test/report', qos), report())]
        node.create_timer(0.05, lambda: [p.publish(m) for p, m in pubs])
        try:
            rclpy.spin(node)
        except KeyboardInterrupt:
            pass
        return 0
    got = {}
    node.create_subscription(ContactState, 'awp_test/contacts',
                             lambda m: got.setdefault('contacts', m), qos)
    node.create_subscription(FeasibilityReport, 'awp_test/report',
                             lambda m: got.setdefault('report', m), qos)
    deadline = time.monotonic() + args.timeout
    while len(got) < 2 and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    if len(got) < 2:
        print(f'timed out; got {sorted(got)}', file=sys.stderr)
        return 1
    c, r = got['contacts'], got['report']
    print(json.dumps({
        'names': list(c.names), 'in_contact': list(c.in_contact),
        'normal_z': [n.z for n in c.normals], 'mu': list(c.friction_coefficients),
        'stamp': [c.header.stamp.sec, c.header.stamp.nanosec],
        'status': r.status, 'status_message': r.status_message, 'stance': list(r.stance_feet),
        'force_z': r.wrench.force.z, 'fwp_margin': r.fwp_margin,
        'fws_normal': list(r.fws_normal), 'feasible': r.feasible,
    }))
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
