"""
Run a command on this machine made slower: a real-time thread steals a share of every CPU.

::

    python -m awp_ros.soak.slow_machine --steal 0.4 -- python -m awp_ros.soak --rate 1000

Machines of the 2-core kind awp_ros targets differ in speed by up to 2x, and a node that
keeps up on a fast one may not on a slow one. This tool emulates the slow one on the fast
one: on each CPU this process may use (``os.sched_getaffinity``) it starts a *stealer*, a
process pinned to that CPU at real-time priority (``SCHED_FIFO``), busy for ``steal`` of
every ``period`` (0.2 ms) and asleep for the rest. Every other thread on that CPU then gets
at most ``1 - steal`` of its time, in slices of ``(1 - steal) period``: a machine
``1 / (1 - steal)`` times slower in throughput, a little more with the extra context
switches. The factor is measured, not assumed: before the command runs, a reference workload
(small numpy operations in a Python loop, the kind of work the node does) is timed without
and with the stealers, and the ratio is printed with both times.

What it does not emulate: a slow CPU is slow at every instant, the stealers only take turns,
so a computation shorter than a slice may still finish at full speed (a median per-call
time of ``awp_bench`` moves less than its long calls; latencies gain up to
``steal * period``). Memory and cache speed are this machine's.

Needs the right to use ``SCHED_FIFO`` (root, or ``CAP_SYS_NICE``; the kernel still keeps
5 % of each second for other tasks, ``/proc/sys/kernel/sched_rt_runtime_us``). A stealer
exits with its parent, and after ``max_seconds`` in any case.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import os
import subprocess
import sys
import time

import numpy as np

from awp_ros.errors import InputError, ProcessError

__all__ = ['Calibration', 'main', 'reference_workload_ms', 'SlowMachine', 'steal_cpu']

#: Stealer period [s]: short enough that every slice is short against a 1 ms cycle.
PERIOD_S = 2e-4
#: Real-time priority of the stealers (SCHED_FIFO, 1-99): above every normal thread.
PRIORITY = 50
#: Exit code of a stealer refused real-time priority.
NO_PERMISSION = 3


def steal_cpu(cpu: int, steal: float, period_s: float = PERIOD_S,
              max_seconds: float = 3600.0) -> None:
    """
    Be a stealer: on ``cpu``, at real-time priority, busy ``steal`` of every ``period_s``.

    Prints ``ready`` once at real-time priority. Returns after ``max_seconds``, or when the
    parent process changes (it died). Raises ``PermissionError`` if real-time priority is
    refused.
    """
    os.sched_setaffinity(0, {cpu})
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
    print('ready', flush=True)
    parent = os.getppid()
    busy = steal * period_s
    t = start = time.perf_counter()
    n = 0
    while True:
        end = t + busy
        while time.perf_counter() < end:
            pass
        t += period_s
        now = time.perf_counter()
        if t > now:
            time.sleep(t - now)
        else:                           # preempted (another real-time task): no catch-up
            t = now
        n += 1
        if n % 256 == 0 and (os.getppid() != parent or now - start > max_seconds):
            return


def reference_workload_ms(repeats: int = 5) -> float:
    """
    Return the shortest of ``repeats`` timings [ms] of a fixed workload like the node's.

    About 20 ms on a fast machine: 9000 passes of small numpy operations (a 6x6 product, a
    norm, a comparison) and Python-level arithmetic, the mix of the node's per-cycle code.
    """
    rng = np.random.default_rng(0)
    A, x = rng.standard_normal((6, 6)), rng.standard_normal(6)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        acc = 0.0
        for i in range(9000):
            y = A @ x
            acc += float(np.sqrt(y @ y)) + (i % 7) * 0.5
            if y.max() > 1e9:
                acc = 0.0
        best = min(best, time.perf_counter() - t0)
    return 1e3 * best


@dataclass
class Calibration:
    """The reference workload's time [ms] without and with the stealers, and their ratio."""

    fast_ms: float
    slow_ms: float

    @property
    def slowdown(self) -> float:
        """How many times slower the machine is with the stealers (measured)."""
        return self.slow_ms / self.fast_ms


class SlowMachine:
    """
    Stealers on the given CPUs while the context is entered (see the module docstring).

    ``with SlowMachine(0.4) as slow: ...``; ``slow.calibration`` holds the measured slowdown
    (measured on entry unless ``calibrate`` is False).
    """

    def __init__(self, steal: float, *, cpus: set[int] | None = None,
                 period_s: float = PERIOD_S, calibrate: bool = True,
                 max_seconds: float = 3600.0):
        if not 0.0 < steal <= 0.8:
            raise InputError(f'steal={steal!r}: the share of each CPU to take must be in '
                             '(0, 0.8]; 0.5 halves the machine')
        if not 2e-5 <= period_s <= 0.01:
            raise InputError(f'period_s={period_s!r} must be in [2e-5, 0.01] s')
        self.steal, self.period_s, self.calibrate = steal, period_s, calibrate
        self.cpus = sorted(os.sched_getaffinity(0) if cpus is None else cpus)
        self.max_seconds = max_seconds
        self.calibration: Calibration | None = None
        self._procs: list[subprocess.Popen] = []
        self._fast_ms: float | None = None

    def measure_fast(self) -> float:
        """
        Time the reference workload without the stealers now, for the calibration [ms].

        Call it while the machine is quiet (the soak: before the node starts): measured in
        :meth:`start`, beside a node loading its kernels, it came out up to 1.6x long (34 ms
        against 21), and the slowdown as much too small.
        """
        self._fast_ms = reference_workload_ms()
        return self._fast_ms

    def confirm_fast(self) -> float:
        """
        Time the reference again without the stealers; the calibration keeps the shorter [ms].

        Call it once the stealers (and the soak's node) are gone. The reference is the quiet
        machine's speed, but one quiet moment is not enough: timed before the node started,
        while a previous test's processes still ran, it came out 33.4 ms against 21 in a CI
        run (the slowdown 1.21x). Of two timings a whole soak apart, the shorter is the quiet
        one. Returns this timing.
        """
        fast = reference_workload_ms()
        c = self.calibration
        if c is not None:
            self.calibration = Calibration(min(c.fast_ms, fast), c.slow_ms)
        return fast

    def start(self) -> None:
        """Start one stealer per CPU; raise ProcessError if one cannot run (permission)."""
        fast = float('nan')
        if self.calibrate:
            fast = self._fast_ms if self._fast_ms is not None else reference_workload_ms()
        for cpu in self.cpus:
            cmd = [sys.executable, '-m', 'awp_ros.soak.slow_machine', '--stealer', str(cpu),
                   '--steal', repr(self.steal), '--period', repr(self.period_s),
                   '--max-seconds', repr(self.max_seconds)]
            self._procs.append(subprocess.Popen(cmd, stdout=subprocess.PIPE,
                                                stderr=subprocess.PIPE, text=True))
        for proc in self._procs:            # 'ready' once at real-time priority
            if proc.stdout.readline().strip() != 'ready':
                proc.wait()
                err = proc.stderr.read().strip()
                self.stop()
                raise ProcessError(f'a stealer could not run (exit {proc.returncode}): {err}')
        if self.calibrate:
            self.calibration = Calibration(fast, reference_workload_ms())

    def stop(self) -> None:
        """Stop the stealers."""
        for proc in self._procs:
            if proc.poll() is None:
                proc.terminate()
        for proc in self._procs:
            try:
                proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            for stream in (proc.stdout, proc.stderr):
                if stream is not None:
                    stream.close()
        self._procs = []

    def __enter__(self) -> 'SlowMachine':
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def summary(self) -> dict:
        """Return the settings and the measured slowdown as JSON-ready builtins."""
        c = self.calibration or Calibration(float('nan'), float('nan'))
        return {'steal': self.steal, 'period_s': self.period_s,
                'slowdown': round(c.slowdown, 3), 'fast_ms': round(c.fast_ms, 3),
                'slow_ms': round(c.slow_ms, 3)}

    def describe(self) -> str:
        """Return one line: the stealers and, once measured, the slowdown."""
        text = (f'slow_machine: on CPUs {self.cpus}, a SCHED_FIFO stealer busy '
                f'{1e3 * self.steal * self.period_s:.3f} ms of every '
                f'{1e3 * self.period_s:.3f} ms')
        if self.calibration is not None:
            c = self.calibration
            text += (f'; reference workload {c.fast_ms:.1f} ms -> {c.slow_ms:.1f} ms: '
                     f'{c.slowdown:.2f}x slower')
        return text


def main(argv: list[str] | None = None) -> int:
    """Run a command under :class:`SlowMachine` (or, with ``--stealer``, be a stealer)."""
    parser = argparse.ArgumentParser(
        prog='python -m awp_ros.soak.slow_machine', description=__doc__.split('\n\n')[0],
        epilog='example: python -m awp_ros.soak.slow_machine --steal 0.4 -- '
        'python -m awp_ros.cli.bench -n 100')
    parser.add_argument('--steal', type=float, default=0.4,
                        help='share of each CPU taken (default 0.4: about 2x slower here)')
    parser.add_argument('--period', type=float, default=PERIOD_S,
                        help=f'stealer period [s] (default {PERIOD_S})')
    parser.add_argument('--max-seconds', type=float, default=3600.0,
                        help='the stealers stop after this long in any case [s]')
    parser.add_argument('--stealer', type=int, metavar='CPU', help=argparse.SUPPRESS)
    parser.add_argument('command', nargs=argparse.REMAINDER,
                        help='the command to run (after --)')
    args = parser.parse_args(argv)
    if args.stealer is not None:
        try:
            steal_cpu(args.stealer, args.steal, args.period, args.max_seconds)
        except PermissionError as exc:
            print(f'real-time priority (SCHED_FIFO) refused: {exc}; the stealers need root '
                  'or CAP_SYS_NICE', file=sys.stderr)
            return NO_PERMISSION
        return 0
    command = args.command[1:] if args.command[:1] == ['--'] else args.command
    if not command:
        parser.error('give the command to run after --')
    try:
        slow = SlowMachine(args.steal, period_s=args.period, max_seconds=args.max_seconds)
        slow.start()
    except (InputError, ProcessError) as exc:
        print(f'slow_machine: {exc}', file=sys.stderr)
        return 2
    try:
        print(slow.describe(), flush=True)
        return subprocess.call(command)
    finally:
        slow.stop()


if __name__ == '__main__':
    sys.exit(main())
