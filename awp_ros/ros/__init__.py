"""
ROS 2 messages around the core, without a node: what awp_node and awp_replay share.

- :mod:`conversions`: messages <-> core values (states, polytopes, reports).
- :mod:`markers`: visualization_msgs/MarkerArray of a result.
- :mod:`cycle`: the outputs of one joint state, built on demand.
- :mod:`pipeline`: messages in, outputs out; every decision by message stamps.
- :mod:`input_buffer`: pairing contacts / imu messages with joint states by stamp.
- :mod:`joint_merge`: joint states carrying subsets of the joints, merged.
- :mod:`contact_source`: the stance from joint efforts (``contact_source: effort``).
"""

__all__ = ['conversions', 'markers', 'cycle', 'pipeline', 'input_buffer',
           'joint_merge', 'contact_source']
