"""
awp_demo: the node fed the default bag, a live table, a bag and a PNG.

- :mod:`demo`: main() of awp_demo.
- :mod:`recorder`: recording a running node into a bag.
- :mod:`table`: the live table.
- :mod:`plot`: the margins PNG.
- :mod:`render_markers`: a MarkerArray rendered to a PNG with matplotlib.
"""

__all__ = ['demo', 'recorder', 'table', 'plot', 'render_markers']
