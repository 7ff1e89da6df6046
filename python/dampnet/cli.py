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
    _refuse_repeats(parser)
    return parser


def _once(cls: type) -> type:
    """`cls` (an argparse store action) refusing a second value for its option: argparse keeps
    the last silently, so `vehicle --speed 80 --speed 90` ran at 90 (issue 49)."""

    class Once(cls):  # type: ignore[misc, valid-type]
        def __call__(self, parser, namespace, values, option_string=None):
            seen = namespace.__dict__.setdefault("_options_given", set())
            if self.dest in seen:
                raise argparse.ArgumentError(self, "given twice: give it once")
            seen.add(self.dest)
            super().__call__(parser, namespace, values, option_string)

    return Once


def _refuse_repeats(parser: argparse.ArgumentParser) -> None:
    """Every option that stores one value, in every command, refuses to be given twice."""
    once = _once(argparse._StoreAction)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in set(action.choices.values()):
                _refuse_repeats(sub)
        elif type(action) is argparse._StoreAction and action.option_strings:
            action.__class__ = once


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    vars(args).pop("_options_given", None)
    if args.version:
        from dampnet import __version__

        print(f"dampnet {__version__}")
        return 0
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help()
        return 2
    from dampnet import signals

    signals.terminate_as_exception()    # SIGTERM cleans up as Ctrl-C does (dampnet.signals)
    try:
        return int(handler(args) or 0)
    except KeyboardInterrupt as e:      # Ctrl-C, or SIGTERM (signals.Terminated)
        return _stopped(e)
    except Exception as e:
        stop = interrupt_behind(e)
        if stop is None:
            raise
        return _stopped(stop)
    finally:
        signals.default_handlers()      # a signal while Python shuts down ends it, no traceback


def interrupt_behind(e: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (or signals.Terminated) that `e` was raised from or during, if any. A
    signal that arrives while a C extension initialises comes back as that extension's own error:
    pybind11 modules (scipy's HiGHS among them) raise ImportError('initialization failed') from it."""
    seen: set[int] = set()
    cur: BaseException | None = e
    while cur is not None and id(cur) not in seen:
        if isinstance(cur, KeyboardInterrupt):
            return cur
        seen.add(id(cur))
        cur = cur.__cause__ or cur.__context__
    return None


def _stopped(stop: KeyboardInterrupt) -> int:
    """The one line and the exit status of a run that a signal stopped."""
    from dampnet import signals

    if isinstance(stop, signals.Terminated):
        print("dampnet: terminated", file=sys.stderr)
        return signals.TERMINATED_STATUS
    print("dampnet: interrupted", file=sys.stderr)
    return signals.INTERRUPTED_STATUS


if __name__ == "__main__":
    sys.exit(main())
