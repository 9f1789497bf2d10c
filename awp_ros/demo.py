"""Placeholder entry point, replaced by its issue's implementation."""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    """Parse arguments; the behaviour lands with its issue."""
    parser = argparse.ArgumentParser(prog='demo', description='awp_ros demo (not yet implemented)')
    parser.parse_args(argv)
    sys.stderr.write('demo: not implemented yet\n')
    return 1


if __name__ == '__main__':
    sys.exit(main())
