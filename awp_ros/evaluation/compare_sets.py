"""
How much of the FWP lies outside the FWS: ``python -m awp_ros.evaluation.compare_sets``.

The FWP (seed: AWP ∩ CWC) asks that *some* force distribution respects the torque limits
and *some*, possibly other, distribution respects friction and unilaterality; the FWS asks
for *one* distribution that respects both at every leg, so FWS ⊆ FWP. This script samples
the FWP uniformly by hit-and-run (random direction, uniform point on the chord through the
current point, chord from the ratio test on the FWP's H-rep) starting at the
gravito-inertial wrench, and counts the samples outside the FWS (its exact H-rep).
Wrenches: [N, N.m] about the CoM, world-aligned axes.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator

__all__ = ['fraction_outside_fws', 'main']


def fraction_outside_fws(evaluator: FeasibilityEvaluator, *, stance=None, mu=None,
                         samples: int = 20000, burn_in: int = 2000, thin: int = 3,
                         seed: int = 0, tol: float = 1e-9) -> float:
    """Return the fraction of FWP volume outside the FWS at the standing posture."""
    rng = np.random.default_rng(seed)
    result = evaluator.evaluate(evaluator.standing_state(stance=stance,
                                                         friction_coefficient=mu))
    if result.fwp.dimension < 6 or result.fwp.margin <= 0.0:
        raise InputError('hit-and-run needs a full-dimensional FWP containing the wrench')
    fwp, fws = result.fwp.polytope, result.fws.polytope
    x = result.wrench.copy()
    outside = 0
    steps = burn_in + samples * thin
    directions = rng.normal(size=(steps, 6))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    for i, d in enumerate(directions):
        ad, slack = fwp.A @ d, fwp.b - fwp.A @ x
        with np.errstate(divide='ignore'):
            t = slack / ad
        x = x + rng.uniform(np.max(t[ad < 0]), np.min(t[ad > 0])) * d
        if i >= burn_in and (i - burn_in) % thin == 0:
            outside += not np.all(fws.A @ x <= fws.b + tol)
    return outside / samples


def main(argv: list[str] | None = None) -> int:
    """Print the fraction for a few stances and friction coefficients."""
    parser = argparse.ArgumentParser(prog='python -m awp_ros.evaluation.compare_sets',
                                     description=__doc__.splitlines()[0])
    parser.add_argument('--robot', default='hyq')
    parser.add_argument('--samples', type=int, default=20000)
    args = parser.parse_args(argv)
    evaluator = FeasibilityEvaluator(args.robot)
    feet = list(evaluator.feet)
    for stance in (feet, feet[:2] + feet[3:]):
        for mu in (0.7, 0.5):
            share = fraction_outside_fws(evaluator, stance=stance, mu=mu, samples=args.samples)
            print(f'{args.robot} stance {",".join(stance)} mu {mu}: '
                  f'{100 * share:.1f} % of the FWP is outside the FWS')
    return 0


if __name__ == '__main__':
    sys.exit(main())
