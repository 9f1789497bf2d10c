"""
The thin command-line programs: argument parsing and main() only.

- :mod:`support`: run_main (errors to exit statuses).
- :mod:`eval`: awp_eval.
- :mod:`replay`: awp_replay.
- :mod:`bench`: awp_bench.
- :mod:`pipeline_bench`: python -m awp_ros.cli.pipeline_bench.
- :mod:`param`: awp_param (a running node's parameters, without the ros2 CLI).
"""

__all__ = ['support', 'eval', 'replay', 'bench', 'pipeline_bench', 'param']
