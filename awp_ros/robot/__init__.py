"""
The robot (ROS-free): configuration, Pinocchio model, state.

- :mod:`parameters`: the parameters schema (robot, pipeline and node keys), PipelineParams.
- :mod:`config`: RobotConfig, config files and their lookup.
- :mod:`model`: the Pinocchio model, leg chains, kinematics and dynamics terms.
- :mod:`state`: RobotState (what one evaluation answers) and its validation.
"""

__all__ = ['parameters', 'config', 'model', 'state']
