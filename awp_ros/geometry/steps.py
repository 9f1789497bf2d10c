"""
Long computations in steps: generators that yield between bounded pieces of work.

A computation written as a generator (``yield`` between pieces, ``return`` its value) runs
whole with :func:`run_steps`, or a piece at a time (``next``) by a caller with other work
between the pieces: the node computes the FWS so, in the idle time of its joint-state loop
(:class:`awp_ros.ros.pipeline.InlineFws`), instead of stalling the stream by the whole
computation. The pieces are the same either way, and so are the results.
"""

from __future__ import annotations

from collections.abc import Generator
import time
from typing import TypeVar

__all__ = ['run_steps', 'timed_steps']

T = TypeVar('T')


def run_steps(steps: Generator[None, None, T]) -> T:
    """Run a stepped computation to its end and return its value."""
    try:
        while True:
            next(steps)
    except StopIteration as stop:
        return stop.value


def timed_steps(steps: Generator[None, None, T]) -> Generator[None, None, tuple[T, float]]:
    """
    Step ``steps`` through, yielding between its pieces; return ``(value, seconds in it)``.

    The time is that spent in the pieces (wall time, ``time.perf_counter``), not between
    them: ``value, seconds = yield from timed_steps(g)``.
    """
    spent = 0.0
    while True:
        t0 = time.perf_counter()
        try:
            next(steps)
        except StopIteration as stop:
            return stop.value, spent + time.perf_counter() - t0
        spent += time.perf_counter() - t0
        yield
