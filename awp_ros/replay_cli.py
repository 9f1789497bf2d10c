"""Placeholder entry point, replaced by its issue's implementation."""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    """Parse arguments; the behaviour lands with its issue."""
    parser = argparse.ArgumentParser(prog='replay_cli', description='awp_ros replay_cli (not yet implemented)')
    parser.parse_args(argv)
    sys.stderr.write('replay_cli: not implemented yet\n')
    return 1


if __name__ == '__main__':
    sys.exit(main())
