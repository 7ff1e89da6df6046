"""The `dampnet` command line.

Each subcommand lives in its own module under `dampnet.commands`, exposing
`add_parser(subparsers)` which registers the parser and sets `handler`.
Add a command by adding its module name to COMMANDS. Handlers return the exit
status: 0 success, 1 a check failed (e.g. a budget missed), 2 bad input (one
line on stderr, `dampnet: error: ...`).
"""

from __future__ import annotations

import argparse
import importlib
import sys

# Module names under dampnet.commands, in the order `dampnet --help` lists them.
COMMANDS = ["demo", "rig", "train", "evaluate", "compare_algorithms", "diagnose", "compare", "export",
            "simulate", "study", "vehicle", "plan_tests", "sweep", "iri", "bench", "info"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="dampnet",
        description="Neural damper models from shock-dyno data: train, diagnose, export, "
                    "simulate, and check real-time latency. Units are SI.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"dampnet.commands.{name}")
        except ModuleNotFoundError as e:
            if e.name == f"dampnet.commands.{name}":
                continue  # not built yet
            raise
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.version:
        from dampnet import __version__

        print(f"dampnet {__version__}")
        return 0
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help()
        return 2
    try:
        return int(handler(args) or 0)
    except KeyboardInterrupt:
        print("dampnet: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
