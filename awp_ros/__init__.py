"""awp_ros: actuation-consistent and feasible wrench polytopes of legged robots.

The core is ROS-free (numpy, scipy, Pinocchio): robot_config, robot_model, state,
force_polytope, friction_polytope, zonotope, contact_wrench_cone, wrench_polytope,
feasible_wrench_set (with sum_facets, face_lattice, exterior, fws_queries), margin, linalg,
polytope, evaluator, result, and the awp_eval / awp_bench front ends. The ROS side (rclpy,
generated messages, rosbags) is the node (node, node_params, pipeline, pipeline_params, cycle,
input_buffer, conversions, markers, diagnostics), the bag tools (bag_*, replay*, gait_bag,
live_recorder, demo) and the soak test (soak*, probe). Typical use of the core::

    from awp_ros import FeasibilityEvaluator
    evaluator = FeasibilityEvaluator('hyq')
    result = evaluator.evaluate(evaluator.standing_state())
    result.fwp.margin, result.fws.margin, result.feasible
"""

from __future__ import annotations

from .errors import AwpError, BagError, ConfigError, GeometryError, InputError, ModelError
from .evaluator import AXES, FeasibilityEvaluator, FeasibilityResult, LegResult, WrenchSetResult
from .force_polytope import force_polytope
from .friction_polytope import friction_polytope
from .margin import directional_margins, polytope_margin, SetMargin
from .polytope import Polytope
from .robot_config import available_configs, load_config, RobotConfig
from .robot_model import RobotModel
from .state import RobotState

__version__ = '0.1.0'

__all__ = [
    'AXES',
    'AwpError',
    'BagError',
    'ConfigError',
    'FeasibilityEvaluator',
    'FeasibilityResult',
    'GeometryError',
    'InputError',
    'LegResult',
    'ModelError',
    'Polytope',
    'RobotConfig',
    'RobotModel',
    'RobotState',
    'SetMargin',
    'WrenchSetResult',
    '__version__',
    'available_configs',
    'directional_margins',
    'force_polytope',
    'friction_polytope',
    'load_config',
    'polytope_margin',
]
