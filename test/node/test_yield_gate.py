"""The gate by which the node pauses the query computation, on real processes (yield_gate)."""

from __future__ import annotations

import mmap
import os
from pathlib import Path
import subprocess
import sys
import time

import pytest

from awp_ros.node.yield_gate import YieldGate
from awp_ros.soak.probe import wait_until

pytestmark = pytest.mark.skipif(not sys.platform.startswith('linux'),
                                reason='SIGSTOP and /proc are Linux')

# A worker: registers with the gate, then counts in its own page, busy (or not) per argv[3].
WORKER = """
import mmap, os, sys, contextlib
from awp_ros.node.yield_gate import YieldGate
gate = YieldGate.attach(sys.argv[1])
fd = os.open(sys.argv[2], os.O_RDWR)
count = memoryview(mmap.mmap(fd, 8)).cast('q')
with gate.busy() if sys.argv[3] == 'busy' else contextlib.nullcontext():
    while True:
        count[0] += 1
"""


def _state(pid: int) -> str:
    """Return the process state letter of /proc/<pid>/stat (R, S, T, ...)."""
    text = Path(f'/proc/{pid}/stat').read_text()
    return text[text.rindex(')') + 2]


@pytest.fixture
def worker(tmp_path):
    started = []

    def start(mode: str):
        gate = YieldGate.create()
        page = tmp_path / f'count_{len(started)}'
        page.write_bytes(bytes(8))
        proc = subprocess.Popen([sys.executable, '-c', WORKER, gate.path, str(page), mode])
        started.append((gate, proc))
        fd = os.open(page, os.O_RDWR)
        count = memoryview(mmap.mmap(fd, 8)).cast('q')
        os.close(fd)
        wait_until(lambda: count[0] > 0, 30.0, 'the worker counting')
        return gate, proc, count

    yield start
    for gate, proc in started:
        gate.close()
        proc.kill()
        proc.wait(5)


def test_a_busy_worker_makes_no_progress_while_paused_and_goes_on_after(worker):
    gate, proc, count = worker('busy')
    for _ in range(3):
        gate.pause()
        wait_until(lambda: _state(proc.pid) == 'T', 2.0, 'the worker stopped')
        first = count[0]
        time.sleep(0.2)
        assert count[0] == first and _state(proc.pid) == 'T'
        gate.resume()
        time.sleep(0.2)
        assert count[0] > first and _state(proc.pid) != 'T'
    assert gate.pauses == 3


def test_an_idle_worker_is_not_touched(worker):
    gate, proc, count = worker('idle')
    gate.pause()
    first = count[0]
    time.sleep(0.2)
    assert count[0] > first and _state(proc.pid) != 'T'
    gate.resume()
    assert gate.pauses == 0


def test_close_continues_a_paused_worker_and_removes_the_page(worker):
    gate, proc, count = worker('busy')
    gate.pause()
    wait_until(lambda: _state(proc.pid) == 'T', 2.0, 'the worker stopped')
    path = gate.path
    gate.close()
    first = count[0]
    time.sleep(0.2)
    assert count[0] > first and not os.path.exists(path)


def test_a_busy_stretch_is_one_stop_and_one_resume_continues_it(worker):
    # The node pauses at every joint state of a busy stretch and resumes once at its end.
    gate, proc, count = worker('busy')
    for _ in range(20):
        gate.pause()
    wait_until(lambda: _state(proc.pid) == 'T', 2.0, 'the worker stopped')
    assert gate.pauses == 1
    gate.resume()
    first = count[0]
    time.sleep(0.2)
    assert count[0] > first


def test_a_gate_whose_worker_is_gone_is_a_no_op(worker):
    gate, proc, count = worker('busy')
    proc.kill()
    proc.wait(5)
    gate.pause()                # no error: the service restarts its worker
    gate.resume()
    assert gate.pauses == 0
