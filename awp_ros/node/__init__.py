"""
The awp_node process: an rclpy shell over awp_ros.ros.pipeline.

- :mod:`node`: AwpNode and main() of the awp_node executable.
- :mod:`parameters`: declaring, validating (on-set) and applying (post-set) its parameters.
- :mod:`input_drain`: taking queued input messages past the rclpy executor.
- :mod:`marker_worker`: building marker arrays in a worker process.
- :mod:`fws_worker`: the FWS in a worker process (``fws_lag_s`` > 0).
- :mod:`diagnostics`: counters and the /diagnostics DiagnosticArray.
- :mod:`launcher`: start and stop awp_node as a process (tests, soak, demo).
- :mod:`evaluate_service`: the ~/evaluate worker process (queries beside the live stream).
- :mod:`evaluate_compute`: its child process evaluating the queries (no DDS).
- :mod:`yield_gate`: how the node stops that child while it answers joint states.
- :mod:`lifecycle`: rclpy init, spin and shutdown of both processes.
- :mod:`dds`: the Fast DDS profile that lets the input queues hold ``qos_depth``.
"""

__all__ = ['node', 'parameters', 'input_drain', 'marker_worker', 'fws_worker', 'diagnostics',
           'launcher', 'evaluate_service', 'evaluate_compute', 'yield_gate', 'lifecycle', 'dds']
