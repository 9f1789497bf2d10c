"""
The parameters of ``awp_node``: declaration with descriptors, validation, conversion.

:class:`NodeParameters` is mixed into :class:`awp_ros.node.node.AwpNode`: it declares the node
parameters (:data:`NODE_PARAMETER_DOCS`), the pipeline parameters
(:data:`awp_ros.ros.pipeline.PARAMETER_DOCS`) and the robot config keys
(:data:`ROBOT_PARAMETER_DOCS`, :data:`ROBOT_PREFIXES`), replacing a bad startup value by its
default (logged and listed in ``config_errors``), and builds the
:class:`~awp_ros.robot.config.RobotConfig` and :class:`~awp_ros.ros.pipeline.PipelineParams` the
pipeline runs with.
"""

from __future__ import annotations

from array import array
from dataclasses import fields, replace

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.parameter import Parameter

from awp_ros.errors import AwpError, ConfigError
from awp_ros.robot.config import load_config, RobotConfig
from awp_ros.ros.pipeline import Pipeline
from awp_ros.ros.pipeline_params import PARAMETER_DOCS, PipelineParams

__all__ = ['limit_value', 'NODE_PARAMETER_DOCS', 'NodeParameters',
           'ROBOT_PARAMETER_DOCS', 'ROBOT_PREFIXES']

_T = Parameter.Type

#: Robot config keys (parameters shared with the core's YAML), their type and meaning.
ROBOT_PARAMETER_DOCS = {
    'robot_name': (_T.STRING, 'robot name (diagnostics hardware_id)'),
    'urdf': (_T.STRING, 'URDF: example-robot-data://<path>, a file path, or the XML'),
    'feet': (_T.STRING_ARRAY, 'contact frames (feet), the order of every per-leg output'),
    'friction_coefficient': (_T.DOUBLE, 'default friction coefficient mu > 0 [-]'),
    'contact_normal': (_T.DOUBLE_ARRAY, 'default contact normal, world axes (normalised)'),
    'pyramid_sides': (_T.INTEGER, 'sides N >= 3 of the friction pyramids'),
}
#: Prefixed robot keys: one parameter per foot or joint.
ROBOT_PREFIXES = {
    'leg_joints': (_T.STRING_ARRAY, 'joints driving foot {} (hip to foot)'),
    'torque_limits': (None, 'torque limit of joint {}: L (range [-L, L]) or [min, max] '
                            '[N.m]'),
    'standing_posture': (_T.DOUBLE, 'standing posture of joint {} [rad]'),
}

#: Node-only parameters: (type, default, description, read_only).
NODE_PARAMETER_DOCS = {
    'robot': (_T.STRING, '', "robot config name or YAML path to start from ('' = the "
              'robot keys given as parameters, else hyq)', True),
    'robot_description': (_T.STRING, '', 'URDF XML (as robot_state_publisher takes it); '
                          'replaces urdf when non-empty', False),
    'qos_depth': (_T.INTEGER, 10000, 'keep-last depth of the input subscriptions and the '
                  'report publisher (10000 = 10 s of 1 kHz joint states of backlog)', True),
    'qos_reliability': (_T.STRING, 'reliable', "input QoS reliability: 'reliable' or "
                        "'best_effort' (matches best-effort publishers)", True),
    'executor': (_T.STRING, 'single_threaded', "rclpy executor: 'single_threaded' or "
                 "'events' (rclpy.experimental.EventsExecutor)", True),
    'diagnostics_period_s': (_T.DOUBLE, 1.0, 'period of /diagnostics [s]', True),
    'drain_budget_s': (_T.DOUBLE, 0.02, 'after a joint state, the node takes the next ones '
                       'straight from the input queues (and waits for them) for up to this '
                       'long before returning to the rclpy executor (timers, parameter '
                       'services): ~0.2 ms less per message [s]; 0 = only those queued', True),
    'max_queue_delay_s': (_T.DOUBLE, 0.0, 'load shedding: a joint state that waited longer '
                          'than this in the input queue (the node is slower than its input) '
                          'is answered at once with a STATUS_STALE_INPUT report instead of '
                          'being evaluated, so latency stays bounded and the queue never '
                          'overflows [s]; 0 = evaluate every joint state however late', False),
    'marker_worker': (_T.BOOL, True, 'build the markers in a worker process (off the '
                      'joint-state loop; ~3 ms each); a marker due while two wait for the '
                      'worker is skipped and counted in /diagnostics; false = in the node',
                      True),
    'blas_threads': (_T.INTEGER, 1, 'threads of the BLAS under numpy/scipy in this process '
                     '(threadpoolctl); 1 avoids the stalls of busy-waiting BLAS threads on '
                     'cores shared with DDS and other processes; 0 = leave as is', True),
}
_FIELDS = {f.name: f for f in fields(PipelineParams)}


class NodeParameters:
    """
    The parameter methods of :class:`awp_ros.node.node.AwpNode` (a mixin of an rclpy Node).

    Uses the node's ``config_errors`` (list of startup problems), ``model_error``,
    ``pipeline``, ``diagnostics``, ``max_queue_delay_s`` and ``_limits_declared``; sets
    ``_base`` (the base robot config).
    """

    def _declare_all(self) -> None:
        """Declare the node and pipeline parameters (the robot keys come later)."""
        for name, (ptype, default, text, ro) in NODE_PARAMETER_DOCS.items():
            self._declare(name, default, text, read_only=ro)
        for name, f in _FIELDS.items():
            self._declare(name, f.default, PARAMETER_DOCS[name],
                          read_only=name == 'use_imu')

    def _declare(self, name: str, default, text: str, *, read_only: bool = False,
                 dynamic: bool = False):
        desc = ParameterDescriptor(name=name, description=text, read_only=read_only,
                                   dynamic_typing=dynamic)
        if name in ('stale_timeout_s', 'fws_rate_hz', 'marker_rate_hz', 'diagnostics_period_s',
                    'max_queue_delay_s', 'drain_budget_s'):
            desc.floating_point_range = [FloatingPointRange(from_value=0.0, to_value=1e6)]
        if name == 'qos_depth':
            desc.integer_range = [IntegerRange(from_value=1, to_value=1_000_000)]
        try:
            return self.declare_parameter(name, default, desc)
        except (InvalidParameterTypeException, InvalidParameterValueException) as first:
            error: Exception = first
            override = self._overrides()[name].value
        # A bad value from the params file or -p: an integer where a double is expected is
        # taken as that double; anything else is reported and the default used.
        if isinstance(default, float) and isinstance(override, int) \
                and not isinstance(override, bool):
            try:
                return self.declare_parameter(
                    name, float(override), desc, ignore_override=True)
            except InvalidParameterValueException as second:
                error = second
        reason = (f'parameter {name} = {override!r} rejected ({type(error).__name__}: '
                  f'{str(error).splitlines()[0]}); using the default {default!r}')
        self.get_logger().error(reason)
        self.config_errors.append(reason)
        return self.declare_parameter(name, default, desc, ignore_override=True)

    def _overrides(self) -> dict:
        """Return the parameter overrides (params file, -p) by name."""
        return dict(getattr(self, '_parameter_overrides', {}))

    def _declare_robot_parameters(self) -> None:
        """Declare the robot keys; defaults from the base config (see ``robot``)."""
        overrides = self._overrides()
        robot = self.get_parameter('robot').value
        self._base: RobotConfig | None = None
        try:
            if robot or not any(k in overrides for k in ('robot_name', 'urdf', 'feet')):
                self._base = load_config(robot or 'hyq')
        except AwpError as exc:
            self.model_error = f'no robot model: {exc}'
        base = self._base_dict()
        for name, (ptype, text) in ROBOT_PARAMETER_DOCS.items():
            if name in base or name in overrides:   # any type: RobotConfig validates
                default = base[name] if name in base else overrides[name].value
                self._declare(name, default, text, dynamic=True)
            else:
                self.declare_parameter(name, ptype, ParameterDescriptor(description=text))
        prefixed = {k for k in overrides if k.split('.', 1)[0] in ROBOT_PREFIXES and '.' in k}
        prefixed |= {k for k in base if '.' in k}
        for key in sorted(prefixed):
            prefix, item = key.split('.', 1)
            ptype, text = ROBOT_PREFIXES[prefix]
            self._declare(key, base.get(key, overrides.get(key).value if key in overrides
                                        else None), text.format(item), dynamic=True)

    def _base_dict(self) -> dict:
        """Return the base config as flat parameter values (dotted keys)."""
        c = self._base
        if c is None:
            return {}
        out = {'robot_name': c.robot_name, 'urdf': c.urdf, 'feet': list(c.feet),
               'friction_coefficient': float(c.friction_coefficient),
               'contact_normal': [float(x) for x in c.contact_normal],
               'pyramid_sides': int(c.pyramid_sides)}
        out.update({f'leg_joints.{k}': list(v) for k, v in c.leg_joints.items()})
        out.update({f'torque_limits.{k}': limit_value(v) for k, v in c.torque_limits.items()})
        out.update({f'standing_posture.{k}': float(v) for k, v in c.standing_posture.items()})
        return out

    def _declare_torque_limits(self) -> None:
        """
        Declare ``torque_limits.<joint>`` for every leg joint, with the limit in use.

        One call for all of them: after a runtime model recovery the on-set callback then
        runs once (the values are the ones in use, so nothing changes).
        """
        new = []
        for leg in self.pipeline.evaluator.model.legs.values():
            for j, lo, hi in zip(leg.joints, leg.tau_min.tolist(), leg.tau_max.tolist()):
                key = f'torque_limits.{j}'
                if not self.has_parameter(key):
                    text = ROBOT_PREFIXES['torque_limits'][1].format(j)
                    new.append((key, limit_value((lo, hi)),
                                ParameterDescriptor(name=key, description=text,
                                                    dynamic_typing=True)))
        self._limits_declared = True
        if new:
            try:
                self.declare_parameters('', new)
            except Exception as exc:  # noqa: BLE001 -- the limits stay in use, undeclared
                self.get_logger().warning(f'torque_limits.* parameters not declared: {exc}')

    def _robot_values(self, changes: dict | None = None) -> dict:
        """Return the robot keys' values (with ``changes``) as plain Python values."""
        names = [n for n in self.list_parameters([], 0).names
                 if n in ROBOT_PARAMETER_DOCS or n.split('.', 1)[0] in ROBOT_PREFIXES]
        values = {p.name: p.value for p in self.get_parameters(names)}
        values.update(changes or {})
        values = {k: (list(v) if isinstance(v, (array, tuple)) else v)
                  for k, v in values.items() if v is not None}
        return values

    def _robot_config(self, changes: dict | None = None) -> RobotConfig:
        """Build the RobotConfig from the parameters (``changes`` applied)."""
        values = self._robot_values(changes)
        base_dir = self._base.base_dir if self._base is not None else None
        config = RobotConfig.from_dict(values, base_dir=base_dir)
        urdf = (changes or {}).get('robot_description',
                                   self.get_parameter('robot_description').value)
        if urdf:
            if not isinstance(urdf, str) or not urdf.lstrip().startswith('<'):
                text = urdf[:60] if isinstance(urdf, str) else urdf
                raise ConfigError(f'robot_description must be URDF XML (starting with <), '
                                  f'got {text!r}')
            config = replace(config, urdf=urdf)
        return config

    def _pipeline_params(self, changes: dict | None = None) -> PipelineParams:
        """Build the PipelineParams from the parameters (``changes`` applied)."""
        kw = {name: self.get_parameter(name).value for name in _FIELDS}
        kw.update({k: v for k, v in (changes or {}).items() if k in _FIELDS})
        return PipelineParams.from_dict(kw)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate a parameter change; apply it from the next joint state on."""
        changes = {p.name: p.value for p in params}
        try:
            new_params = self._pipeline_params(changes)
            robot = {k for k in changes if k in ROBOT_PARAMETER_DOCS or k == 'robot_description'
                     or k.split('.', 1)[0] in ROBOT_PREFIXES}
            if self.pipeline is None and robot:
                self.pipeline = Pipeline(self._robot_config(changes), new_params,
                                         input_buffer=self.get_parameter('qos_depth').value)
                self.model_error = self.diagnostics.model_error = ''
                self.diagnostics.hardware_id = self.pipeline.config.robot_name
                self.get_logger().info(f'robot model {self.pipeline.config.robot_name!r} '
                                       'built; evaluating joint states')
            elif self.pipeline is not None:
                if robot:
                    self.pipeline.set_config(self._robot_config(changes))
                self.pipeline.set_params(new_params)
        except (AwpError, ValueError, TypeError) as exc:
            reason = f'rejected {sorted(changes)}: {exc}'
            self.get_logger().warning(reason)
            return SetParametersResult(successful=False, reason=reason)
        self.diagnostics.stale_timeout_s = new_params.stale_timeout_s
        if 'max_queue_delay_s' in changes:
            self.max_queue_delay_s = float(changes['max_queue_delay_s'])
        return SetParametersResult(successful=True)

    def checked_choice(self, name: str, choices: tuple[str, ...]) -> str:
        """Return parameter ``name`` if among ``choices``, else log, list and use the first."""
        value = self.get_parameter(name).value
        if value in choices:
            return value
        reason = (f"{name} must be {' or '.join(repr(c) for c in choices)}, got {value!r}; "
                  f'using {choices[0]!r}')
        self.get_logger().error(reason)
        self.config_errors.append(reason)
        return choices[0]


def limit_value(pair) -> float | list[float]:
    """Return a torque range as a parameter value: L when symmetric, else [min, max]."""
    lo, hi = (float(x) for x in pair)
    return hi if lo == -hi else [lo, hi]
