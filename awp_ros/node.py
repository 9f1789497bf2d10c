"""Placeholder entry point, replaced by its issue's implementation."""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    """Parse arguments; the behaviour lands with its issue."""
    parser = argparse.ArgumentParser(prog='node', description='awp_ros node (not yet implemented)')
    parser.parse_args(argv)
    sys.stderr.write('node: not implemented yet\n')
    return 1


if __name__ == '__main__':
    sys.exit(main())
