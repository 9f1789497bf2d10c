"""
ROS 2 messages around the core, without a node: what awp_node and awp_replay share.

- :mod:`conversions`: messages <-> core values (states, polytopes, reports).
- :mod:`markers`: visualization_msgs/MarkerArray of a result.
- :mod:`cycle`: the outputs of one joint state, built on demand.
- :mod:`pipeline`: messages in, outputs out; every decision by message stamps.
- :mod:`pipeline_params`: PipelineParams, their descriptions, the ros__parameters loader.
- :mod:`input_buffer`: pairing contacts / imu messages with joint states by stamp.
"""

__all__ = ['conversions', 'markers', 'cycle', 'pipeline', 'pipeline_params', 'input_buffer']
