"""
awp_ros: actuation-consistent and feasible wrench polytopes of legged robots.

``import awp_ros`` gives the ROS-free library (numpy, scipy, Pinocchio; no rclpy, no
message packages)::

    from awp_ros import FeasibilityEvaluator
    evaluator = FeasibilityEvaluator('hyq')
    result = evaluator.evaluate(evaluator.standing_state())
    result.fwp.margin, result.fws.margin, result.feasible

The subpackages, lowest first (each imports only those above it):

- :mod:`awp_ros.geometry`: polytopes, exact Minkowski-sum facets, margins;
- :mod:`awp_ros.wrench`: force and friction polytopes, CWC, AWP / FWP, FWS;
- :mod:`awp_ros.robot`: robot configs, the Pinocchio model, robot states;
- :mod:`awp_ros.evaluation`: the evaluator and its results.

The ROS 2 side, which needs rclpy and the generated messages:

- :mod:`awp_ros.ros`: message conversions, markers and the pipeline shared by node and replay;
- :mod:`awp_ros.node`: the ``awp_node`` process (parameters, input drain, diagnostics);
- :mod:`awp_ros.bags`: rosbag2 files and the offline replay;
- :mod:`awp_ros.gait`, :mod:`awp_ros.demo`, :mod:`awp_ros.soak`: the default bag's gait
  generator, ``awp_demo``, the load tests;
- :mod:`awp_ros.cli`: the thin command-line programs.

Package-wide: :mod:`awp_ros.errors` (every exception the package raises) and
:mod:`awp_ros.runtime` (process tuning for the executables).
"""

from __future__ import annotations

from awp_ros.errors import (AwpError, BagError, ConfigError, GeometryError, InputError,
                            ModelError, ProcessError)
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.evaluation.result import AXES, FeasibilityResult, LegResult, WrenchSetResult
from awp_ros.geometry.margin import directional_margins, polytope_margin, SetMargin
from awp_ros.geometry.polytope import Polytope
from awp_ros.robot.config import available_configs, load_config, RobotConfig
from awp_ros.robot.model import RobotModel
from awp_ros.robot.state import RobotState
from awp_ros.wrench.force_polytope import force_polytope
from awp_ros.wrench.friction_polytope import friction_polytope

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
    'ProcessError',
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
