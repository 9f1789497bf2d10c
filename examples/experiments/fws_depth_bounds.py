r"""
Measure how much of the FWS's facet search a force-distribution bound on the depth could skip.

::

    PYTHONPATH=. .venv/bin/python examples/experiments/fws_depth_bounds.py [--every 50]

The measurement behind the README's "Speed: awp_bench" paragraph on searching only for the
facet nearest to the wrench. The FWS's Euclidean margin of a wrench ``w`` inside it is its
depth ``d* = min_a (h_S(a) - a . w)`` over unit facet normals ``a``. With forces ``f_k`` in
the legs' friction-bounded polytopes ``Q_k`` and ``sum_k L_k f_k = w``, every direction splits
exactly into the legs' slacks (``c_k = L_k^T a``):

.. math::

    h_S(a) - a \cdot w = \sum_k \bigl(h_{Q_k}(c_k) - c_k \cdot f_k\bigr)
                       \ge \sum_k \rho_k |c_k|                                  \qquad (1)

with ``rho_k`` the depth of ``f_k`` in ``Q_k``. On the slice of leg A's facet (unit normal
``n``, offset ``o``: ``c_A = lambda n``, ``x = (lambda, t)``, ``a = M x``), leg A's term is
exactly ``lambda (o - n . f_A)``, and (1) with ``|.|_1 >= |.|_2`` gives

.. math::

    h_S(a) - a \cdot w \ge \sqrt{x^T Q x}, \quad
    Q = (o - n \cdot f_A)^2 e_0 e_0^T + \sum_{k \ne A} \rho_k^2 J_k^T J_k, \quad
    \min_{|M x| = 1} \sqrt{x^T Q x} = \sqrt{\mu_{min}(Q, M^T M)}                  \qquad (2)

(``J_k x = c_k``; the smallest generalised eigenvalue). A slice whose bound (2) reaches
``d*`` holds no facet nearer than the nearest one, nor does a node of the (2, 1, 1, 1)
search (an edge of leg B and one of leg C: the same bound on the node's plane of ``x``); a
search for the nearest facet only could skip them. The forces are the most interior
distribution (the LP ``max r`` with every ``rho_k >= r``, HiGHS). Runs the node's pipeline
(no DDS) over the default bag and, on every ``--every``-th joint state with four stance legs,
prints ``r``, ``d*`` (from the exact H-rep), how many slices and nodes (2) would skip and the
largest bounds relative to ``d*``. It
also checks that (2) bounds every H-rep row of its slice (a lower bound, never above).
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.linalg import eigh
from scipy.optimize import linprog

from awp_ros.wrench.wrench_polytope import lift_matrices


def _skew(v: np.ndarray) -> np.ndarray:
    """Return ``[v]x``, the matrix of ``u -> v x u``: the moment rows of the lift ``L(v)``."""
    return lift_matrices(np.reshape(v, (1, 3)))[0, 3:]


def interior_forces(positions: np.ndarray, faces: list, w: np.ndarray) -> tuple:
    """
    Return ``(f (K, 3), r)``: forces with ``sum_k L_k f_k = w`` maximising ``min_k rho_k``.

    ``rho_k = min_i (o_i - n_i . f_k)`` over leg k's unit facet normals ``n_i`` and offsets
    ``o_i`` (its depth in ``Q_k``); an LP in ``(f, r)``.
    """
    K = len(faces)
    rows, rhs = [], []
    for k, F in enumerate(faces):
        for n, o in zip(F.facet_normals, F.facet_offsets):
            row = np.zeros(3 * K + 1)
            row[3 * k:3 * k + 3], row[-1] = n, 1.0
            rows.append(row)
            rhs.append(o)
    eq = np.zeros((6, 3 * K + 1))
    eq[:, :-1] = np.hstack(lift_matrices(positions))            # sum_k L_k f_k = w
    cost = np.zeros(3 * K + 1)
    cost[-1] = -1.0
    lp = linprog(cost, A_ub=np.array(rows), b_ub=rhs, A_eq=eq, b_eq=w,
                 bounds=[(None, None)] * (3 * K + 1), method='highs')
    if lp.status != 0:
        raise RuntimeError(f'no force distribution: {lp.message}')
    return lp.x[:-1].reshape(K, 3), float(lp.x[-1])


def slice_bounds(positions: np.ndarray, faces: list, forces: np.ndarray) -> list[dict]:
    """
    Return, per slice (leg A, facet of A), bound (2) and the node bounds of (2, 1, 1, 1).

    Each item: ``leg``, ``normal`` (n), ``bound`` (2) and ``nodes``, the bounds on the planes
    ``{x : r_B . x = r_C . x = 0}`` of every pair of edge directions of the next two legs
    (``r = (n . e, (p_k - p_A) x e)``), NaN for a degenerate pair.
    """
    K = len(faces)
    depth = np.array([np.min(F.facet_offsets - F.facet_normals @ f)
                      for F, f in zip(faces, forces)])
    out = []
    for A in range(K):
        others = [k for k in range(K) if k != A]
        for n, o in zip(faces[A].facet_normals, faces[A].facet_offsets):
            M = np.zeros((6, 4))
            M[:3, 0], M[:3, 1:], M[3:, 1:] = n, _skew(positions[A]), np.eye(3)
            Q = np.zeros((4, 4))
            Q[0, 0] = (o - n @ forces[A]) ** 2
            for k in others:
                J = np.zeros((3, 4))
                J[:, 0], J[:, 1:] = n, -_skew(positions[k] - positions[A])
                Q += depth[k] ** 2 * J.T @ J
            N = M.T @ M
            bound = float(np.sqrt(max(eigh(Q, N, eigvals_only=True)[0], 0.0)))
            walls = []
            for k in others[:2]:
                e = faces[k].groups[0].dirs[:, 0]                     # edge classes (m, 3)
                walls.append(np.column_stack([e @ n, np.cross(positions[k] - positions[A], e)]))
            pairs = np.stack(np.broadcast_arrays(walls[0][:, None], walls[1][None]), axis=-1)
            pairs = pairs.reshape(-1, 4, 2)
            basis = np.linalg.qr(pairs, mode='complete')[0][:, :, 2:]      # the node planes
            q = np.swapaxes(basis, 1, 2) @ Q @ basis
            m = np.swapaxes(basis, 1, 2) @ N @ basis
            # Smallest root of det(q - mu m) = 0 (2x2, m positive definite).
            a2 = m[:, 0, 0] * m[:, 1, 1] - m[:, 0, 1] ** 2
            a1 = -(q[:, 0, 0] * m[:, 1, 1] + q[:, 1, 1] * m[:, 0, 0] - 2 * q[:, 0, 1] * m[:, 0, 1])
            a0 = q[:, 0, 0] * q[:, 1, 1] - q[:, 0, 1] ** 2
            with np.errstate(invalid='ignore', divide='ignore'):
                mu = (-a1 - np.sqrt(np.maximum(a1 * a1 - 4 * a2 * a0, 0.0))) / (2 * a2)
                nodes = np.sqrt(np.maximum(mu, 0.0))
            rb, rc = pairs[:, :, 0], pairs[:, :, 1]
            gram = np.einsum('pi,pi->p', rb, rb) * np.einsum('pi,pi->p', rc, rc)
            wedge = gram - np.einsum('pi,pi->p', rb, rc) ** 2       # |r_B ^ r_C|^2
            nodes[~(wedge > 1e-16 * gram)] = np.nan                # rank-deficient: no node
            out.append({'leg': A, 'normal': n, 'bound': bound, 'nodes': nodes})
    return out


def measure(positions: np.ndarray, frictions: list, w: np.ndarray) -> dict:
    """Return ``r``, ``d*``, the slices and nodes bound (2) skips, and its worst violation."""
    from awp_ros.evaluation.evaluator import compute_fws
    from awp_ros.geometry.face_lattice import polytope_faces
    from awp_ros.wrench.feasible_wrench_set import _leg_inputs
    P = np.asarray(positions, dtype=float)
    faces = [polytope_faces(V, H, rank_tol=1e-7, plane_tol=1e-9)     # as the FWS's H-rep
             for V, H in zip(*_leg_inputs(frictions))]
    forces, r = interior_forces(P, faces, w)
    S = compute_fws(P, frictions, w, 1e-6, 1e-6)[0]
    slack = S.b - S.A @ w
    d_star = float(slack.min())
    L = lift_matrices(P)
    bounds = slice_bounds(P, faces, forces)
    worst = -np.inf                      # max over the H-rep rows of a slice of bound - slack
    for item in bounds:
        c = S.A @ L[item['leg']]          # c_A = L_A^T a of every row
        along = c @ item['normal']
        on = (along > 1e-9) & (np.linalg.norm(c - np.outer(along, item['normal']), axis=1)
                               <= 1e-9 * np.abs(along))
        if np.any(on):
            worst = max(worst, float(np.max(item['bound'] - slack[on])))
    nodes = np.concatenate([item['nodes'] for item in bounds])
    nodes = nodes[np.isfinite(nodes)]
    return {'r': r, 'd_star': d_star,
            'slices': (sum(item['bound'] >= d_star for item in bounds), len(bounds)),
            'nodes': (int(np.sum(nodes >= d_star)), int(nodes.size)),
            'largest_bound': max(item['bound'] for item in bounds),
            'largest_node': float(nodes.max(initial=0.0)), 'worst': worst}


def four_leg_jobs(every: int) -> list[tuple]:
    """Return ``(positions, frictions, wrench)`` of every ``every``-th 4-leg state of the bag."""
    from awp_ros_msgs.msg import ContactState
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState

    from awp_ros.bags.reader import read_bag
    from awp_ros.gait.bag import default_bag_path
    from awp_ros.robot.config import load_parameters
    from awp_ros.ros.pipeline import Pipeline
    params, base_dir = load_parameters('hyq', {})
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    types = {'/joint_states': JointState, '/contacts': ContactState}
    jobs, seen = [], 0
    for m in read_bag(str(default_bag_path()), topics=list(types)):
        msg = deserialize_message(m.data, types[m.topic])
        if m.topic == '/contacts':
            pipeline.on_contacts(msg)
            continue
        r = pipeline.on_joint_state(msg).result
        if r is None or len(r.stance) != 4:
            continue
        if seen % every == 0:
            positions, frictions, wrench = pipeline.evaluator.fws_job(r)[:3]
            jobs.append((positions, frictions, wrench))
        seen += 1
    return jobs


def main(argv: list[str] | None = None) -> int:
    """Print the bound's reach on the default bag (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--every', type=int, default=50,
                        help='measure every n-th four-leg joint state (default 50)')
    args = parser.parse_args(argv)
    rows = [measure(*job) for job in four_leg_jobs(args.every)]
    for i, row in enumerate(rows):
        print(f'{i:3d}: r {row["r"]:.1f} N, d* {row["d_star"]:.1f}, largest slice bound '
              f'{row["largest_bound"]:.1f}; slices skipped {row["slices"][0]} of '
              f'{row["slices"][1]}, nodes skipped {row["nodes"][0]} of {row["nodes"][1]}')
    skipped = [sum(row[key][j] for row in rows) for key in ('slices', 'nodes') for j in (0, 1)]
    ratio = np.array([[row['largest_bound'] / row['d_star'], row['largest_node'] / row['d_star']]
                      for row in rows])
    print(f'{len(rows)} four-leg joint states: slices skipped {skipped[0]} of {skipped[1]}, '
          f'(2, 1, 1, 1) nodes skipped {skipped[2]} of {skipped[3]}; largest bound / d*: '
          f'slices {ratio[:, 0].min():.2f}-{ratio[:, 0].max():.2f}, nodes '
          f'{ratio[:, 1].min():.2f}-{ratio[:, 1].max():.2f}; bound - row slack at most '
          f'{max(row["worst"] for row in rows):.3g} (a lower bound: <= 0)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
