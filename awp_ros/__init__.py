"""awp_ros: actuation-consistent and feasible wrench polytopes of legged robots.

The core (every module but ``node``, ``replay*`` and ``demo``) is ROS-free: it needs numpy,
scipy and Pinocchio only.
"""

from __future__ import annotations

from .errors import AwpError, BagError, ConfigError, GeometryError, InputError, ModelError
from .polytope import Polytope

__version__ = '0.1.0'

__all__ = [
    'AwpError',
    'BagError',
    'ConfigError',
    'GeometryError',
    'InputError',
    'ModelError',
    'Polytope',
    '__version__',
]
