"""
Measure how the FWS's facets change along the default bag.

The measurement behind the README's "Speed: awp_bench" paragraph on reusing the previous
cycle's facets.

::

    PYTHONPATH=. .venv/bin/python examples/experiments/fws_facet_changes.py [--states 300]

Runs the node's pipeline (:class:`awp_ros.ros.pipeline.Pipeline`, no DDS) over the default bag
``config/hyq_gait.mcap`` with the FWS every cycle (``fws_rate_hz: 0``) and, over the first
``--states`` consecutive joint states with four stance legs, identifies each facet of the FWS
``S = sum_k L_k Q_k`` by the faces it takes from the legs: for a row ``a`` of the H-rep the face
of leg ``k`` is the set of vertices of ``Q_k`` maximising ``(L_k^T a) . v`` (to 1e-9 of the
values' scale), each vertex named by the rows of ``Q_k``'s H-rep it lies on (torque limits and
pyramid sides: a name that survives from one joint state to the next). A row is a *facet*
when the lifted faces span 5 dimensions, *degenerate* when the faces' own dimensions add up
to more than 5. It prints the mean counts per joint state and how many facets appear and
disappear between consecutive joint states.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]


def _rank(X: np.ndarray) -> int:
    """Return the numerical rank of the rows of X (:func:`orthonormal_span`'s, rtol 1e-9)."""
    from awp_ros.geometry.linalg import orthonormal_span
    return orthonormal_span(X).shape[1]


def facet_names(positions: np.ndarray, legs: list, A: np.ndarray) -> dict:
    """
    Name the facets of the FWS rows ``A`` (unit normals) by the faces they take from the legs.

    ``legs``: each leg's friction-bounded polytope (vertices, H-rep) [N]; ``positions`` (K, 3)
    the feet relative to the CoM [m]. Returns ``names`` (the facets' names: one per facet,
    whatever its copies among the rows), ``degenerate`` (how many of them have faces adding up
    to more than 5) and ``redundant`` (rows whose face spans fewer than 5 dimensions: valid
    supporting halfspaces, not facets).
    """
    from awp_ros.wrench.wrench_polytope import lift_matrices
    L = lift_matrices(positions)                                  # (K, 6, 3)
    vertex_names, scales = [], []
    for Q in legs:
        V = Q.vertices
        scale = np.abs(V).max()
        tight = np.abs(V @ Q.A.T - Q.b) <= 1e-9 * scale * (1.0 + np.abs(Q.A).max())
        vertex_names.append([frozenset(np.flatnonzero(t).tolist()) for t in tight])
        scales.append(scale)
    rows, redundant = {}, 0                  # name -> (degenerate, the facet's rows)
    for a in A:
        faces, directions, dims = [], [], 0
        for k, Q in enumerate(legs):
            c = L[k].T @ a
            values = Q.vertices @ c
            slack = 1e-9 * scales[k] * max(1.0, np.abs(c).max())
            on = np.flatnonzero(values >= values.max() - slack)
            F = Q.vertices[on]
            dims += _rank(F[1:] - F[0]) if len(on) > 1 else 0
            directions.append((F[1:] - F[0]) @ L[k].T)
            faces.append(frozenset(vertex_names[k][i] for i in on))
        if _rank(np.vstack(directions)) != 5:
            redundant += 1
            continue
        rows.setdefault(tuple(faces), (dims > 5, []))[1].append(a)
    return {'names': set(rows), 'degenerate': sum(d for d, _ in rows.values()),
            'redundant': redundant}


def main(argv: list[str] | None = None) -> int:
    """Print the facet counts of the FWS along the bag (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--states', type=int, default=300,
                        help='consecutive four-leg joint states to analyse (default 300)')
    parser.add_argument('--bag', default=str(REPO / 'config' / 'hyq_gait.mcap'))
    args = parser.parse_args(argv)
    from awp_ros_msgs.msg import ContactState
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState

    from awp_ros.bags.reader import read_bag
    from awp_ros.robot.config import load_parameters
    from awp_ros.ros.pipeline import Pipeline

    params, base_dir = load_parameters('hyq', {'fws_rate_hz': 0.0})
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    types = {'/joint_states': JointState, '/contacts': ContactState}
    rows, facets, degenerate, redundant = [], [], [], []
    appear, disappear, unchanged, previous = [], [], 0, None
    for m in read_bag(args.bag, topics=list(types)):
        msg = deserialize_message(m.data, types[m.topic])
        if m.topic == '/contacts':
            pipeline.on_contacts(msg)
            continue
        r = pipeline.on_joint_state(msg).result
        if r is None or len(r.stance) != 4 or r.fws is None:
            previous = None                          # consecutive four-leg states only
            continue
        legs = [r.legs[f] for f in r.stance]
        P = np.array([leg.position for leg in legs])
        found = facet_names(P, [leg.friction_polytope for leg in legs], r.fws.polytope.A)
        names = found['names']
        rows.append(r.fws.polytope.A.shape[0])
        facets.append(len(names))
        degenerate.append(found['degenerate'])
        redundant.append(found['redundant'])
        if previous is not None:
            appear.append(len(names - previous))
            disappear.append(len(previous - names))
            unchanged += names == previous
        previous = names
        if len(rows) == args.states:
            break
    print(f'{len(rows)} four-leg joint states of {Path(args.bag).name}: per joint state, mean '
          f'{np.mean(rows):.0f} rows, {np.mean(facets):.0f} facets, {np.mean(degenerate):.0f} '
          f'of them degenerate (faces adding up to more than 5); {np.mean(redundant):.0f} rows '
          f'are not facets (faces spanning fewer than 5 dimensions), the others are the facets '
          f'and copies of them')
    print(f'between {len(appear)} consecutive pairs: {np.mean(appear):.0f} facets appear and '
          f'{np.mean(disappear):.0f} disappear (mean); no change in {unchanged} pairs')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
