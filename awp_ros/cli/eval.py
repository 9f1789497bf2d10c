"""
``awp_eval``: evaluate one robot state given as JSON and print the result as JSON.

Input (a file argument, or stdin when absent or ``-``), one JSON object::

    {
      "robot": "hyq",                       # config name or YAML path (default hyq)
      "posture": "standing",                # optional: start from the config's posture
      "joint_positions": {"lf_haa_joint": -0.1, ...},   # [rad]; all joints unless posture
      "joint_velocities": {...},            # optional [rad/s], all joints
      "joint_accelerations": {...},         # optional [rad/s^2], all joints
      "joint_efforts": {...},               # optional [N.m], all joints: measured forces
      "base_orientation": [0, 0, 0, 1],     # optional quaternion [x, y, z, w]
      "base_twist": [vx, vy, vz, wx, wy, wz],          # optional, base frame [m/s, rad/s]
      "base_acceleration": [ax, ay, az, alx, aly, alz],  # optional, base frame
      "stance": ["lf_foot", "rh_foot"],     # optional, default all feet; [] allowed
      "friction_coefficient": 0.7,          # optional, all feet
      "friction_coefficients": {"lf_foot": 0.5},       # optional, per foot
      "normals": {"lf_foot": [0, 0, 1]},    # optional, per foot, world frame
      "wrench": [fx, fy, fz, mx, my, mz]    # optional: the margins of this wrench [N, N.m]
    }                                       # (about the CoM, world axes) instead of w

Output: the :meth:`~awp_ros.evaluation.result.FeasibilityResult.to_dict` document (``mass``,
``com``, ``wrench``, ``legs``, ``awp``/``fwp``/``fws`` with ``margin``, ``normal``,
``dimension``, ``affine_residual``, ``feasible``, ``halfspaces``; ``fws.directional``;
``status``, ``warnings``, ``timings_ms``: per stage [ms], ``total`` the per-cycle evaluation
without the FWS, and ``fws`` / ``fws_directional`` / ``fws_margin`` / ``feasible_region``
when it is computed). The CoM regions (world-aligned x/y, origin the CoM, [m]):
``feasible_region`` (the FWS's slice, by projection every evaluation; ``null`` when not
computed: no stance leg, or a singular leg with ``--no-fws``), ``support_region``
(slice of the CWC), ``fwp_region`` (slice of the FWP), each ``{"dimension": 2 | 1 | 0 | -1,
"vertices": [[x, y], ...], "halfspaces": [[a_x, a_y, b], ...], "margin": m, "area": a}``
(vertices counter-clockwise; a segment for two stance legs, a point for one, ``[]`` and
``"margin": null`` when empty); ``com_velocity`` [m/s] and ``capture_point`` [m, relative
to the CoM] when ``base_twist`` is given (else ``null``), ``capture_point_margin`` [m]
(its signed distance to the feasible region, ``null`` without it);
``fws_directional_per_cycle`` (``{"fx": {"plus": t, "minus": t}, ...}`` [N, N.m]: the FWS's
directional margins by LPs without its H-rep, as the node reports them every cycle; with three
or more stance legs, else ``null``; equal to ``fws.directional`` to about 1e-7);
``fws_margin_per_cycle`` (``{"margin": m, "margin_in_hull": m, "normal": [...], "dimension": 6,
"affine_residual": 0, "feasible": false}``: the FWS's signed margin and witness from its
nearest point, without its H-rep, as the node reports them every cycle when the wrench is
outside the FWS with three or more stance legs; else ``null``; equal to ``fws``'s to about
1e-7).
Non-finite numbers are written as ``null``.
Exit status: 0 on success, 2 on bad input (one line on stderr naming it), 1 on an internal
error.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
import json
from pathlib import Path
import sys

from awp_ros.errors import AwpError, InputError, ModelError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.robot.state import RobotState
from awp_ros.runtime import tune_process

__all__ = ['main', 'state_from_json']

PROG = 'awp_eval'
_STATE_KEYS = ('joint_positions', 'joint_velocities', 'joint_accelerations',
               'joint_efforts', 'base_orientation', 'base_twist', 'base_acceleration',
               'stance', 'normals', 'friction_coefficient', 'friction_coefficients')
_KEYS = ('robot', 'posture', 'wrench') + _STATE_KEYS


def state_from_json(doc: Mapping, evaluator: FeasibilityEvaluator) -> RobotState:
    """
    Return the :class:`RobotState` of an ``awp_eval`` input document.

    :raises InputError: unknown keys, a bad ``posture``, or missing ``joint_positions``.
    """
    unknown = [k for k in doc if k not in _KEYS]
    if unknown:
        raise InputError(f'unknown input keys {unknown}; known keys are {list(_KEYS)}')
    kw = {k: doc[k] for k in _STATE_KEYS if k in doc and doc[k] is not None}
    posture = doc.get('posture')
    if posture is not None:
        if posture != 'standing':
            raise InputError(f"posture must be 'standing', got {posture!r}")
        base = evaluator.standing_state().joint_positions
        override = kw.get('joint_positions', {})
        if not isinstance(override, Mapping):
            raise InputError(f'joint_positions must be an object, got {override!r}')
        kw['joint_positions'] = {**base, **override}
    elif 'joint_positions' not in kw:
        raise InputError('joint_positions is required (or give "posture": "standing")')
    return RobotState(**kw)


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``awp_eval``."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Evaluate the force polytopes, AWP, FWP and FWS of one robot state and '
                    'print them as JSON. The state is a JSON object (see the keys below).',
        epilog='input keys: ' + ', '.join(_KEYS) + '. Example: echo \'{"posture": '
               '"standing"}\' | awp_eval --indent 2. Exit status 2 on bad input.')
    parser.add_argument('state', nargs='?', default='-',
                        help='JSON file with the state (default: stdin, also "-")')
    parser.add_argument('--robot', default=None,
                        help='robot config name or YAML path; overrides the "robot" key '
                             '(default: the key, else hyq)')
    parser.add_argument('--no-fws', action='store_true',
                        help='skip the feasible wrench set (FWS) and its margins')
    parser.add_argument('--no-halfspaces', action='store_true',
                        help='omit the 6D H-representations from the output')
    parser.add_argument('--indent', type=int, default=None,
                        help='indent the JSON output by this many spaces (default: one line)')
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``awp_eval``; return the exit status."""
    tune_process()
    args = build_parser().parse_args(argv)
    try:
        doc = _read(args.state)
        robot = args.robot or doc.get('robot') or 'hyq'
        if not isinstance(robot, str):
            raise InputError(f'robot must be a config name or path, got {robot!r}')
        evaluator = FeasibilityEvaluator(robot)
        state = state_from_json(doc, evaluator)
        result = evaluator.evaluate(state, fws=not args.no_fws, wrench=doc.get('wrench'))
    except (ValueError, ModelError) as exc:   # InputError, ConfigError, JSON errors
        _error(str(exc))
        return 2
    except (AwpError, RuntimeError) as exc:
        _error(f'internal error: {exc}')
        return 1
    out = result.to_dict(halfspaces=not args.no_halfspaces)
    sys.stdout.write(json.dumps(out, indent=args.indent, allow_nan=False) + '\n')
    return 0


def _read(path: str) -> dict:
    """Return the JSON object in ``path`` (``-``: stdin); InputError if unreadable."""
    try:
        doc = json.loads(sys.stdin.read() if path == '-' else Path(path).read_text('utf-8'))
    except OSError as exc:
        raise InputError(f'cannot read state file {path!r}: {exc.strerror}') from exc
    except json.JSONDecodeError as exc:
        raise InputError(f'state is not valid JSON: {exc}') from exc
    if not isinstance(doc, dict):
        raise InputError(f'state must be a JSON object, got {type(doc).__name__}')
    return doc


def _error(message: str) -> None:
    line = ' '.join(message.split())
    sys.stderr.write(f'{PROG}: error: {line}\n')


if __name__ == '__main__':
    sys.exit(main())
