"""
Render a ``visualization_msgs/MarkerArray`` to a PNG with matplotlib (no display needed).

For the README's screenshot of what RViz / Foxglove show, from the markers ``awp_node``
publishes::

    # from a running node (waits for one MarkerArray of an evaluated cycle on the topic,
    # optionally with 3 stance legs):
    python -m awp_ros.demo.render_markers --topic /awp_node/markers --legs 3 -o docs/markers.png
    # offline, through the same pipeline the node runs, at the standing posture:
    python -m awp_ros.demo.render_markers --robot hyq --stance lf_foot,rf_foot,rh_foot -o m.png

Drawn: ``TRIANGLE_LIST`` (translucent faces), ``ARROW`` (two-point arrows), ``SPHERE`` /
``SPHERE_LIST`` / ``POINTS`` (dots), ``LINE_STRIP`` / ``LINE_LIST`` and ``TEXT_VIEW_FACING``
(2D text in the corner, in the marker's colour, since matplotlib's 3D text does not face the
viewer). Other types are skipped. Points are taken in the markers' frame, pose applied.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from visualization_msgs.msg import Marker, MarkerArray

from awp_ros.cli.support import run_main
from awp_ros.errors import ProcessError

__all__ = ['main', 'render_marker_array']


def _pose_points(m: Marker) -> np.ndarray:
    """Return the marker's points (or its position) in the header frame, pose applied."""
    from awp_ros.geometry.linalg import quaternion_matrix
    o = m.pose.orientation
    R = quaternion_matrix([o.x, o.y, o.z, o.w]) if (o.x, o.y, o.z, o.w) != (0, 0, 0, 0) \
        else np.eye(3)
    t = np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z])
    P = np.array([[p.x, p.y, p.z] for p in m.points]).reshape(-1, 3)
    if P.size == 0:
        P = np.zeros((1, 3))
    return P @ R.T + t


def render_marker_array(arr: MarkerArray, path: str, *, title: str = '',
                        elev: float = 18.0, azim: float = -60.0, dpi: int = 130) -> None:
    """
    Draw the ADD markers of ``arr`` into a PNG at ``path``.

    :param arr: the markers (a DELETEALL first, as awp_node sends, is ignored).
    :param path: output PNG path.
    :param title: figure title (default: the frame id and stamp).
    :param elev: camera elevation [deg]; :param azim: camera azimuth [deg].
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plt.figure(figsize=(9, 7.5))
    ax = fig.add_subplot(projection='3d')
    pts_all, texts, legend = [], [], {}
    for m in arr.markers:
        if m.action != Marker.ADD:
            continue
        rgba = (m.color.r, m.color.g, m.color.b, m.color.a)
        P = _pose_points(m)
        if m.type == Marker.TRIANGLE_LIST and len(P) >= 3:
            tri = P[: len(P) // 3 * 3].reshape(-1, 3, 3)
            edge = (*rgba[:3], min(1.0, rgba[3] + 0.25))
            ax.add_collection3d(Poly3DCollection(tri, facecolor=rgba, edgecolor=edge,
                                                 linewidth=0.3))
            pts_all.append(P)
            legend.setdefault(m.ns, rgba)
        elif m.type == Marker.ARROW and len(m.points) == 2:
            a, b = P
            d = b - a
            ax.quiver(*a, *d, color=rgba[:3], linewidth=2.5, arrow_length_ratio=0.12)
            pts_all.append(P)
            legend.setdefault(m.ns, rgba)
        elif m.type in (Marker.SPHERE, Marker.SPHERE_LIST, Marker.POINTS, Marker.CUBE):
            ax.scatter(P[:, 0], P[:, 1], P[:, 2], color=rgba[:3], s=25, depthshade=False)
            pts_all.append(P)
        elif m.type in (Marker.LINE_STRIP, Marker.LINE_LIST) and len(P) >= 2:
            segs = P if m.type == Marker.LINE_STRIP else P[: len(P) // 2 * 2]
            ax.plot(segs[:, 0], segs[:, 1], segs[:, 2], color=rgba[:3])
            pts_all.append(P)
        elif m.type == Marker.TEXT_VIEW_FACING and m.text:
            texts.append((m.text, rgba))
    if pts_all:
        X = np.vstack(pts_all)
        lo, hi = X.min(axis=0), X.max(axis=0)
        c, r = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 0.1)
        ax.set_xlim(c[0] - r, c[0] + r)
        ax.set_ylim(c[1] - r, c[1] + r)
        ax.set_zlim(c[2] - r, c[2] + r)
        ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_zlabel('z [m]')
    ax.view_init(elev=elev, azim=azim)
    header = next((m.header for m in arr.markers if m.action == Marker.ADD), None)
    if not title and header is not None:
        title = (f'awp_node markers, frame {header.frame_id!r}, stamp '
                 f'{header.stamp.sec}.{header.stamp.nanosec:09d}')
    ax.set_title(title, fontsize=10)
    for i, (text, rgba) in enumerate(texts):
        fig.text(0.02, 0.92 - 0.035 * i, text, color=rgba[:3], fontsize=10,
                 family='monospace', bbox={'facecolor': '0.25', 'edgecolor': 'none',
                                           'alpha': 0.85, 'pad': 2})
    handles = [plt.Line2D([], [], color=rgba[:3], linewidth=6, alpha=max(rgba[3], 0.4))
               for rgba in legend.values()]
    if handles:
        ax.legend(handles, list(legend), loc='upper right', fontsize=8, framealpha=0.8)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def _stance_legs(arr: MarkerArray) -> int:
    """Return the number of force polytope meshes (stance legs) in a MarkerArray."""
    return sum(m.ns.startswith('force_polytope') for m in arr.markers)


def _from_topic(topic: str, timeout: float, legs: int | None = None) -> MarkerArray:
    """Wait for one evaluated MarkerArray on ``topic`` (with ``legs`` stance legs)."""
    import time

    import rclpy
    rclpy.init()
    node = rclpy.create_node('awp_render_markers')
    got: list = []

    def keep(arr: MarkerArray) -> None:
        n = _stance_legs(arr)
        if n and (legs is None or n == legs):
            got.append(arr)

    node.create_subscription(MarkerArray, topic, keep, 10)
    deadline = time.monotonic() + timeout
    try:
        while not got and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    if not got:
        raise ProcessError(f'no MarkerArray on {topic} within {timeout} s')
    return got[0]


def _offline(robot: str, stance: list[str] | None, params: dict) -> MarkerArray:
    """Return the markers the node would publish for the standing posture of ``robot``."""
    from awp_ros_msgs.msg import ContactState
    from sensor_msgs.msg import JointState

    from awp_ros.ros.pipeline import Pipeline
    from awp_ros.robot.parameters import PipelineParams
    pipe = Pipeline(robot, PipelineParams(**params))
    ev = pipe.evaluator
    feet = list(ev.feet)
    stance = feet if stance is None else stance
    pipe.on_contacts(ContactState(names=feet, in_contact=[f in stance for f in feet]))
    js = JointState(name=list(ev.model.joint_names), position=ev.model.standing_q.tolist())
    return pipe.on_joint_state(js).markers()


def main(argv: list[str] | None = None) -> int:
    """Command line: render markers from a topic or from the offline pipeline to a PNG."""
    parser = argparse.ArgumentParser(prog='render_markers', description=__doc__.split('\n')[0])
    parser.add_argument('-o', '--output', required=True, help='PNG path')
    parser.add_argument('--topic', help='wait for one MarkerArray on this topic')
    parser.add_argument('--timeout', type=float, default=30.0, help='[s] with --topic')
    parser.add_argument('--legs', type=int, help='with --topic: wait for markers with this '
                        'many stance legs')
    parser.add_argument('--robot', default='hyq', help='offline: config name or path')
    parser.add_argument('--stance', help='offline: comma-separated stance feet (default all)')
    parser.add_argument('--force-scale', type=float, default=0.0005, help='offline [m/N]')
    parser.add_argument('--elev', type=float, default=18.0, help='camera elevation [deg]')
    parser.add_argument('--azim', type=float, default=-60.0, help='camera azimuth [deg]')
    parser.add_argument('--title', default='', help='figure title')
    args = parser.parse_args(argv)
    return run_main('render_markers', lambda: _render(args))


def _render(args) -> int:
    if args.topic:
        arr = _from_topic(args.topic, args.timeout, args.legs)
    else:
        stance = args.stance.split(',') if args.stance else None
        arr = _offline(args.robot, stance, {'marker_force_scale': args.force_scale})
    render_marker_array(arr, args.output, title=args.title, elev=args.elev, azim=args.azim)
    print(args.output)
    return 0


if __name__ == '__main__':
    sys.exit(main())
