"""
The feasibility evaluator (ROS-free): one state in, every set and margin out.

- :mod:`evaluator`: FeasibilityEvaluator, the per-cycle stages.
- :mod:`result`: FeasibilityResult, LegResult, WrenchSetResult.
- :mod:`compare_sets`: how much of the FWP lies outside the FWS (hit-and-run).
"""

__all__ = ['evaluator', 'result', 'compare_sets']
