"""Docstring style: ament_pep257 (ROS 2's linter) on the package, tests, examples, setup.py."""

from pathlib import Path

from ament_pep257.main import main
import pytest

REPO = Path(__file__).resolve().parent.parent


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc = main(argv=[str(REPO / 'awp_ros'), str(REPO / 'test'), str(REPO / 'examples'),
                    str(REPO / 'setup.py')])
    assert rc == 0, 'Found code style errors / warnings'
