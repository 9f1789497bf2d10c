"""awp_ros: actuation-consistent and feasible wrench polytopes of legged robots.

The core (every module but ``node``, ``pipeline``, ``conversions``, ``markers``,
``diagnostics``, ``replay*``, ``bag_io`` and ``demo``) is ROS-free: it needs numpy, scipy and
Pinocchio only. Typical use::

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
