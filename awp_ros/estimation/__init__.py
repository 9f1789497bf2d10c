"""
Motion estimation (ROS-free): what the robot's accelerations are at each joint state.

- :mod:`filters`: a causal differentiator (2nd-order Butterworth, irregular stamps, lag).
- :mod:`imu`: the IMU's mounting from the URDF and the base motion an IMU reading implies.
- :mod:`motion`: MotionEstimator, joint states + IMU (+ odometry) -> RobotState motion.
"""

__all__ = ['filters', 'imu', 'motion']
