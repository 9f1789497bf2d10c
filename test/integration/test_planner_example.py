"""The README's planner example, ``examples/planner_client.py``, against a real awp_node."""

import subprocess
import sys

from awp_ros.node.launcher import start_node, stop_node
from awp_ros.robot.config import find_parameters_file

README_OUTPUT = 'Output (nothing publishes joint states here, so no live margins):'


def test_the_planner_example_prints_what_the_readme_shows(ros_env, repo):
    """Run as the README says (the node with config/hyq.yaml, then the example): same text."""
    text = (repo / 'README.md').read_text()
    assert text.count(README_OUTPUT) == 1
    shown = text.split(README_OUTPUT, 1)[1].split('```', 2)[1].strip('\n')
    proc = start_node(env=ros_env, robot=None, params_file=find_parameters_file('hyq'))
    try:
        run = subprocess.run([sys.executable, str(repo / 'examples' / 'planner_client.py')],
                             env=ros_env, cwd=repo, capture_output=True, text=True,
                             timeout=300)
    finally:
        log = stop_node(proc)
    assert run.returncode == 0, run.stdout + run.stderr + log
    assert run.stdout.strip('\n') == shown
    assert 'Traceback' not in log, log
