r"""
RViz / Foxglove markers of one evaluation (``visualization_msgs/MarkerArray``).

What is drawn (the seed's Fig. 1 plus the wrench), each namespace stating its force scale
``s`` [m/N] so that a length in the scene reads back as a force:

- ``force_polytope [s m/N]`` (blue) and ``friction_polytope [s m/N]`` (red): per stance leg,
  the force polytope and the friction-bounded polytope as translucent ``TRIANGLE_LIST``
  meshes with their origin (zero force) at the foot: vertex ``f`` is drawn at ``p + s f``.
- ``friction_pyramid [s m/N]`` (pink): the N-sided pyramid of each stance leg (apex at the
  foot), cut at the height of the leg's force polytope along the normal.
- ``gravito_inertial_wrench [s m/N]`` (orange ``ARROW`` from the CoM to ``c + s f``) and
  ``gravito_inertial_moment [s_m m/(N.m)]`` (purple), the wrench the contacts must supply.
- ``fwp_force_slice [s m/N]`` (green): the **force slice of the FWP at the current moment**,
  :math:`\{f : [f; \tau_{now}] \in FWP\}`, drawn from the CoM: the wrench arrow's tip is
  inside it exactly when the wrench is in the FWP. It is 3D with 3-4 stance legs, a polygon
  with 2 legs (the FWP is 5D), at most a point with 1 leg (not drawn).
- ``support_region`` (blue), ``fwp_region`` (yellow) and ``feasible_region`` (green): the
  CoM regions (:mod:`awp_ros.wrench.com_region`) as filled ``TRIANGLE_LIST`` polygons,
  drawn flat on the stance feet's mean height (the ground under the CoM; the CoM height
  without a stance foot), each a few millimetres above the previous; a segment (two
  stance legs) is a ``LINE_STRIP``, a point (one leg) a small ``SPHERE``, an empty region
  nothing. ``com_projection``: a ``SPHERE`` at the CoM's vertical projection on that
  plane, green inside the feasible region, red outside, grey without one. The feasible
  region is the latest computed (with the FWS), the others the cycle's.
- ``com`` (white ``SPHERE``), ``stance_feet`` (white ``SPHERE_LIST``) and ``margins``
  (``TEXT_VIEW_FACING`` lines above the CoM, one per set, green when the wrench is in the
  set (margin >= 0 on its affine hull), red when not, grey when not computed).

Every array starts with a ``DELETEALL`` marker, so legs that lift off vanish. Points are in
the CoM-centred world-aligned frame (``wrench_frame_id``; RViz needs no TF when it is the
fixed frame), or in the base link frame when the caller passes its rotation and offset.
Markers are built at the marker rate only, not in the per-cycle hot path.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
import numpy as np
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from awp_ros.evaluation.result import FeasibilityResult, WrenchSetResult
from awp_ros.geometry.mesh import force_slice, hull_triangles
from awp_ros.wrench.contact_wrench_cone import friction_pyramids

__all__ = ['MarkerStyle', 'build_markers', 'error_markers']


def _rgba(code: str) -> tuple[float, ...]:
    """Return the RGBA values in [0, 1] of a colour ``#rrggbbaa``."""
    return tuple(int(code[i:i + 2], 16) / 255.0 for i in (1, 3, 5, 7))


#: Colours of every drawn element (RGBA, written as Foxglove and the web write them).
_COLORS = {name: _rgba(code) for name, code in {
    'force_polytope': '#3373ff4c', 'friction_polytope': '#ff404c8c',
    'friction_pyramid': '#ff99d92e', 'fwp_force_slice': '#33cc5940', 'wrench': '#ff8c00ff',
    'moment': '#994ce6ff', 'com': '#ffffffff', 'positive': '#33d933ff', 'negative': '#ff3333ff',
    'unknown': '#b2b2b2ff', 'support_region': '#4c99ff4c', 'fwp_region': '#ffd93359',
    'feasible_region': '#33d95980',
}.items()}
#: Drawing order of the CoM regions (bottom first) and their height steps above the plane.
_REGION_ORDER = ('support_region', 'fwp_region', 'feasible_region')
_REGION_STEP = 0.003    # [m]


@dataclass(frozen=True)
class MarkerStyle:
    """
    Sizes of the markers.

    :ivar force_scale: scene length per newton [m/N] (forces drawn as ``p + s f``).
    :ivar moment_scale: scene length per newton-metre [m/(N.m)] for the moment arrow.
    :ivar text_height: height of the margin text [m].
    :ivar arrow_diameter: shaft diameter of the wrench arrows [m].
    :ivar com_diameter: diameter of the CoM sphere [m].
    """

    force_scale: float = 0.0005
    moment_scale: float = 0.002
    text_height: float = 0.06
    arrow_diameter: float = 0.02
    com_diameter: float = 0.05


# -- markers -------------------------------------------------------------------------------


def _color(rgba: tuple[float, float, float, float]) -> ColorRGBA:
    r, g, b, a = rgba
    return ColorRGBA(r=r, g=g, b=b, a=a)


def _points(X: np.ndarray) -> list[Point]:
    return [Point(x=x, y=y, z=z) for x, y, z in np.asarray(X, dtype=float).reshape(-1, 3)
            .tolist()]


class _Builder:
    """Collects markers with a common header and a frame transform x -> R x + t."""

    def __init__(self, header: Header, R: np.ndarray, t: np.ndarray) -> None:
        self.header, self.R, self.t = header, R, t
        clear = Marker(header=header, action=Marker.DELETEALL)
        self.markers: list[Marker] = [clear]

    def to_frame(self, X: np.ndarray) -> np.ndarray:
        return np.asarray(X, dtype=float) @ self.R.T + self.t

    def add(self, ns: str, mid: int, mtype: int, rgba, *, points=None, position=None,
            scale=(1.0, 1.0, 1.0), text: str = '') -> Marker:
        m = Marker(header=self.header, ns=ns, id=mid, type=mtype, action=Marker.ADD)
        m.pose.orientation.w = 1.0
        if position is not None:
            x, y, z = self.to_frame(position).tolist()
            m.pose.position.x, m.pose.position.y, m.pose.position.z = x, y, z
        m.scale.x, m.scale.y, m.scale.z = (float(v) for v in scale)
        m.color = _color(rgba)
        m.lifetime = Duration()
        if points is not None:
            m.points = _points(self.to_frame(points))
        m.text = text
        self.markers.append(m)
        return m


def build_markers(result: FeasibilityResult, header: Header, *,
                  style: MarkerStyle = MarkerStyle(), fws: WrenchSetResult | None = None,
                  pyramid_sides: int = 4, rotation: np.ndarray | None = None,
                  translation: np.ndarray | None = None, status_text: str = ''
                  ) -> MarkerArray:
    """
    Return the markers of one evaluation (see the module docstring).

    :param result: the evaluation (wrench [N, N.m] and leg polytopes [N], CoM-centred
        world-aligned frame).
    :param header: stamp of the answered joint state; frame_id the markers' frame.
    :param style: scales and sizes.
    :param fws: the latest FWS result for the margin text (default ``result.fws``).
    :param pyramid_sides: sides of the drawn friction pyramids.
    :param rotation: ``(3, 3)`` rotation from the CoM-centred world-aligned frame to the
        marker frame (default identity).
    :param translation: ``(3,)`` position of the CoM in the marker frame [m] (default 0).
    :param status_text: an extra text line (warnings), shown under the margins.
    """
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    t = np.zeros(3) if translation is None else np.asarray(translation, dtype=float)
    out = _Builder(header, R, t)
    s = style.force_scale
    tag = f'[{s:g} m/N]'
    legs = list(result.legs.values())
    if legs:
        normals = np.array([leg.normal for leg in legs])
        mus = np.array([leg.friction_coefficient for leg in legs])
        rays, _ = friction_pyramids(normals, mus, pyramid_sides)
    for k, leg in enumerate(legs):
        p = leg.position
        tri = hull_triangles(leg.force_polytope.vertices)
        if tri.size:
            out.add(f'force_polytope {tag}', k, Marker.TRIANGLE_LIST,
                    _COLORS['force_polytope'], points=p + s * tri)
        tri = hull_triangles(leg.friction_polytope.vertices)
        if tri.size:
            out.add(f'friction_polytope {tag}', k, Marker.TRIANGLE_LIST,
                    _COLORS['friction_polytope'], points=p + s * tri)
        V = leg.force_polytope.vertices
        height = float(np.max(V @ leg.normal)) if V.size else 0.0
        if height > 0.0:
            ring = rays[k] * (height / (rays[k] @ leg.normal))[:, None]
            sides = np.stack([np.zeros_like(ring), ring, np.roll(ring, -1, axis=0)], axis=1)
            sides = np.concatenate([sides, sides[:, ::-1]])
            out.add(f'friction_pyramid {tag}', k, Marker.TRIANGLE_LIST,
                    _COLORS['friction_pyramid'], points=p + s * sides)
    w = result.wrench
    d = style.arrow_diameter
    if np.linalg.norm(w[:3]) > 0.0:
        out.add(f'gravito_inertial_wrench {tag}', 0, Marker.ARROW, _COLORS['wrench'],
                points=np.array([np.zeros(3), s * w[:3]]), scale=(d, 2 * d, 3 * d))
    if np.linalg.norm(w[3:]) * style.moment_scale > 1e-4:
        out.add(f'gravito_inertial_moment [{style.moment_scale:g} m/(N.m)]', 0,
                Marker.ARROW, _COLORS['moment'],
                points=np.array([np.zeros(3), style.moment_scale * w[3:]]),
                scale=(d / 2, d, 1.5 * d))
    fwp = result.fwp
    tri = hull_triangles(force_slice(fwp.polytope, w[3:], interior=w))
    if tri.size:
        out.add(f'fwp_force_slice {tag}', 0, Marker.TRIANGLE_LIST, _COLORS['fwp_force_slice'],
                points=s * tri)
    c = style.com_diameter
    out.add('com', 0, Marker.SPHERE, _COLORS['com'], position=np.zeros(3), scale=(c, c, c))
    if legs:
        out.add('stance_feet', 0, Marker.SPHERE_LIST, _COLORS['com'],
                points=np.array([leg.position for leg in legs]), scale=(c, c, c))
    fws = result.fws if fws is None else fws
    _regions(out, result, fws, style)
    lines = [(name.upper(), r) for name, r in (('awp', result.awp), ('fwp', fwp),
                                               ('fws', fws))]
    _margin_texts(out, lines, style, status_text)
    return MarkerArray(markers=out.markers)


def _regions(out: _Builder, result: FeasibilityResult, fws: WrenchSetResult | None,
             style: MarkerStyle) -> None:
    """Add the CoM regions and the CoM's projection, flat on the stance feet's height."""
    legs = list(result.legs.values())
    z0 = float(np.mean([leg.position[2] for leg in legs])) if legs else 0.0
    regions = {'support_region': getattr(result, 'support_region', None),
               'fwp_region': result.fwp.region,
               'feasible_region': result.feasible_region_with(fws)[0]}
    for i, name in enumerate(_REGION_ORDER):
        region = regions[name]
        if region is None or region.is_empty:
            continue
        z = z0 + _REGION_STEP * (i + 1)
        V = np.column_stack([region.vertices, np.full(region.vertices.shape[0], z)])
        rgba = _COLORS[name]
        if region.dimension == 2:
            k = V.shape[0]
            fan = np.stack([np.repeat(V[:1], k - 2, axis=0), V[1:-1], V[2:]], axis=1)
            tri = np.concatenate([fan, fan[:, ::-1]])         # both sides
            out.add(name, 0, Marker.TRIANGLE_LIST, rgba, points=tri)
        elif region.dimension == 1:
            out.add(name, 0, Marker.LINE_STRIP, rgba[:3] + (1.0,), points=V,
                    scale=(style.arrow_diameter / 2,) * 3)      # x: the line width
        else:
            c = style.com_diameter / 2
            out.add(name, 0, Marker.SPHERE, rgba[:3] + (1.0,), position=V[0],
                    scale=(c, c, c))
    feasible = regions['feasible_region']
    margin = math.nan if feasible is None else feasible.margin
    rgba = _COLORS['unknown'] if not math.isfinite(margin) else \
        _COLORS['positive' if margin >= 0.0 else 'negative']
    c = 0.6 * style.com_diameter
    z = z0 + _REGION_STEP * (len(_REGION_ORDER) + 1)
    out.add('com_projection', 0, Marker.SPHERE, rgba, position=np.array([0.0, 0.0, z]),
            scale=(c, c, c))
    parts = []
    for name in reversed(_REGION_ORDER):
        r = regions[name]
        value = 'n/a' if r is None else 'empty' if r.is_empty else f'{r.margin:+.3f}'
        parts.append(f'{name.split("_")[0]} {value}')
    out.add('region_margins', 0, Marker.TEXT_VIEW_FACING, rgba,
            position=np.array([0.0, 0.0, z + style.text_height]),
            scale=(0.0, 0.0, 0.8 * style.text_height),
            text='CoM region margins [m]: ' + ', '.join(parts))


def _margin_texts(out: _Builder, lines, style: MarkerStyle, status_text: str) -> None:
    """Add one TEXT_VIEW_FACING per margin above the CoM, coloured by its sign."""
    h = style.text_height
    top = 0.45
    for i, (name, r) in enumerate(lines):
        if r is None or not math.isfinite(r.margin):
            text, rgba = f'{name} margin: n/a', _COLORS['unknown']
        else:
            inside = r.feasible
            text = f'{name} margin {r.margin:+.1f} (dim {r.dimension})'
            rgba = _COLORS['positive' if inside else 'negative']
        out.add('margins', i, Marker.TEXT_VIEW_FACING, rgba,
                position=np.array([0.0, 0.0, top - 1.4 * h * i]), scale=(0.0, 0.0, h),
                text=text)
    if status_text:
        out.add('margins', len(lines), Marker.TEXT_VIEW_FACING, _COLORS['unknown'],
                position=np.array([0.0, 0.0, top - 1.4 * h * len(lines)]),
                scale=(0.0, 0.0, 0.8 * h), text=status_text[:200])


def error_markers(header: Header, reason: str, *, style: MarkerStyle = MarkerStyle()
                  ) -> MarkerArray:
    """Return the markers of a message that was not evaluated: a red text with the reason."""
    out = _Builder(header, np.eye(3), np.zeros(3))
    out.add('margins', 0, Marker.TEXT_VIEW_FACING, _COLORS['negative'],
            position=np.array([0.0, 0.0, 0.45]), scale=(0.0, 0.0, style.text_height),
            text=f'not evaluated: {reason[:200]}')
    return MarkerArray(markers=out.markers)
