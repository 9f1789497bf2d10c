"""Code style: ament_flake8 (ROS 2's flake8 linter) on the package, tests, examples, setup.py."""

from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

REPO = Path(__file__).resolve().parent.parent


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch):
    # ament_flake8 walks the current directory for folders to exclude (AMENT_IGNORE, dot- and
    # underscore-folders): run it from the repository, whatever pytest's working directory.
    monkeypatch.chdir(REPO)
    rc, errors = main_with_errors(argv=[
        '--config', str(REPO / 'setup.cfg'),
        str(REPO / 'awp_ros'), str(REPO / 'test'), str(REPO / 'examples'),
        str(REPO / 'setup.py'),
    ])
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)
