"""
The parameters of ``awp_node``: declaration with descriptors, validation, application.

:class:`NodeParameters` is a part of :class:`awp_ros.node.node.AwpNode`, as rclpy's parameter
examples do it: it declares the node parameters (:data:`NODE_PARAMETER_DOCS`), the pipeline
parameters (:data:`awp_ros.robot.parameters.PARAMETER_DOCS`) and the robot config keys
(:data:`ROBOT_PARAMETER_DOCS`, :data:`ROBOT_PREFIXES`) with the defaults of the one parameter
schema (:func:`awp_ros.robot.parameters.parameter_schema`; a minimal config of ``urdf`` and
``feet`` leaves no parameter unset), refusing keys the schema does not know (the model error
names them and their close matches), replacing a bad startup value by its
default (logged and listed in :attr:`NodeParameters.config_errors`); a change at runtime is
validated in the on-set callback (the robot model is rebuilt there, a few ms, and the result
kept) and applied in the post-set callback, which hands the new
:class:`~awp_ros.robot.config.RobotConfig` model and
:class:`~awp_ros.robot.parameters.PipelineParams` to the node's ``apply`` function.
"""

from __future__ import annotations

from array import array
from collections.abc import Callable
from dataclasses import fields, replace

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from awp_ros.errors import AwpError, ConfigError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.robot.config import check_keys, DEFAULT_ROBOT, load_config, RobotConfig
from awp_ros.robot.parameters import (NODE_KEYS, PARAMETER_DOCS, PIPELINE_KEYS, PipelineParams,
                                      ROBOT_KEYS)
from awp_ros.ros.pipeline import check_marker_frame

__all__ = ['limit_value', 'NODE_PARAMETER_DOCS', 'NodeParameters',
           'ROBOT_PARAMETER_DOCS', 'ROBOT_PREFIXES']

_T = Parameter.Type
#: Schema kind -> rclpy parameter type (None: a double or a pair, dynamically typed).
_TYPES = {'string': _T.STRING, 'double': _T.DOUBLE, 'integer': _T.INTEGER, 'bool': _T.BOOL,
          'string_array': _T.STRING_ARRAY, 'double_array': _T.DOUBLE_ARRAY, 'limit': None}

#: Robot config keys (parameters shared with the core's YAML), their type and meaning; the
#: defaults are those of :data:`awp_ros.robot.parameters.ROBOT_KEYS`.
ROBOT_PARAMETER_DOCS = {name: (_TYPES[k.kind], k.doc) for name, k in ROBOT_KEYS.items()
                        if not k.item}
#: Prefixed robot keys: one parameter per foot or joint.
ROBOT_PREFIXES = {name: (_TYPES[k.kind], f'{k.item} {{}}: {k.doc}')
                  for name, k in ROBOT_KEYS.items() if k.item}

#: Node-only parameters: (type, default, description, read_only), from
#: :data:`awp_ros.robot.parameters.NODE_KEYS`.
NODE_PARAMETER_DOCS = {name: (_TYPES[k.kind], k.default, k.doc, k.read_only)
                       for name, k in NODE_KEYS.items()}
_FIELDS = {f.name: f for f in fields(PipelineParams)}


class NodeParameters:
    """
    Declare, validate (on-set) and apply (post-set) the parameters of an ``awp_node``.

    :param node: the rclpy node the parameters belong to.
    :param apply: called after an accepted change with ``(evaluator, params)``: the new
        :class:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator` (None when no robot key
        changed) and the new :class:`~awp_ros.robot.parameters.PipelineParams`.
    :param root_link: returns the root link of the robot model in use, None without a
        model (a change of a robot key then builds one).
    :ivar config_errors: startup problems (bad values replaced by defaults).
    :ivar base: the robot config the robot keys' defaults come from (``robot``), or None.
    :ivar base_error: why there is no robot model at startup ('' = none): the base config
        cannot be loaded, or a parameter no part of the node knows was given (a typo; the
        message names its close matches).
    """

    def __init__(self, node: Node, apply: Callable,
                 root_link: Callable[[], str | None]) -> None:
        self._node = node
        self._apply_fn = apply
        self._root_link = root_link
        self._pending: tuple | None = None
        self._declaring = False
        self.config_errors: list[str] = []
        self.base: RobotConfig | None = None
        self.base_error = ''
        for name, (ptype, default, text, ro) in NODE_PARAMETER_DOCS.items():
            self._declare(name, default, text, read_only=ro)
        overrides = self._overrides()
        for name, f in _FIELDS.items():
            rejected = ''
            if name in overrides:       # a value of the right type may still be out of range
                try:
                    PipelineParams.from_dict({name: overrides[name].value})
                except ConfigError as exc:
                    rejected = str(exc)
            self._declare(name, f.default, PARAMETER_DOCS.get(name, ''),
                          read_only=PIPELINE_KEYS[name].read_only,
                          dynamic=isinstance(f.default, tuple), rejected=rejected)
        self._declare_robot_parameters()
        self._check_overrides()
        self._check_pipeline_values()
        node.add_on_set_parameters_callback(self._validate)
        node.add_post_set_parameters_callback(self._apply)

    def value(self, name: str):
        """Return the value of parameter ``name``."""
        return self._node.get_parameter(name).value

    def choice(self, name: str, choices: tuple[str, ...]) -> str:
        """Return parameter ``name`` if among ``choices``, else log, list and use the first."""
        value = self.value(name)
        if value in choices:
            return value
        reason = (f"{name} must be {' or '.join(repr(c) for c in choices)}, got {value!r}; "
                  f'using {choices[0]!r}')
        self._node.get_logger().error(reason)
        self.config_errors.append(reason)
        return choices[0]

    # -- declaration -----------------------------------------------------------------------

    def _declare(self, name: str, default, text: str, *, read_only: bool = False,
                 dynamic: bool = False, rejected: str = ''):
        node = self._node
        desc = ParameterDescriptor(name=name, description=text, read_only=read_only,
                                   dynamic_typing=dynamic)
        if rejected:                    # the override is invalid: the default, reported
            reason = (f'parameter {name} = {self._overrides()[name].value!r} rejected '
                      f'({rejected}); using the default {default!r}')
            node.get_logger().error(reason)
            self.config_errors.append(reason)
            return node.declare_parameter(name, default, desc, ignore_override=True)
        if name in ('stale_timeout_s', 'fws_rate_hz', 'fws_lag_s', 'marker_rate_hz',
                    'diagnostics_period_s', 'max_queue_delay_s', 'drain_budget_s'):
            desc.floating_point_range = [FloatingPointRange(from_value=0.0, to_value=1e6)]
        if name == 'qos_depth':
            desc.integer_range = [IntegerRange(from_value=1, to_value=1_000_000)]
        if name == 'main_thread_cpu':
            desc.integer_range = [IntegerRange(from_value=-1, to_value=4095)]
        try:
            return node.declare_parameter(name, default, desc)
        except (InvalidParameterTypeException, InvalidParameterValueException) as first:
            error: Exception = first
            override = self._overrides()[name].value
        # A bad value from the params file or -p: an integer where a double is expected is
        # taken as that double; anything else is reported and the default used.
        if isinstance(default, float) and isinstance(override, int) \
                and not isinstance(override, bool):
            try:
                return node.declare_parameter(name, float(override), desc, ignore_override=True)
            except InvalidParameterValueException as second:
                error = second
        reason = (f'parameter {name} = {override!r} rejected ({type(error).__name__}: '
                  f'{str(error).splitlines()[0]}); using the default {default!r}')
        node.get_logger().error(reason)
        self.config_errors.append(reason)
        return node.declare_parameter(name, default, desc, ignore_override=True)

    def _overrides(self) -> dict:
        """Return the parameter overrides (params file, -p) by name."""
        return dict(getattr(self._node, '_parameter_overrides', {}))

    def _declare_robot_parameters(self) -> None:
        """
        Declare the robot keys, with the defaults of the base config (``robot``) or the schema.

        Without ``robot``, the robot keys given as parameters (``urdf``, ``feet``: the
        required ones) make the config, every other key taking its schema default; with
        neither, the base config is ``hyq``. A required key nobody gave is declared unset
        (the config then names it in the model error).
        """
        overrides = self._overrides()
        robot = self.value('robot')
        try:
            if robot or not any(k in overrides for k in ('urdf', 'feet')):
                self.base = load_config(robot or DEFAULT_ROBOT)
        except AwpError as exc:
            self.base_error = f'no robot model: {exc}'
        base = self._base_dict()
        for name, (ptype, text) in ROBOT_PARAMETER_DOCS.items():
            default = ROBOT_KEYS[name].default
            if name in base or name in overrides or default is not None:
                if name in base:        # any type: RobotConfig validates
                    default = base[name]
                elif name in overrides:
                    default = overrides[name].value
                self._declare(name, default, text, dynamic=True)
            else:
                self._node.declare_parameter(name, ptype, ParameterDescriptor(
                    description=text, dynamic_typing=True))
        prefixed = {k for k in overrides if k.split('.', 1)[0] in ROBOT_PREFIXES and '.' in k}
        prefixed |= {k for k in base if '.' in k}
        for key in sorted(prefixed):
            prefix, item = key.split('.', 1)
            ptype, text = ROBOT_PREFIXES[prefix]
            self._declare(key, base.get(key, overrides.get(key).value if key in overrides
                                        else None), text.format(item), dynamic=True)

    def _check_overrides(self) -> None:
        """
        Refuse parameters (params file, ``-p``) that no part of the node knows.

        A typo (``friction_coeficient``) would otherwise leave the default in use silently:
        it becomes the model error (every report ``STATUS_ERROR`` naming the key and its
        close matches, ``/diagnostics`` ERROR) until a robot key is set at runtime.
        """
        declared = {name.split('.', 1)[0] for name in self._node._parameters}
        try:
            check_keys({k: p.value for k, p in self._overrides().items()}, extra=declared)
        except ConfigError as exc:
            reason = f'bad parameters: {exc}'       # logged by the node as its model error
            self.base_error = '; '.join(e for e in (self.base_error, reason) if e)

    def _check_pipeline_values(self) -> None:
        """
        Replace pipeline parameters that PipelineParams rejects together by their defaults.

        Values valid one by one but not together (``contact_force_off_n`` above
        ``contact_force_on_n``; one by one they are checked when declared) are logged,
        listed in :attr:`config_errors` and replaced by their defaults.
        """
        for _ in range(len(_FIELDS)):
            try:
                self.pipeline_params()
                return
            except ConfigError as exc:
                text = str(exc)
                bad = [n for n in _FIELDS if n in text.split(' ', 1)[0] or f' {n} ' in text
                       or text.startswith(n)] or list(_FIELDS)
                for name in bad:
                    default = _FIELDS[name].default
                    value = self.value(name)
                    reason = (f'parameter {name} = {value!r} rejected ({text}); using the '
                              f'default {default!r}')
                    self._node.get_logger().error(reason)
                    self.config_errors.append(reason)
                    self._declaring = True       # the default: nothing to validate or apply
                    try:
                        self._node.set_parameters([Parameter(name, value=default)])
                    finally:
                        self._declaring = False

    def _base_dict(self) -> dict:
        """Return the base config as flat parameter values (dotted keys)."""
        c = self.base
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

    def declare_torque_limits(self, model) -> None:
        """
        Declare ``torque_limits.<joint>`` for every leg joint of ``model``, with the limit in use.

        One call for all of them, accepted without validation: the values are the ones in
        use, so nothing changes.
        """
        node = self._node
        new = []
        for leg in model.legs.values():
            for j, lo, hi in zip(leg.joints, leg.tau_min.tolist(), leg.tau_max.tolist()):
                key = f'torque_limits.{j}'
                if not node.has_parameter(key):
                    text = ROBOT_PREFIXES['torque_limits'][1].format(j)
                    new.append((key, limit_value((lo, hi)),
                                ParameterDescriptor(name=key, description=text,
                                                    dynamic_typing=True)))
        if new:
            self._declaring = True      # the values in use: nothing to validate or apply
            try:
                node.declare_parameters('', new)
            except Exception as exc:  # noqa: BLE001 -- the limits stay in use, undeclared
                node.get_logger().warning(f'torque_limits.* parameters not declared: {exc}')
            finally:
                self._declaring = False

    # -- values ----------------------------------------------------------------------------

    def robot_config(self, changes: dict | None = None) -> RobotConfig:
        """Build the RobotConfig from the parameters (``changes`` applied)."""
        node = self._node
        names = [n for n in node.list_parameters([], 0).names
                 if n in ROBOT_PARAMETER_DOCS or n.split('.', 1)[0] in ROBOT_PREFIXES]
        values = {n: node.get_parameter_or(n, None).value for n in names}   # unset: None
        values.update(changes or {})
        values = {k: (list(v) if isinstance(v, (array, tuple)) else v)
                  for k, v in values.items() if v is not None}
        base_dir = self.base.base_dir if self.base is not None else None
        config = RobotConfig.from_dict(values, base_dir=base_dir)
        urdf = (changes or {}).get('robot_description', self.value('robot_description'))
        if urdf:
            if not isinstance(urdf, str) or not urdf.lstrip().startswith('<'):
                text = urdf[:60] if isinstance(urdf, str) else urdf
                raise ConfigError(f'robot_description must be URDF XML (starting with <), '
                                  f'got {text!r}')
            config = replace(config, urdf=urdf)
        return config

    def pipeline_params(self, changes: dict | None = None) -> PipelineParams:
        """Build the PipelineParams from the parameters (``changes`` applied)."""
        kw = {name: self.value(name) for name in _FIELDS}
        kw.update({k: v for k, v in (changes or {}).items() if k in _FIELDS})
        return PipelineParams.from_dict(kw)

    # -- runtime changes -------------------------------------------------------------------

    def _validate(self, params: list[Parameter]) -> SetParametersResult:
        """Check a parameter change (on-set): build what it needs, keep it for :meth:`_apply`."""
        changes = {p.name: p.value for p in params}
        self._pending = None
        if self._declaring:
            return SetParametersResult(successful=True)
        try:
            new_params = self.pipeline_params(changes)
            robot = any(k in ROBOT_PARAMETER_DOCS or k == 'robot_description'
                        or k.split('.', 1)[0] in ROBOT_PREFIXES for k in changes)
            evaluator = None
            if robot:
                evaluator = FeasibilityEvaluator(self.robot_config(changes))
                check_marker_frame(new_params, evaluator.model.root_link)
            elif self._root_link() is not None:
                check_marker_frame(new_params, self._root_link())
        except (AwpError, ValueError, TypeError) as exc:
            reason = f'rejected {sorted(changes)}: {exc}'
            self._node.get_logger().warning(reason)
            return SetParametersResult(successful=False, reason=reason)
        self._pending = (evaluator, new_params)
        return SetParametersResult(successful=True)

    def _apply(self, params: list[Parameter]) -> None:
        """Apply a validated change (post-set) from the next joint state on."""
        if self._pending is not None:
            evaluator, new_params = self._pending
            self._pending = None
            self._apply_fn(evaluator, new_params)


def limit_value(pair) -> float | list[float]:
    """Return a torque range as a parameter value: L when symmetric, else [min, max]."""
    lo, hi = (float(x) for x in pair)
    return hi if lo == -hi else [lo, hi]
