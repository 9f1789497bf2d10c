"""
The gait generator of the default bag: balanced crawl and trot, an infeasible lurch, IMU.

- :mod:`generator`: GaitSamples and generate_gait (the motion, its timeline).
- :mod:`params`: GaitParams, the gaits' names.
- :mod:`plan`: footholds, swings, nominal body path and ZMP windows of each gait.
- :mod:`balance`: the ZMP planner of the CoM (cart-table model, least squares).
- :mod:`dynamics`: CoM, angular momentum, contact wrench and ZMP of sampled motion.
- :mod:`curves`: minimum-jerk and cycloid curves.
- :mod:`kinematics`: whole-body inverse kinematics on the Pinocchio model.
- :mod:`bag`: the gait's messages and the default bag file.
"""

__all__ = ['generator', 'params', 'plan', 'balance', 'dynamics', 'curves', 'kinematics',
           'bag']
