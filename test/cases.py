"""
Test cases shared by several test modules (hand-computable robots, HyQ-like legs, messages).

Test modules import it as ``from cases import ...`` (``test/conftest.py`` puts this folder on
``sys.path``).
"""

from __future__ import annotations

from itertools import combinations
import textwrap
import threading

from awp_ros_msgs.msg import ContactState
import numpy as np
import pinocchio as pin
import rclpy
from rclpy.executors import SingleThreadedExecutor
from scipy.optimize import linprog
from scipy.spatial import cKDTree
from sensor_msgs.msg import JointState

from awp_ros.node.launcher import stop_node
from awp_ros.wrench.wrench_polytope import lift_matrices

# -- a toy robot whose legs have a diagonal Jacobian ------------------------------------------

G = 9.81
M_BASE, M_FOOT = 10.0, 1.0
EFFORT = (10.0, 20.0, 30.0)


def toy_urdf(efforts=EFFORT, legs=(('a', 0.0), ('b', 1.0))) -> str:
    """
    Return a URDF whose legs have J = diag(0.5, 0.4, 0.3) at q = 0 (world axes).

    Leg ``name`` at x offset ``dx``: joint 1 (axis z) at (dx, 0.5, 0), joint 2 (axis x) at
    (dx, 0, 0.4), joint 3 (axis y) at (dx + 0.3, 0, 0), foot (and a 1 kg point mass) at
    (dx, 0, 0). A revolute column is axis x (foot - joint): z x (-0.5 y) = 0.5 x,
    x x (-0.4 z) = 0.4 y, y x (-0.3 x) = 0.3 z.
    """
    def inertial(mass, xyz):
        return (f'<inertial><origin xyz="{xyz}"/><mass value="{mass}"/>'
                '<inertia ixx="1e-3" iyy="1e-3" izz="1e-3" ixy="0" ixz="0" iyz="0"/>'
                '</inertial>')
    parts = ['<robot name="toy">', f'<link name="base">{inertial(M_BASE, "0 0 0.5")}</link>']
    for name, dx in legs:
        e1, e2, e3 = efforts
        parts += [
            f'<link name="{name}_l1"/><link name="{name}_l2"/>',
            f'<link name="{name}_l3">{inertial(M_FOOT, "-0.3 0 0")}</link>',
            f'<link name="{name}_foot"/>',
            f'<joint name="{name}_j1" type="revolute"><parent link="base"/>'
            f'<child link="{name}_l1"/><origin xyz="{dx} 0.5 0"/><axis xyz="0 0 1"/>'
            f'<limit effort="{e1}" lower="-3" upper="3" velocity="10"/></joint>',
            f'<joint name="{name}_j2" type="revolute"><parent link="{name}_l1"/>'
            f'<child link="{name}_l2"/><origin xyz="0 -0.5 0.4"/><axis xyz="1 0 0"/>'
            f'<limit effort="{e2}" lower="-3" upper="3" velocity="10"/></joint>',
            f'<joint name="{name}_j3" type="revolute"><parent link="{name}_l2"/>'
            f'<child link="{name}_l3"/><origin xyz="0.3 0 -0.4"/><axis xyz="0 1 0"/>'
            f'<limit effort="{e3}" lower="-3" upper="3" velocity="10"/></joint>',
            f'<joint name="{name}_fj" type="fixed"><parent link="{name}_l3"/>'
            f'<child link="{name}_foot"/><origin xyz="-0.3 0 0"/></joint>',
        ]
    parts.append('</robot>')
    return ''.join(parts)


# -- HyQ-like friction-bounded leg polytopes ---------------------------------------------------

HYQ_FEET = np.array([[0.37, 0.33, -0.55], [0.37, -0.33, -0.55],
                     [-0.37, 0.33, -0.55], [-0.37, -0.33, -0.55]])


# -- test data: parallelepipeds clipped by the mu = 0.7 pyramid (written here, on purpose) --

def clipped_parallelepiped(centre, generators, mu=0.7, normal=(0.0, 0.0, 1.0), sides=4):
    """Vertices of {c + G t, |t|_inf <= 1} & pyramid & {n.f >= 0}, brute force on triples."""
    G = np.asarray(generators, dtype=float)
    Ginv = np.linalg.inv(G)
    rows = [Ginv, -Ginv]
    offs = [1.0 + Ginv @ centre, 1.0 - Ginv @ centre]
    n = np.asarray(normal, dtype=float)
    n /= np.linalg.norm(n)
    x = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.99 else np.array([0.0, 1.0, 0.0])
    t1 = x - (x @ n) * n
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    th = 2 * np.pi * np.arange(sides) / sides
    rows.append(np.cos(th)[:, None] * t1 + np.sin(th)[:, None] * t2
                - mu * np.cos(np.pi / sides) * n)
    offs.append(np.zeros(sides))
    rows.append(-n[None, :])
    offs.append(np.zeros(1))
    A, b = np.vstack(rows), np.concatenate(offs)
    A, b = A / np.linalg.norm(A, axis=1)[:, None], b / np.linalg.norm(A, axis=1)
    V = []
    for i, j, k in combinations(range(len(A)), 3):
        M = A[[i, j, k]]
        if abs(np.linalg.det(M)) < 1e-9:
            continue
        v = np.linalg.solve(M, b[[i, j, k]])
        if np.all(A @ v <= b + 1e-7 * (1.0 + np.abs(b))):
            V.append(v)
    V = np.array(V).reshape(-1, 3)
    keep = [i for i in range(len(V)) if all(np.linalg.norm(V[i] - V[j]) > 1e-6
                                            for j in range(i))]
    return V[keep]


def hyq_like_leg(rng) -> np.ndarray:
    """Return a HyQ-like friction-bounded polytope: generators of 300-2000 N, centre near 0."""
    while True:
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        G = R * rng.uniform(300.0, 2000.0, size=3)
        if abs(np.linalg.det(G)) > 1e6:
            break
    centre = rng.uniform(-80.0, 80.0, size=3) + [0.0, 0.0, 100.0]
    return clipped_parallelepiped(centre, G)


def hyq_feet(rng, K) -> np.ndarray:
    """K feet near HyQ's (a fifth one, a hexapod's middle leg, near the body's side)."""
    feet = np.vstack([HYQ_FEET, [[0.0, 0.4, -0.55], [0.0, -0.4, -0.55]]])
    return feet[:K] + rng.uniform(-0.05, 0.05, size=(K, 3))


def assert_same_polytope(S, other, *, share: float = 0.2) -> None:
    """
    Assert that two H-reps describe one set.

    Each row of one is the other's to 1e-9 or implied by the other's rows (an LP within the
    other's hull), and fewer than ``share`` of the rows are not the other's.
    """
    assert S.dimension == other.dimension
    np.testing.assert_allclose(S.hull_basis @ S.hull_basis.T,
                               other.hull_basis @ other.hull_basis.T, atol=1e-9)
    for P, Q in ((S, other), (other, S)):
        rows = np.column_stack([P.A, P.b / 1e3])
        gap, _ = cKDTree(np.column_stack([Q.A, Q.b / 1e3])).query(rows)
        for i in np.flatnonzero(gap > 1e-9):
            # Within the hull (its equalities), P's row i is no tighter than Q's rows allow.
            E, e = Q.equalities
            best = linprog(-P.A[i], A_ub=Q.A, b_ub=Q.b, A_eq=E if E.shape[0] else None,
                           b_eq=e if E.shape[0] else None, bounds=(None, None),
                           method='highs')
            assert best.status == 0 and -best.fun <= P.b[i] + 1e-9 * (1 + abs(P.b[i]))
        assert np.count_nonzero(gap > 1e-9) < share * gap.size


def vertex_sums(positions, vertex_sets) -> np.ndarray:
    pts = np.zeros((1, 6))
    for Lk, V in zip(lift_matrices(positions), vertex_sets):
        pts = (pts[:, None, :] + (V @ Lk.T)[None, :, :]).reshape(-1, 6)
    return pts


# -- HyQ input messages ------------------------------------------------------------------------

FEET = ['lf_foot', 'rf_foot', 'lh_foot', 'rh_foot']
T0 = 1_700_000_000 * 10**9


def stamp(msg, ns: int):
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
    return msg


def joints_msg(evaluator, ns: int, dq: float = 0.0) -> JointState:
    js = JointState(name=list(evaluator.model.joint_names),
                    position=(evaluator.model.standing_q + dq).tolist())
    return stamp(js, ns)


def contacts_msg(ns: int, stance=FEET, mu=()) -> ContactState:
    return stamp(ContactState(names=FEET, in_contact=[f in stance for f in FEET],
                              friction_coefficients=list(mu)), ns)


# -- joint efforts of known contact forces (inverse dynamics, Jacobians by differences) -----

def fd_jacobian(model, q: np.ndarray, frame: str, eps: float = 1e-7) -> np.ndarray:
    """Return d(foot position)/d(joint positions), (3, n_joints), by central differences."""
    data = model.createData()
    fid = model.getFrameId(frame)

    def foot(qq):
        pin.framesForwardKinematics(model, data, qq)
        return data.oMf[fid].translation.copy()
    J = np.zeros((3, model.nq - 7))
    for i in range(model.nq - 7):
        dq = np.zeros(model.nq)
        dq[7 + i] = eps
        J[:, i] = (foot(q + dq) - foot(q - dq)) / (2 * eps)
    return J


def efforts_for(evaluator, joints: dict, forces: dict, velocities: dict | None = None):
    """Return tau = rnea(q, v, 0) - sum_k J_k^T f_k, J by finite differences (base at rest)."""
    m = evaluator.model
    q = np.concatenate([[0, 0, 0, 0, 0, 0, 1], [joints[n] for n in m.joint_names]])
    v = np.zeros(m.model.nv)
    if velocities:
        v[6:] = [velocities[n] for n in m.joint_names]
    tau = pin.rnea(m.model, m.model.createData(), q, v, np.zeros(m.model.nv))[6:].copy()
    for foot, f in forces.items():
        tau -= fd_jacobian(m.model, q, foot).T @ np.asarray(f, dtype=float)
    return dict(zip(m.joint_names, tau.tolist()))


# -- a report recorder process (live tests) ----------------------------------------------------

#: ``python -c REPORT_RECORDER WANT TIMEOUT``: subscribe to /awp_node/report, print ``ready``
#: once the node's publisher is discovered (a volatile subscription misses what was published
#: before it matched), then one JSON line per report received (up to WANT, within TIMEOUT s).
REPORT_RECORDER = textwrap.dedent("""
    import json, sys, time
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from awp_ros_msgs.msg import FeasibilityReport
    want, timeout = int(sys.argv[1]), float(sys.argv[2])
    rclpy.init()
    node = rclpy.create_node('awp_test_recorder')
    got = []
    node.create_subscription(FeasibilityReport, '/awp_node/report', got.append,
                             QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
    deadline = time.monotonic() + timeout
    while node.count_publishers('/awp_node/report') < 1 and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    for _ in range(10):
        rclpy.spin_once(node, timeout_sec=0.05)
    print('ready', flush=True)
    while len(got) < want and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    for r in got:
        f, t = r.wrench.force, r.wrench.torque
        print(json.dumps({'stamp': r.header.stamp.sec * 10**9 + r.header.stamp.nanosec,
                          'status': r.status, 'message': r.status_message,
                          'motion': r.motion, 'stance': list(r.stance_feet),
                          'wrench': [f.x, f.y, f.z, t.x, t.y, t.z],
                          'awp': r.awp_margin, 'fwp': r.fwp_margin,
                          'fwp_res': r.fwp_affine_residual}))
    node.destroy_node()
    rclpy.shutdown()
""")


class DdsPeer:
    """
    A test's own DDS participant: a private rclpy context and node, spun in a thread.

    Subclasses create their publishers and subscriptions (``keep`` stores messages under
    ``lock``), then call :meth:`start`; :meth:`close` ends it all.
    """

    def __init__(self, env: dict, name: str) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=int(env['ROS_DOMAIN_ID']))
        self.node = rclpy.create_node(name, context=self.context)
        self.lock = threading.Lock()

    def keep(self, into: list):
        """Return a subscription callback appending each message to ``into``."""
        def callback(msg) -> None:
            with self.lock:
                into.append(msg)
        return callback

    def start(self) -> None:
        """Spin the node in a daemon thread."""
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def close(self) -> None:
        """Stop spinning, destroy the node, shut the context down."""
        self.executor.shutdown()
        self.thread.join(timeout=5)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def stop_peers(started: list) -> None:
    """Close each ``(node process, DdsPeer)``'s peer and stop its node: no traceback logged."""
    for proc, peer in started:
        peer.close()
        log = stop_node(proc)
        assert 'Traceback' not in log, log
