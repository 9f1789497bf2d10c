"""
Load tests of awp_node over real DDS: python -m awp_ros.soak.

- :mod:`soak`: run_soak and main().
- :mod:`driver`: the joint-state publisher process.
- :mod:`result`: SoakResult and its table.
- :mod:`probe`: a DDS participant of our own (publish, subscribe, wait).
- :mod:`monitor`: CPU and memory of a process from /proc.
- :mod:`query_load`: ~/evaluate queries beside a live stream, their effect on latency.
- :mod:`slow_machine`: a slower machine emulated on this one (real-time CPU stealers).
"""

__all__ = ['soak', 'driver', 'result', 'probe', 'monitor', 'query_load', 'slow_machine']
