"""Shared fixtures: an isolated ROS 2 environment per test, and the repository's paths."""

from __future__ import annotations

import itertools
import os
from pathlib import Path
import random
import sys

import pytest

REPO = Path(__file__).resolve().parent.parent
# The shared test cases (test/cases.py) import as `cases` from every test folder. Test file
# names are unique across folders (pytest imports them by basename).
sys.path.insert(0, str(Path(__file__).resolve().parent))
_domain_ids = itertools.count(random.Random(os.getpid()).randrange(1, 101))


@pytest.fixture
def ros_env() -> dict[str, str]:
    """
    Return os.environ with DDS kept on this machine and a ROS domain of this test's own.

    Each test gets the next domain id (1..101, starting at a per-run random offset), so that
    node processes of two tests, or of two test runs, never discover each other.
    """
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['ROS_DOMAIN_ID'] = str(next(_domain_ids) % 101 + 1)
    env['PYTHONUNBUFFERED'] = '1'
    return env


@pytest.fixture(scope='session')
def repo() -> Path:
    """Return the repository root."""
    return REPO
