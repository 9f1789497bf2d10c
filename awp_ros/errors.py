"""
Exception classes of awp_ros, one per area (the rosbags pattern).

Every error raised on purpose by the package derives from :class:`AwpError`.
Errors caused by what the caller passed also derive from :class:`ValueError`,
so ``except ValueError`` keeps working for users who do not know this module.
"""

from __future__ import annotations

__all__ = [
    'AwpError',
    'ConfigError',
    'InputError',
    'ModelError',
    'GeometryError',
    'BagError',
    'ProcessError',
]


class AwpError(Exception):
    """Base class of every error raised by awp_ros."""


class InputError(AwpError, ValueError):
    """A robot state or message is invalid (NaN, unknown joint or foot, bad shape)."""


class ConfigError(AwpError, ValueError):
    """A robot configuration (YAML, parameter, URDF) is missing or invalid."""


class ModelError(AwpError):
    """The robot model cannot be built or evaluated (Pinocchio, URDF)."""


class GeometryError(AwpError):
    """A polytope computation failed in a way that is not the caller's fault."""


class BagError(AwpError, ValueError):
    """A rosbag2 file is unreadable, truncated, or lacks a needed topic or type."""


class ProcessError(AwpError):
    """A process the package started (``awp_node``, a soak driver) failed or did not answer."""
