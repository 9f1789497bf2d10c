"""Plumbing shared by the command-line programs (``awp_replay``, ``awp_demo``, the gait script).

- :func:`run_main`: run a program's body and turn the package's errors into one line on
  stderr and an exit status (2 bad input, 1 internal failure, 130 Ctrl-C).
- :func:`find_config_file`: the first ``<name>`` in the config folders of
  :func:`awp_ros.robot_config.config_dirs` (installed share folder first, then the source
  tree).
- :func:`remove_path`: clear an old output (file or rosbag2 directory) before rewriting it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
import shutil
import sys

from awp_ros.errors import AwpError

__all__ = ['run_main', 'find_config_file', 'remove_path']


def run_main(prog: str, body: Callable[[], int], *, interrupted: str = 'interrupted',
             failures: tuple[type[AwpError], ...] = ()) -> int:
    """Return ``body()``, or an exit status after writing ``PROG: ...`` to stderr.

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


def find_config_file(name: str) -> Path | None:
    """Return the first ``<config dir>/<name>`` that is a file, or None."""
    from awp_ros.robot_config import config_dirs

    for d in config_dirs():
        if (d / name).is_file():
            return d / name
    return None


def remove_path(path: Path) -> None:
    """Remove ``path`` if it exists: a directory with its contents, or a file."""
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()
