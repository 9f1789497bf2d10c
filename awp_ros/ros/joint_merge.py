"""
Merging ``sensor_msgs/JointState`` messages that carry subsets of the joints.

A robot may publish its joint states from several publishers (legs and arm, one per leg, a
wheel driver), each message naming only its joints, and may name joints the model does not
have (an arm, wheels, a gripper). :class:`JointMerger` keeps each model joint's latest
position, velocity and effort with the stamp of the message that carried it, in arrays in
the model's joint order, preallocated; a joint state is evaluated with those latest values
when every model joint has one stamped at most ``timeout_s`` before it. Velocities (efforts)
are used when every joint's latest value came with one.

Per message the work is one dictionary lookup of its name tuple (the layout of a name list
is computed once: which entries are model joints, where they go, which are extra) and a
few numpy copies; no Python loop over the joints.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence

import numpy as np

from awp_ros.errors import InputError

__all__ = ['JointMerger', 'MergedJoints']

_NEVER = np.iinfo(np.int64).min
_MAX_LAYOUTS = 256          # distinct name lists remembered (a pathological input: cleared)


def _shorten(items: Sequence, limit: int = 8) -> str:
    """Return ``repr(list(items))``, eliding entries after the first ``limit``."""
    items = list(items)
    if len(items) <= limit:
        return repr(items)
    return repr(items[:limit])[:-1] + f', ... ({len(items) - limit} more)]'


class MergedJoints:
    """
    The merged joint state, in the model's joint order (what a JointState carries).

    ``name`` the model's joints; ``position`` [rad or m]; ``velocity`` [rad/s] and
    ``effort`` [N.m] empty when not every joint's latest value came with one. The arrays
    are the merger's buffers: read them before the next :meth:`JointMerger.add`.
    """

    __slots__ = ('name', 'position', 'velocity', 'effort')

    def __init__(self, name: list[str], position: np.ndarray, velocity: np.ndarray,
                 effort: np.ndarray) -> None:
        self.name = name
        self.position = position
        self.velocity = velocity
        self.effort = effort


class _Layout:
    """Where the entries of one name list go: model indices, and the extra names."""

    __slots__ = ('src', 'dst', 'full', 'identity', 'extra')

    def __init__(self, src: np.ndarray, dst: np.ndarray, full: bool, identity: bool,
                 extra: tuple[str, ...]) -> None:
        self.src = src
        self.dst = dst
        self.full = full
        self.identity = identity
        self.extra = extra


class JointMerger:
    """
    The latest value of every model joint, from joint states carrying any subset of them.

    :param joint_names: the model's joints, in q order.
    :param timeout_s: a joint state is complete when every joint has a value stamped at
        most this long before it [s]; 0 = any age.
    :param ignored: joints the model does not have that are expected (not listed in
        :attr:`extra`).
    :ivar extra: joints seen in messages that the model does not have and ``ignored`` does
        not list (the node lists them once in ``/diagnostics``).
    """

    def __init__(self, joint_names: Sequence[str], *, timeout_s: float = 0.1,
                 ignored: Collection[str] = ()) -> None:
        self.names = list(joint_names)
        self._index = {name: i for i, name in enumerate(self.names)}
        n = len(self.names)
        self.timeout_ns = int(round(timeout_s * 1e9))
        self.ignored = frozenset(ignored)
        self.extra: set[str] = set()
        self.position = np.zeros(n)
        self.velocity = np.zeros(n)
        self.effort = np.zeros(n)
        self.stamp = np.full(n, _NEVER, dtype=np.int64)
        self.velocity_stamp = np.full(n, _NEVER, dtype=np.int64)
        self.effort_stamp = np.full(n, _NEVER, dtype=np.int64)
        self._layouts: dict[tuple[str, ...], _Layout] = {}
        self._empty = np.zeros(0)

    def _layout(self, names: tuple[str, ...]) -> _Layout:
        """Return (and remember) the layout of a name list; InputError for duplicates."""
        layout = self._layouts.get(names)
        if layout is not None:
            return layout
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise InputError(f'joint_states names joints twice: {_shorten(dup)}')
        index = self._index
        pairs = [(i, index[name]) for i, name in enumerate(names) if name in index]
        src = np.array([i for i, _ in pairs], dtype=np.intp)
        dst = np.array([j for _, j in pairs], dtype=np.intp)
        full = len(pairs) == len(self.names)
        identity = full and len(names) == len(self.names) and bool(np.all(src == dst))
        extra = tuple(n for n in names if n not in index and n not in self.ignored)
        if len(self._layouts) >= _MAX_LAYOUTS:
            self._layouts.clear()
        layout = self._layouts[names] = _Layout(src, dst, full, identity, extra)
        return layout

    def is_full(self, names: Sequence[str]) -> bool:
        """Return whether a name list holds every model joint (False for duplicates)."""
        try:
            return self._layout(tuple(names)).full
        except InputError:
            return False

    def add(self, msg, ns: int) -> MergedJoints | str:
        """
        Take one joint-state message stamped ``ns`` [ns]; return the merged state or why not.

        :param msg: ``name``, ``position`` (one per name), ``velocity`` and ``effort`` (one
            per name, or empty) of a ``sensor_msgs/JointState``.
        :return: the merged state, or the reason the state is not complete (joints without
            a value yet, or whose latest value is older than the timeout).
        :raises InputError: array lengths that do not match the names, duplicate names.
        """
        names = tuple(msg.name)
        k = len(names)
        if len(msg.position) != k:
            raise InputError(f'joint_states has {k} names but {len(msg.position)} positions')
        nv, ne = len(msg.velocity), len(msg.effort)
        if nv not in (0, k):
            raise InputError(f'joint_states has {k} names but {nv} velocities')
        if ne not in (0, k):
            raise InputError(f'joint_states has {k} names but {ne} efforts')
        layout = self._layout(names)
        if layout.extra and not self.extra.issuperset(layout.extra):
            self.extra.update(layout.extra)
        src, dst = layout.src, layout.dst
        if layout.identity:
            self.position[:] = msg.position
            self.stamp[:] = ns
            if nv:
                self.velocity[:] = msg.velocity
                self.velocity_stamp[:] = ns
            if ne:
                self.effort[:] = msg.effort
                self.effort_stamp[:] = ns
        elif dst.size:
            self.position[dst] = np.asarray(msg.position, dtype=float)[src]
            self.stamp[dst] = ns
            if nv:
                self.velocity[dst] = np.asarray(msg.velocity, dtype=float)[src]
                self.velocity_stamp[dst] = ns
            if ne:
                self.effort[dst] = np.asarray(msg.effort, dtype=float)[src]
                self.effort_stamp[dst] = ns
        if layout.full:          # every joint in this message: complete, this message's values
            return MergedJoints(self.names, self.position,
                                self.velocity if nv else self._empty,
                                self.effort if ne else self._empty)
        reason = self._incomplete(ns)
        if reason:
            return reason
        stamp = self.stamp
        velocity = self.velocity if np.array_equal(self.velocity_stamp, stamp) \
            else self._empty
        effort = self.effort if np.array_equal(self.effort_stamp, stamp) else self._empty
        return MergedJoints(self.names, self.position, velocity, effort)

    def _incomplete(self, ns: int) -> str:
        """Return why the merged state at ``ns`` is not complete, or ''."""
        never = self.stamp == _NEVER
        if never.any():
            missing = [self.names[i] for i in np.flatnonzero(never).tolist()]
            return (f'joint_states: no message has named joints {_shorten(missing)} yet '
                    '(messages carrying subsets of the joints are merged)')
        if self.timeout_ns > 0:
            old = self.stamp < ns - self.timeout_ns
            if old.any():
                idx = np.flatnonzero(old).tolist()
                age = (ns - int(self.stamp[idx].min())) * 1e-9
                return (f'joint_states: joints {_shorten([self.names[i] for i in idx])} were '
                        f'last received up to {age:.3f} s before this joint state '
                        f'(joint_states_timeout_s {self.timeout_ns * 1e-9:g})')
        return ''

    def clear(self) -> None:
        """Forget every value (a new robot model, or stamps that went back)."""
        for a in (self.stamp, self.velocity_stamp, self.effort_stamp):
            a[:] = _NEVER
