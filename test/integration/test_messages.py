"""The generated awp_ros_msgs messages, exchanged between two processes over real DDS."""

from __future__ import annotations

import json
import subprocess
import sys

from awp_ros_msgs.msg import FeasibilityReport, Polytope, WrenchPolytope
import numpy as np
from rclpy.serialization import deserialize_message, serialize_message


def test_contact_state_and_report_cross_two_processes(ros_env, repo):
    peer = str(repo / 'test' / 'integration' / 'dds_peer.py')
    pub = subprocess.Popen([sys.executable, peer, 'pub'], env=ros_env,
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        sub = subprocess.run([sys.executable, peer, 'sub', '--timeout', '30'], env=ros_env,
                             capture_output=True, text=True, timeout=60)
    finally:
        pub.terminate()
        pub.wait(timeout=10)
    assert sub.returncode == 0, sub.stderr
    got = json.loads(sub.stdout.strip().splitlines()[-1])
    assert got['names'] == ['lf_foot', 'rf_foot', 'lh_foot', 'rh_foot']
    assert got['in_contact'] == [True, False, True, True]
    assert got['normal_z'] == [1.0] * 4
    assert got['mu'] == [0.7, 0.7, 0.5, 0.6]
    assert got['stamp'] == [12, 345]
    assert got['status'] == FeasibilityReport.STATUS_WARNING
    assert got['status_message'] == 'singular leg lf_foot'
    assert got['stance'] == ['lf_foot', 'lh_foot', 'rh_foot']
    assert got['force_z'] == 851.3 and got['fwp_margin'] == 42.5
    assert got['fws_normal'] == [0.0, 0.0, -1.0, 0.0, 0.0, 0.0]
    assert got['feasible'] is True


def test_polytope_arrays_serialise_losslessly():
    rng = np.random.default_rng(0)
    msg = WrenchPolytope(kind=WrenchPolytope.FWP, stance_feet=['a', 'b', 'c'])
    A, b = rng.normal(size=(40, 6)), rng.normal(size=40)
    msg.polytope = Polytope(ambient_dimension=6, dimension=6, halfspace_normals=A.ravel(),
                            halfspace_offsets=b, hull_origin=np.zeros(6),
                            hull_basis=np.eye(6).ravel())
    back = deserialize_message(serialize_message(msg), WrenchPolytope)
    assert back.kind == WrenchPolytope.FWP
    np.testing.assert_array_equal(np.asarray(back.polytope.halfspace_normals).reshape(-1, 6), A)
    np.testing.assert_array_equal(np.asarray(back.polytope.halfspace_offsets), b)
