"""
Start and stop ``awp_node`` as its own process (the soak test and the node tests).

:func:`ros_env` keeps discovery on this machine and sets the ROS domain;
:func:`start_node` runs the console script with parameters, its output going to a log
file that :func:`stop_node` returns.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile

__all__ = ['node_command', 'ros_env', 'start_node', 'stop_node']


def node_command() -> list[str]:
    """
    Return the command of ``awp_node``.

    The console script beside this interpreter, else the one on PATH, else
    ``python -m awp_ros.node.node``.
    """
    beside = Path(sys.executable).parent / 'awp_node'
    if beside.is_file():
        return [str(beside)]
    found = shutil.which('awp_node')
    return [found] if found else [sys.executable, '-m', 'awp_ros.node.node']


def ros_env(domain_id: int | None = None) -> dict[str, str]:
    """Return ``os.environ`` with discovery on this machine (unless set) and ``domain_id``."""
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if domain_id is not None:
        env['ROS_DOMAIN_ID'] = str(domain_id)
    env['PYTHONUNBUFFERED'] = '1'
    return env


def start_node(*, env: dict[str, str] | None = None, robot: str | None = 'hyq',
               namespace: str = '', params_file: str | os.PathLike | None = None,
               params: dict | None = None, ros_args: tuple[str, ...] = (),
               command: list[str] | None = None, log_path: str | os.PathLike | None = None,
               new_session: bool = False) -> subprocess.Popen:
    """
    Start ``awp_node`` as its own process.

    :param env: the environment (see :func:`ros_env`; default ``os.environ``).
    :param robot: the ``robot`` parameter (config name or YAML path); None leaves it out.
    :param namespace: the node's namespace (``-r __ns:=...``), '' = root.
    :param params_file: a parameters file (``--params-file``).
    :param params: more parameters, ``{name: value}`` (values as ``-p name:=value`` text;
        lists and strings as YAML).
    :param ros_args: more ``--ros-args`` arguments.
    :param command: the node's command (default :func:`node_command`), e.g.
        ``['ros2', 'run', 'awp_ros', 'awp_node']``.
    :param log_path: file receiving the node's stdout and stderr (default a temporary
        file; ``proc.log_path`` holds it). A file, not a pipe: a pipe nobody reads would
        block a node that logs a lot.
    :param new_session: start the node in a process group of its own, so that
        :func:`stop_node` signals the whole group (a ``ros2 run`` wrapper and its child)
        and a Ctrl-C in the terminal reaches only the caller.
    :return: the process (``proc.log_path`` set).
    """
    args = []
    if params_file is not None:
        args += ['--params-file', str(params_file)]
    if robot is not None:
        args += ['-p', f'robot:={robot}']
    for name, value in (params or {}).items():
        text = json.dumps(value) if isinstance(value, (list, bool)) else str(value)
        args += ['-p', f'{name}:={text}']
    if namespace:
        args += ['-r', f'__ns:={namespace}']
    temporary = log_path is None
    if temporary:
        fd, log_path = tempfile.mkstemp(prefix='awp_node_', suffix='.log')
        os.close(fd)
    log = open(log_path, 'w')  # noqa: SIM115 -- handed to the child, closed below
    try:
        proc = subprocess.Popen((command or node_command()) + ['--ros-args', *args, *ros_args],
                                env=env, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=new_session)
    finally:
        log.close()
    proc.log_path = str(log_path)
    proc.log_is_temporary = temporary
    proc.new_session = new_session
    return proc


def stop_node(proc: subprocess.Popen, timeout_s: float = 10.0) -> str:
    """
    Stop a node started by :func:`start_node`; return its log.

    SIGINT, then SIGTERM, then SIGKILL, each after ``timeout_s`` [s] without exit (to the
    whole process group when started with ``new_session``); a temporary log is removed.
    """
    group = getattr(proc, 'new_session', False)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if proc.poll() is not None:
            break
        try:
            if group:
                os.killpg(proc.pid, sig)
            else:
                proc.send_signal(sig)
        except ProcessLookupError:
            break
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            continue
    path = getattr(proc, 'log_path', None)
    if not path:
        return ''
    text = Path(path).read_text(errors='replace')
    if getattr(proc, 'log_is_temporary', False):
        Path(path).unlink(missing_ok=True)
    return text
