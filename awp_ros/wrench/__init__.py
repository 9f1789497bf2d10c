"""
Wrench sets of a legged robot (ROS-free): the seed paper's sets and the FWS.

- :mod:`force_polytope`: per-leg force polytope from joint-torque limits, seed eq. (1).
- :mod:`friction_polytope`: force polytope cut by the friction pyramid (and n.f >= 0).
- :mod:`contact_wrench_cone`: friction pyramids, their lifts, the CWC H-rep.
- :mod:`wrench_polytope`: lifts [f; p x f], the AWP (seed eq. 3) and FWP = AWP n CWC.
- :mod:`feasible_wrench_set`: the FWS, sum of lifted friction-bounded leg polytopes.
- :mod:`fws_queries`: FWS membership and directional margins by exact LPs.
- :mod:`contact_forces`: measured contact forces from joint efforts, slip margins, external wrench.
- :mod:`com_region`: CoM regions (feasible, support, FWP region): exact slices of the sets.
"""

__all__ = ['force_polytope', 'friction_polytope', 'contact_wrench_cone', 'wrench_polytope',
           'feasible_wrench_set', 'fws_queries', 'contact_forces', 'com_region']
