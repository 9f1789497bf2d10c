"""
Polytope geometry, ROS-free: H/V-representations, exact Minkowski-sum facets, margins.

- :mod:`polytope`: the Polytope value (vertices, H-rep A x <= b with unit rows, affine hull).
- :mod:`linalg`: spans, ranks, hyperplane normals, subset trees (the numerics every module shares).
- :mod:`exterior`: exterior products (generalised cross products) of small vector sets.
- :mod:`face_lattice`: faces of a 3D polytope, grouped by dimension.
- :mod:`zonotope`: H-rep of a zonotope (a sum of segments), e.g. the AWP of 3-joint legs.
- :mod:`minkowski_facets`: facet normals of a sum of lifted polytopes from face combinations.
- :mod:`certified_search`: their most frequent search along a stream, skipping certified choices.
- :mod:`margin`: signed Euclidean margin of a point to a polytope, and directional margins.
- :mod:`lp`: the Chebyshev-ball LP (the one LP helper).
- :mod:`mesh`: triangle meshes and force slices of polytopes, for drawing.
- :mod:`iterative_projection`: Bretl & Lall iterative projection (a baseline).
- :mod:`kernels`: compiled (numba) kernels of the per-cycle sets, numpy code their reference.
- :mod:`steps`: long computations as generators, run whole or a piece at a time.
"""

__all__ = ['polytope', 'linalg', 'exterior', 'face_lattice', 'zonotope', 'minkowski_facets',
           'certified_search', 'margin', 'lp', 'mesh', 'iterative_projection', 'kernels', 'steps']
