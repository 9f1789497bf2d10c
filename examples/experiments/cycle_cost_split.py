"""
Split the per-cycle evaluation's time: compiled kernels, Pinocchio, and the Python between them.

::

    PYTHONPATH=. .venv/bin/python examples/experiments/cycle_cost_split.py [--postures 200]

The measurement behind the README's "Speed: awp_bench" paragraph on where the per-cycle time
goes. Over ``--postures`` random HyQ postures (seed 0, joints +-0.1 rad around standing, four
stance legs, as ``awp_bench``), ``FeasibilityEvaluator.evaluate(state, fws=False)`` is run in a
loop (one pass to warm up, then ``--passes`` timed passes):

- ``loop``: the mean wall time of one evaluation, nothing wrapped;
- ``in the loop``: every compiled kernel of :mod:`awp_ros.geometry.kernels` and every
  Pinocchio function the model stage calls, wrapped by a timer (about 0.2 us each), summed per
  evaluation over the same loop; their arguments are recorded;
- ``isolated``: each of them called again on its recorded arguments, the calls of all postures
  in a row (the best of ``--passes`` passes): the same work with its code and data hot;
- ``in order``: all recorded calls replayed back to back in the order the loop made them (the
  kernels of one evaluation after another, without the Python between them), the best of
  ``--passes`` passes.

The rest of ``loop`` (``loop`` minus the wrapped calls in the loop) is Python and numpy between
the kernels: validation, result objects, glue. ``in order`` against ``in the loop`` is what
that Python costs the kernels besides its own time. It prints one line per wrapped function
(mean us per evaluation, in the loop and isolated) and the totals, then one JSON object.
"""

from __future__ import annotations

import argparse
from collections import Counter
import json
import time

import numpy as np
import pinocchio as pin

from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.geometry import kernels
from awp_ros.runtime import tune_process

#: The Pinocchio functions of ``RobotModel.kinematics`` (timed as ``pin.<name>``).
PINOCCHIO = ('rnea', 'centerOfMass', 'computeCentroidalMomentumTimeVariation',
             'computeJointJacobians', 'updateFramePlacements', 'getFrameJacobian')


def postures(evaluator: FeasibilityEvaluator, count: int, seed: int = 0,
             spread: float = 0.1) -> list:
    """Return ``count`` random states around standing (``awp_bench``'s postures)."""
    base = evaluator.standing_state()
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    states = []
    for q in q0 + np.random.default_rng(seed).uniform(-spread, spread, size=(count, q0.size)):
        state = evaluator.standing_state()
        state.joint_positions = dict(zip(names, q.tolist()))
        states.append(state)
    return states


class Recorder:
    """Wrap functions of modules by timers that sum their time and record their arguments."""

    def __init__(self) -> None:
        self.seconds: Counter = Counter()
        self.calls: dict[str, list] = {}
        #: Every recorded call in the order made: ``(function, args, kwargs)``.
        self.sequence: list[tuple] = []
        self._undo: list[tuple] = []
        self.recording = False

    def wrap(self, module, name: str, label: str) -> None:
        """Replace ``module.name`` by a timed, recording wrapper (undone by :meth:`restore`)."""
        function = getattr(module, name)
        self._undo.append((module, name, function))
        calls = self.calls.setdefault(label, [])
        seconds, clock = self.seconds, time.perf_counter

        def timed(*args, **kwargs):
            t0 = clock()
            out = function(*args, **kwargs)
            seconds[label] += clock() - t0
            if self.recording:
                calls.append((function, args, kwargs))
                self.sequence.append(calls[-1])
            return out
        setattr(module, name, timed)

    def restore(self) -> None:
        """Put the original functions back."""
        for module, name, function in reversed(self._undo):
            setattr(module, name, function)
        self._undo.clear()


def replay_us(calls: list, evaluations: int, passes: int) -> float:
    """Return the best time [us] per evaluation of replaying ``calls`` back to back."""
    best = np.inf
    for _ in range(passes):
        t0 = time.perf_counter()
        for function, args, kwargs in calls:
            function(*args, **kwargs)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / evaluations


def split(count: int = 200, passes: int = 5) -> dict:
    """Return the time split of the module docstring over ``count`` postures."""
    evaluator = FeasibilityEvaluator('hyq')
    states = postures(evaluator, count)

    def loop() -> float:
        t0 = time.perf_counter()
        for state in states:
            evaluator.evaluate(state, fws=False)
        return time.perf_counter() - t0
    loop()
    plain = min(loop() for _ in range(passes)) / count
    rec = Recorder()
    for name in dir(kernels):
        if hasattr(getattr(kernels, name), 'py_func'):           # a compiled kernel
            rec.wrap(kernels, name, name)
    for name in PINOCCHIO:
        rec.wrap(pin, name, f'pin.{name}')
    try:
        loop()
        rec.seconds.clear()
        wrapped = sum(loop() for _ in range(passes)) / (passes * count)
        timed = rec.seconds.copy()
        rec.recording = True
        loop()
        rec.recording = False
    finally:
        rec.restore()
    rows = []
    for label, seconds in timed.most_common():
        if seconds > 0.0:
            rows.append({'name': label, 'in_loop_us': 1e6 * seconds / (passes * count),
                         'isolated_us': replay_us(rec.calls[label], count, passes),
                         'calls_per_evaluation': len(rec.calls[label]) / count})
    in_loop = sum(r['in_loop_us'] for r in rows)
    return {'postures': count, 'loop_us': 1e6 * plain, 'wrapped_loop_us': 1e6 * wrapped,
            'calls_in_loop_us': in_loop, 'calls_isolated_us': sum(r['isolated_us'] for r in rows),
            'calls_in_order_us': replay_us(rec.sequence, count, passes),
            'python_us': 1e6 * wrapped - in_loop, 'rows': rows}


def main(argv: list[str] | None = None) -> dict:
    """Print the split (module docstring) and return it."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--postures', type=int, default=200)
    parser.add_argument('--passes', type=int, default=5)
    args = parser.parse_args(argv)
    tune_process()
    out = split(args.postures, args.passes)
    print(f'{"function":<42}{"in the loop [us]":>18}{"isolated [us]":>15}{"calls":>7}')
    for r in out['rows']:
        print(f'{r["name"]:<42}{r["in_loop_us"]:>18.1f}{r["isolated_us"]:>15.1f}'
              f'{r["calls_per_evaluation"]:>7.1f}')
    print(f'{"compiled kernels and Pinocchio":<42}{out["calls_in_loop_us"]:>18.1f}'
          f'{out["calls_isolated_us"]:>15.1f}')
    print(f'the same calls in the order of the loop, back to back: {out["calls_in_order_us"]:.1f} '
          'us per evaluation')
    print(f'evaluate: {out["loop_us"]:.1f} us per evaluation ({out["wrapped_loop_us"]:.1f} with '
          f'the timers), of which Python and numpy between the calls '
          f'{out["python_us"]:.1f} us ({100 * out["python_us"] / out["wrapped_loop_us"]:.0f} %)')
    print(json.dumps(out))
    return out


if __name__ == '__main__':
    main()
