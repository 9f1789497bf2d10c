"""
The gait generator of the default bag: crawl and trot postures, contacts, IMU.

- :mod:`generator`: GaitParams and generate_gait.
- :mod:`plan`: footstep and body plans of each gait.
- :mod:`curves`: minimum-jerk and cycloid curves.
- :mod:`kinematics`: inverse kinematics on the Pinocchio model.
- :mod:`bag`: the gait's messages and the default bag file.
"""

__all__ = ['generator', 'plan', 'curves', 'kinematics', 'bag']
