"""
The parameters schema: every key of a robot's parameters file, with defaults and meanings.

One YAML file holds the robot's keys (read by the core: :class:`awp_ros.robot.config.
RobotConfig`), the pipeline's (:class:`PipelineParams`: what ``awp_node`` and the offline
replay compute and publish) and the node's own (``awp_node``'s process). This module is the
one home of all three, ROS-free (no rclpy, no messages), so that every reader of such a file
knows every key and tells a key of another reader from a typo (:func:`parameter_schema`).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field, fields
import difflib
import math

from awp_ros.errors import ConfigError

__all__ = ['CONTACT_SOURCES', 'ConfigKey', 'MOTIONS', 'NODE_KEYS', 'PARAMETER_DOCS',
           'PIPELINE_KEYS', 'PipelineParams', 'ROBOT_KEYS', 'ROS_KEYS', 'close_matches',
           'parameter_schema', 'ros_parameters']


@dataclass(frozen=True)
class ConfigKey:
    """
    One key of the parameters schema: its kind, default and meaning.

    ``kind`` is ``'string'``, ``'double'``, ``'integer'``, ``'bool'``, ``'string_array'``,
    ``'double_array'`` or ``'limit'`` (a double ``L`` or a pair ``[min, max]``). A key with
    an ``item`` is prefixed: one parameter ``<name>.<item>`` per foot or joint (nested in
    YAML). ``default`` is None for a required key and for one whose default is derived
    (``doc`` says from what). ``group``: ``'robot'`` (the core's keys), ``'pipeline'`` or
    ``'node'`` (``awp_node`` and the replay only).
    """

    kind: str
    default: object
    doc: str
    required: bool = False
    item: str = ''
    group: str = 'robot'
    read_only: bool = False


#: The robot keys: what the core reads (RobotConfig), with defaults; ``urdf`` and ``feet``
#: are the only required keys.
ROBOT_KEYS: dict[str, ConfigKey] = {
    'robot_name': ConfigKey(
        'string', '', "robot name (reports, diagnostics hardware_id); '' = the URDF's file "
        'name without extension (a1.urdf: a1), or the name attribute of URDF XML'),
    'urdf': ConfigKey(
        'string', None, 'URDF: example-robot-data://<path under robots/>, file://<path>, a '
        'path (relative to the YAML file) or the XML itself', required=True),
    'feet': ConfigKey(
        'string_array', None, 'contact frames (URDF links or frames), in the order of every '
        'per-leg output', required=True),
    'leg_joints': ConfigKey(
        'string_array', None, 'joints driving the foot, base to foot; default: the 1-DoF '
        'joints on the kinematic chain from the base to the foot', item='foot'),
    'torque_limits': ConfigKey(
        'limit', None, 'torque limit of a leg joint: L (the range [-L, L]) or [min, max] '
        '[N.m] ([N] prismatic); default: the URDF effort limit; a joint that drives no leg is '
        'an error', item='joint'),
    'friction_coefficient': ConfigKey(
        'double', 0.7, 'default friction coefficient mu > 0 of every foot [-]'),
    'contact_normal': ConfigKey(
        'double_array', [0.0, 0.0, 1.0], 'default contact normal, world axes (normalised on '
        'load)'),
    'pyramid_sides': ConfigKey('integer', 4, 'sides N >= 3 of the friction pyramids'),
    'standing_posture': ConfigKey(
        'double', None, 'standing posture of a joint [rad]: all joints of the model or none; '
        "used by awp_eval's \"posture\": \"standing\" and the gait generator; default: none "
        "(awp_demo then takes the 'standing' state of the SRDF beside the URDF)",
        item='joint'),
}

#: Parameters every rclpy node has (declared by rclpy; accepted in a parameters file).
ROS_KEYS = ('use_sim_time', 'start_type_description_service', 'qos_overrides')


def parameter_schema() -> dict[str, ConfigKey]:
    """
    Return every key of a parameters file: the robot keys, the pipeline's and the node's.

    One schema for every reader of a parameters file (the core loader, the offline replay,
    ``awp_node``), so that each tells a key of another reader from a typo.
    """
    return {**ROBOT_KEYS, **PIPELINE_KEYS, **NODE_KEYS}


def close_matches(name: str, names: Collection[str]) -> str:
    """Return `` (did you mean 'a' or 'b'?)`` for the names close to ``name``, or ''."""
    found = difflib.get_close_matches(name, list(names), n=3, cutoff=0.6)
    if not found:
        return ''
    return f" (did you mean {' or '.join(repr(m) for m in found)}?)"


def ros_parameters(params: Mapping) -> dict:
    """
    Merge the ``ros__parameters`` sections of a parameters file's mapping.

    A mapping without such a section (the section itself, or rclpy's flat parameters) is
    returned as a copy.
    """
    sections = [v['ros__parameters'] for v in params.values()
                if isinstance(v, Mapping) and isinstance(v.get('ros__parameters'), Mapping)]
    if isinstance(params.get('ros__parameters'), Mapping):
        sections.append(params['ros__parameters'])
    merged: dict = {}
    for section in sections or [params]:
        merged.update(section)
    return merged


#: Values of ``motion``: ``auto`` = ``measured`` when the IMU or odometry is on, else
#: ``quasi_static``.
MOTIONS = ('auto', 'measured', 'quasi_static')
#: Values of ``contact_source``: where the stance comes from (see PipelineParams).
CONTACT_SOURCES = ('topic', 'effort', 'all')


def _param(default, doc: str, *, read_only: bool = False):
    """Return a PipelineParams field: its default, its meaning and whether it is read-only."""
    return field(default=default, metadata={'doc': doc, 'read_only': read_only})


@dataclass(frozen=True)
class PipelineParams:
    """The node-only parameters that shape the pipeline's outputs: defaults and meanings."""

    wrench_frame_id: str = _param(
        'com_world_aligned', 'frame_id of reports and wrench/leg polytopes: '
        'origin at the CoM, world-aligned axes (REP 103)')
    marker_frame_id: str = _param(
        '', "frame of the markers: '' = wrench_frame_id (set it as RViz's fixed "
        'frame, no TF needed), or the URDF root link (e.g. base_link) to overlay '
        'the robot model')
    stale_timeout_s: float = _param(
        0.5, 'imu/odom older than this w.r.t. the joint-state stamp, or any input '
        'stamped more than this later than it (clocks that disagree), give a '
        'STATUS_STALE_INPUT report [s]; 0 disables the check (contacts: '
        'contacts_timeout_s)')
    fws_rate_hz: float = _param(
        10.0, 'rate of the FWS computation (H-rep, Euclidean margin and witness; the '
        'directional margins with one or two stance legs: three or more have them every '
        'cycle, by LPs) by joint-state stamps [Hz]; 0 = every cycle; a stance change '
        'forces it')
    fws_lag_s: float = _param(
        0.0, 'FWS off the joint-state loop [s]: an FWS due at stamp t is computed beside '
        'the loop (the node: in a worker process, or in steps between joint states with '
        'fws_worker false) and enters the reports from the '
        'first joint state stamped >= t + fws_lag_s, the same in the node and the '
        'replay; after a stance change, until its FWS arrives, fws_* are NaN (but the '
        'directional margins with three or more legs) and '
        "feasible is this cycle's verdict (fwp_feasible without one: one leg, a singular "
        'leg); 0 = in the loop, in the cycle it is due')
    marker_rate_hz: float = _param(
        30.0, 'marker publication rate by joint-state stamps [Hz]; 0 = no markers')
    marker_force_scale: float = _param(
        0.0005, 'scene length per newton of the drawn polytopes and wrench [m/N]')
    marker_moment_scale: float = _param(
        0.002, 'scene length per newton-metre of the drawn moment [m/(N.m)]')
    use_imu: bool = _param(
        False, 'subscribe to imu (sensor_msgs/Imu, mounting from the URDF frame '
        'header.frame_id): the base orientation and, with motion measured (auto), '
        'its angular velocity and specific force (read-only)', read_only=True)
    use_joint_velocities: bool = _param(
        True, 'use joint_states velocities (Coriolis terms of the bias torques, '
        'seed eq. 1)')
    max_queue_delay_s: float = _param(
        0.0, 'load shedding: a joint state that waited longer than this in the '
        'input queue (the node is slower than its input) is answered at once with '
        'a STATUS_STALE_INPUT report instead of being evaluated, so latency stays '
        'bounded and the queue never overflows [s]; 0 = evaluate every joint '
        'state however late')
    use_odometry: bool = _param(
        False, 'subscribe to odom (nav_msgs/Odometry): base twist in '
        'child_frame_id, and the base orientation when there is no IMU '
        '(read-only)', read_only=True)
    motion: str = _param(
        'auto', "what the wrench and leg biases are computed for: 'measured' (the "
        'motion of the IMU, odometry and differentiated joint velocities: w = [m '
        "(cdd - g); dL/dt], biases with M qdd + c), 'quasi_static' (no "
        'accelerations: w = [0, 0, m g, 0, 0, 0] plus, with use_joint_velocities, '
        "the velocity-product terms) or 'auto' (measured when use_imu or "
        'use_odometry)')
    acceleration_cutoff_hz: float = _param(
        100.0, 'cut-off of the causal 2nd-order Butterworth differentiators of '
        'the joint velocities and the IMU angular velocity [Hz]; lag sqrt(2) / (2 '
        'pi f_c) (2.25 ms at 100 Hz)')
    use_joint_efforts: bool = _param(
        True, 'use joint_states efforts: measured contact forces, slip margins, '
        'torque ratios and the external wrench')
    hull_tolerance: float = _param(
        3.0, "distance of the wrench from a flat set's affine hull (1-2 stance "
        'legs) up to which it counts as on the hull [N, N.m]: a measured wrench '
        'is on the 5D hull of two stance legs only up to its estimation error '
        '(measured: max 1.6 on the default bag, 2 in the analytic-motion test), '
        'so 3 by default; 0 = the feasibility tolerance (1e-6)')
    contact_source: str = _param(
        'topic', "where the stance comes from: 'topic' (the contacts topic, "
        "awp_ros_msgs/ContactState), 'effort' (from joint_states efforts: a foot "
        'is in stance while the normal component n . f of its measured contact '
        'force f = J^-T (b - tau) is above the thresholds below; needs efforts, '
        "no contacts topic) or 'all' (every foot in stance, for standing tests; "
        'no contacts topic) (read-only)', read_only=True)
    contact_force_on_n: float = _param(
        20.0, "contact_source 'effort': a swing foot touches down when its "
        'measured normal force rises above this [N]')
    contact_force_off_n: float = _param(
        10.0, "contact_source 'effort': a stance foot lifts off when its measured "
        'normal force falls below this (<= contact_force_on_n: the hysteresis '
        'that keeps a foot from chattering) [N]')
    contacts_timeout_s: float = _param(
        0.0, 'a contacts message holds until the next one (publishers that '
        'publish on change); > 0: contacts older than this w.r.t. the joint-state '
        'stamp give a STATUS_STALE_INPUT report [s]')
    joint_states_timeout_s: float = _param(
        0.1, 'joint_states messages may carry subsets of the joints (several '
        "publishers): each joint's latest value is used, and a joint state is "
        'evaluated when every model joint has a value stamped at most this long '
        'before it, else STATUS_STALE_INPUT naming the joints [s]; 0 = any age')
    ignored_joints: tuple[str, ...] = _param(
        (), 'joints in joint_states that the model does not have and that are '
        'ignored silently (wheels, an arm); other such joints are ignored too, '
        'listed once in /diagnostics')

    @property
    def measured_motion(self) -> bool:
        """Return whether the wrench and leg biases come from the measured motion."""
        if self.motion == 'auto':
            return self.use_imu or self.use_odometry
        return self.motion == 'measured'

    def __post_init__(self) -> None:
        """Validate every field (raise ConfigError naming the bad value)."""
        if self.motion not in MOTIONS:
            raise ConfigError(f"motion must be one of {', '.join(MOTIONS)}, got {self.motion!r}")
        if self.contact_source not in CONTACT_SOURCES:
            raise ConfigError(f"contact_source must be one of {', '.join(CONTACT_SOURCES)}, "
                              f'got {self.contact_source!r}'
                              + close_matches(str(self.contact_source), CONTACT_SOURCES))
        if not all(isinstance(j, str) and j for j in self.ignored_joints):
            raise ConfigError(f'ignored_joints must be a list of joint names, got '
                              f'{list(self.ignored_joints)!r}')
        for name in ('stale_timeout_s', 'fws_rate_hz', 'fws_lag_s', 'marker_rate_hz',
                     'max_queue_delay_s',
                     'hull_tolerance', 'contact_force_on_n', 'contact_force_off_n',
                     'contacts_timeout_s', 'joint_states_timeout_s'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ConfigError(f'{name} must be a finite number >= 0, got {value!r}')
        for name in ('marker_force_scale', 'marker_moment_scale', 'acceleration_cutoff_hz'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ConfigError(f'{name} must be a finite number > 0, got {value!r}')
        if not isinstance(self.wrench_frame_id, str) or not self.wrench_frame_id.strip():
            raise ConfigError(f'wrench_frame_id must be a non-empty frame name, got '
                              f'{self.wrench_frame_id!r}')
        if not isinstance(self.marker_frame_id, str):
            raise ConfigError(f'marker_frame_id must be a string, got {self.marker_frame_id!r}')
        if self.contact_force_off_n > self.contact_force_on_n:
            raise ConfigError(f'contact_force_off_n ({self.contact_force_off_n:g} N) must not '
                              f'exceed contact_force_on_n ({self.contact_force_on_n:g} N): the '
                              'foot touches down above on and lifts off below off')

    @classmethod
    def from_dict(cls, params: Mapping) -> PipelineParams:
        """
        Read the known keys of a parameters mapping; other keys are ignored.

        The mapping is a params file, its ``ros__parameters`` section, or a flat mapping.

        :raises ConfigError: a value of the wrong type or range.
        """
        flat = ros_parameters(params)
        kw = {}
        for f in fields(cls):
            if f.name in flat:
                value = flat[f.name]
                default = f.default
                if isinstance(default, bool):
                    if not isinstance(value, bool):
                        raise ConfigError(f'{f.name} must be true or false, got {value!r}')
                elif isinstance(default, float):
                    if isinstance(value, bool) or not isinstance(value, (int, float)):
                        raise ConfigError(f'{f.name} must be a number, got {value!r}')
                    value = float(value)
                elif isinstance(default, tuple):
                    if isinstance(value, str) or not hasattr(value, '__iter__'):
                        raise ConfigError(f'{f.name} must be a list, got {value!r}')
                    value = tuple(value)
                kw[f.name] = value
        return cls(**kw)


#: Description of every pipeline parameter (the node's descriptors and the README).
PARAMETER_DOCS = {f.name: f.metadata['doc'] for f in fields(PipelineParams)}


def _kind(default) -> str:
    """Return the schema kind of a default value."""
    if isinstance(default, bool):
        return 'bool'
    if isinstance(default, float):
        return 'double'
    if isinstance(default, int):
        return 'integer'
    if isinstance(default, tuple):
        return 'string_array'
    return 'string'


#: Read-only pipeline parameters (they decide which topics the node subscribes to).
READ_ONLY = tuple(f.name for f in fields(PipelineParams) if f.metadata['read_only'])

#: The pipeline's keys of the parameters schema (from PipelineParams and PARAMETER_DOCS).
PIPELINE_KEYS: dict[str, ConfigKey] = {
    f.name: ConfigKey(_kind(f.default), f.default, f.metadata['doc'], group='pipeline',
                      read_only=f.metadata['read_only'])
    for f in fields(PipelineParams)}

_NODE = {     # name: (default, description, read-only)
    'robot': ('', "robot config name or YAML path to start from ('' = the robot keys given "
              'as parameters, else hyq)', True),
    'robot_description': ('', 'URDF XML (as robot_state_publisher takes it); replaces urdf '
                          'when non-empty', False),
    'qos_depth': (10000, 'keep-last depth of the input subscriptions and the report publisher '
                  '(10000 = 10 s of 1 kHz joint states of backlog)', True),
    'qos_reliability': ('reliable', "input QoS reliability: 'reliable' or 'best_effort' "
                        '(matches best-effort publishers)', True),
    'contacts_durability': ('volatile', "durability of the contacts subscription: 'volatile' "
                            "or 'transient_local' (receives the last contacts message of a "
                            'transient-local publisher that published it before the node '
                            'started: on-change publishers; does not match a volatile '
                            'publisher)', True),
    'executor': ('single_threaded', "rclpy executor: 'single_threaded' or 'events' "
                 '(rclpy.experimental.EventsExecutor)', True),
    'diagnostics_period_s': (1.0, 'period of /diagnostics [s]', True),
    'drain_budget_s': (0.02, 'after a joint state, the node takes the next ones straight from '
                       'the input queues (and waits for them) for up to this long before '
                       'returning to the rclpy executor (timers, parameter services): ~0.2 ms '
                       'less per message [s]; 0 = only those queued', True),
    'marker_worker': (True, 'build the markers in a worker process (off the joint-state loop; '
                      '~3 ms each); a marker due while two wait for the worker is skipped and '
                      'counted in /diagnostics; false = in the node', True),
    'fws_worker': (True, 'with fws_lag_s > 0, compute the FWS in a worker process (beside the '
                   'node, on another core); false = in the node, in steps of about 0.2 ms between '
                   'joint states and in its idle time (no second process; the FWS costs the '
                   "node's own core)", True),
    'evaluate_yield': (True, 'the ~/evaluate computation (a process at SCHED_IDLE) is '
                       'stopped while the node handles a joint state, so a query never '
                       'competes with the stream for the cores and caches (it waits while the '
                       'node is busy); false = it runs beside the node at SCHED_IDLE', True),
    'blas_threads': (1, 'threads of the BLAS under numpy/scipy in this process '
                     '(threadpoolctl); 1 avoids the stalls of busy-waiting BLAS threads on '
                     'cores shared with DDS and other processes; 0 = leave as is', True),
    'main_thread_cpu': (-1, 'run the thread that answers the joint states (the executor, '
                        'the evaluation, the reports) on this CPU only, from the end of '
                        'the startup (Linux CPU affinity); Fast DDS threads keep every CPU '
                        'and worker processes started later get the others; -1 = not '
                        'pinned', True),
}
#: The node-only keys of the parameters schema (``awp_node``; the replay ignores them).
NODE_KEYS: dict[str, ConfigKey] = {
    name: ConfigKey(_kind(default), default, doc, group='node', read_only=ro)
    for name, (default, doc, ro) in _NODE.items()}
