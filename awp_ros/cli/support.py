"""
Plumbing shared by the command-line programs (``awp_replay``, ``awp_demo``, the gait script).

- :func:`run_main`: run a program's body and turn the package's errors into one line on
  stderr and an exit status (2 bad input, 1 internal failure, 130 Ctrl-C).
"""

from __future__ import annotations

from collections.abc import Callable
import sys

from awp_ros.errors import AwpError

__all__ = ['run_main']


def run_main(prog: str, body: Callable[[], int], *, interrupted: str = 'interrupted',
             failures: tuple[type[AwpError], ...] = ()) -> int:
    """
    Return ``body()``, or an exit status after writing ``PROG: ...`` to stderr.

    :param prog: the program name that starts the message.
    :param interrupted: the message on Ctrl-C (status 130).
    :param failures: :class:`~awp_ros.errors.AwpError` subclasses that are internal
        failures (status 1); every other ``AwpError`` is bad input (status 2).
    """
    try:
        return body()
    except AwpError as exc:
        sys.stderr.write(f'{prog}: error: {exc}\n')
        return 1 if isinstance(exc, failures) else 2
    except KeyboardInterrupt:
        sys.stderr.write(f'{prog}: {interrupted}\n')
        return 130
