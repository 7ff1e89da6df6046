"""The `dampnet` command line."""

from __future__ import annotations

import argparse
import sys


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="dampnet", description=__doc__)
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command")
    sub.add_parser("info", help="print the runtime's version and build facts")
    args = parser.parse_args(argv)
    if args.version or args.command == "info":
        from dampnet import __version__, _core

        print(f"dampnet {__version__} (C++ core {_core.__version__})")
        return 0
    parser.print_help()
    return 2


if __name__ == "__main__":
    sys.exit(main())
