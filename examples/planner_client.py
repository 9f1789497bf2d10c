"""
Check candidate postures of HyQ with awp_node, as a footstep or posture planner would.

The planner listens to the live stream (``/awp_node/report``: the margins of the robot's
current state, one report per joint state) and asks the node about states it is
considering (``/awp_node/evaluate``, awp_ros_msgs/srv/Evaluate): a few postures around
standing with different stance sets, and the same standing posture with a wrench the
planner intends (a push forward and sideways). Margins are signed Euclidean distances in
wrench space [N, N.m] (force, then moment about the CoM, world-aligned axes): >= 0 when the
wrench is in the set, < 0 when it is not.

Run it against a node (two terminals, the repository root, the venv)::

    export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=42
    .venv/bin/awp_node --ros-args --params-file config/hyq.yaml
    # in the second terminal, with the same two variables exported:
    .venv/bin/python examples/planner_client.py

Without a publisher of ``/joint_states`` (and ``/contacts``) it says so and prints no live
margins; with one (a robot, a bag played by ``ros2 bag play``, or the soak's gait publisher in a
third terminal: ``.venv/bin/python -m awp_ros.soak --drive --rate 100 --duration 30
--namespace /``) it prints the latest live report first.
"""

from __future__ import annotations

import sys
import threading
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport
from awp_ros_msgs.srv import Evaluate
from geometry_msgs.msg import Wrench
import rclpy
from sensor_msgs.msg import JointState

from awp_ros.robot.config import load_config

FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')
STATUS = {0: 'ok', 1: 'warning', 2: 'invalid_input', 3: 'stale_input', 4: 'error'}


def candidates(config) -> list[tuple[str, JointState, ContactState]]:
    """Return (label, joint state, contacts) of a few postures around standing."""
    names = sorted(config.standing_posture)
    q0 = [config.standing_posture[n] for n in names]
    out = []
    for label, dq, stance in (('standing, 4 feet', 0.0, FEET),
                              ('crouched (knees +0.2 rad), 4 feet', 0.2, FEET),
                              ('standing, 3 feet (rh_foot lifted)', 0.0, FEET[:3]),
                              ('standing, trot pair lf+rh', 0.0, ('lf_foot', 'rh_foot'))):
        q = [x + (dq if n.endswith('kfe_joint') else 0.0) * (1 if x > 0 else -1)
             for n, x in zip(names, q0)]
        out.append((label, JointState(name=names, position=q),
                    ContactState(names=list(FEET), in_contact=[f in stance for f in FEET])))
    return out


def print_report(label: str, r: FeasibilityReport) -> None:
    """Print the margins of one report."""
    if r.status > FeasibilityReport.STATUS_WARNING:
        print(f'  {label:<36} {STATUS[r.status]}: {r.status_message}')
        return
    print(f'  {label:<36} feasible {str(r.feasible):<5}  margins [N, N.m]: '
          f'fwp {r.fwp_margin:8.2f}  fws {r.fws_margin:8.2f}  (stance {len(r.stance_feet)}, '
          f'FWS dimension {r.fws_dimension})')


def main() -> int:
    """Print the live margins (if any) and those of the candidates."""
    rclpy.init()
    node = rclpy.create_node('planner_example')
    live: list[FeasibilityReport] = []
    got_live = threading.Event()

    def on_report(msg: FeasibilityReport) -> None:
        live[:] = [msg]
        got_live.set()

    node.create_subscription(FeasibilityReport, '/awp_node/report', on_report, 10)
    client = node.create_client(Evaluate, '/awp_node/evaluate')
    try:
        if not client.wait_for_service(timeout_sec=30.0):
            print('no /awp_node/evaluate: is awp_node running on this ROS_DOMAIN_ID?')
            return 1
        deadline = time.monotonic() + 3.0
        while not got_live.is_set() and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        if live:
            print_report('live (latest /awp_node/report)', live[0])
        else:
            print('no live report within 3 s (nothing publishes /joint_states)')
        config = load_config('hyq')
        cands = candidates(config)
        request = Evaluate.Request(joint_states=[js for _, js, _ in cands],
                                   contacts=[c for _, _, c in cands])
        print(f'{len(cands)} candidate postures:')
        response = call(node, client, request)
        for (label, _, _), report in zip(cands, response.reports):
            print_report(label, report)
        # The standing posture with wrenches the planner intends: the weight plus a push.
        standing = cands[0]
        weight = response.reports[0].wrench.force.z        # m g [N]
        pushes = [('weight only', 0.0, 0.0), ('+ 300 N forward', 300.0, 0.0),
                  ('+ 300 N sideways', 0.0, 300.0), ('+ 900 N forward', 900.0, 0.0)]
        wrenches = []
        for _, fx, fy in pushes:
            w = Wrench()
            w.force.x, w.force.y, w.force.z = fx, fy, weight
            wrenches.append(w)
        request = Evaluate.Request(joint_states=[standing[1]] * len(pushes),
                                   contacts=[standing[2]], wrenches=wrenches)
        print(f'standing, 4 feet, with intended wrenches (m g = {weight:.1f} N up):')
        for (label, _, _), report in zip(pushes, call(node, client, request).reports):
            print_report(label, report)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def call(node, client, request: Evaluate.Request) -> Evaluate.Response:
    """Call the service and wait for the response (exit when none comes in 60 s)."""
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=60.0)
    if future.result() is None:
        sys.exit('no answer from /awp_node/evaluate within 60 s')
    return future.result()


if __name__ == '__main__':
    sys.exit(main())
