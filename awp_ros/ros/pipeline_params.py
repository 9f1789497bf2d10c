"""
The pipeline's parameters: :class:`PipelineParams` and their descriptions.

Shared by ``awp_node`` (its parameter descriptors) and the offline replay (a params file).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
import math

from awp_ros.errors import ConfigError
from awp_ros.robot.config import ros_parameters

__all__ = ['MOTIONS', 'PARAMETER_DOCS', 'PipelineParams']


#: Values of ``motion``: ``auto`` = ``measured`` when the IMU or odometry is on, else
#: ``quasi_static``.
MOTIONS = ('auto', 'measured', 'quasi_static')


@dataclass(frozen=True)
class PipelineParams:
    """The node-only parameters that shape the pipeline's outputs (see PARAMETER_DOCS)."""

    wrench_frame_id: str = 'com_world_aligned'
    marker_frame_id: str = ''
    stale_timeout_s: float = 0.5
    fws_rate_hz: float = 10.0
    marker_rate_hz: float = 30.0
    marker_force_scale: float = 0.0005
    marker_moment_scale: float = 0.002
    use_imu: bool = False
    use_joint_velocities: bool = True
    max_queue_delay_s: float = 0.0
    use_odometry: bool = False
    motion: str = 'auto'
    acceleration_cutoff_hz: float = 100.0
    use_joint_efforts: bool = True
    hull_tolerance: float = 3.0

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
        for name in ('stale_timeout_s', 'fws_rate_hz', 'marker_rate_hz', 'max_queue_delay_s',
                     'hull_tolerance'):
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
                kw[f.name] = value
        return cls(**kw)


#: Description of every pipeline parameter (used for the node's descriptors and the README).
PARAMETER_DOCS = {
    'wrench_frame_id': 'frame_id of reports and wrench/leg polytopes: origin at the CoM, '
                       'world-aligned axes (REP 103)',
    'marker_frame_id': "frame of the markers: '' = wrench_frame_id (set it as RViz's fixed "
                       'frame, no TF needed), or the URDF root link (e.g. base_link) to '
                       'overlay the robot model',
    'stale_timeout_s': 'contacts/imu older than this w.r.t. the joint-state stamp give a '
                       'STATUS_STALE_INPUT report [s]; 0 disables the check',
    'fws_rate_hz': 'rate of the FWS computation (H-rep, directional and Euclidean margins) '
                   'by joint-state stamps [Hz]; 0 = every cycle; a stance change forces it',
    'marker_rate_hz': 'marker publication rate by joint-state stamps [Hz]; 0 = no markers',
    'marker_force_scale': 'scene length per newton of the drawn polytopes and wrench [m/N]',
    'marker_moment_scale': 'scene length per newton-metre of the drawn moment [m/(N.m)]',
    'use_imu': 'subscribe to imu and take its orientation as the base orientation '
               '(read-only)',
    'use_joint_velocities': 'use joint_states velocities (Coriolis terms of the bias '
                            'torques, seed eq. 1)',
    'max_queue_delay_s': 'load shedding: a joint state that waited longer than this in the '
                         'input queue (the node is slower than its input) is answered at once '
                         'with a STATUS_STALE_INPUT report instead of being evaluated, so '
                         'latency stays bounded and the queue never overflows [s]; 0 = '
                         'evaluate every joint state however late',
    'use_odometry': 'subscribe to odom (nav_msgs/Odometry): base twist in child_frame_id, and '
                    'the base orientation when there is no IMU (read-only)',
    'motion': "what the wrench and leg biases are computed for: 'measured' (the motion of "
              'the IMU, odometry and differentiated joint velocities: w = [m (cdd - g); '
              "dL/dt], biases with M qdd + c), 'quasi_static' (the robot standing still: "
              "w = [0, 0, m g, 0, 0, 0]) or 'auto' (measured when use_imu or use_odometry)",
    'acceleration_cutoff_hz': 'cut-off of the causal 2nd-order Butterworth differentiators of '
                              'the joint velocities and the IMU angular velocity [Hz]; lag '
                              'sqrt(2) / (2 pi f_c) (2.25 ms at 100 Hz)',
    'use_joint_efforts': 'use joint_states efforts: measured contact forces, slip margins, '
                         'torque ratios and the external wrench',
    'hull_tolerance': "distance of the wrench from a flat set's affine hull (1-2 stance legs) "
                      'up to which it counts as on the hull [N, N.m]: a measured wrench is '
                      'on the 5D hull of two stance legs only up to its estimation error '
                      '(measured: max 1.6 on the default bag, 2 in the analytic-motion test), '
                      'so 3 by default; 0 = the feasibility tolerance (1e-6)',
}
