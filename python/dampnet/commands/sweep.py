"""`dampnet sweep SPEC.toml`: many trainings and simulations on Dask (dampnet.sweep)."""

from __future__ import annotations

import argparse


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "sweep", help="run a grid of trainings, quarter-car and/or full-vehicle simulations on Dask",
        description="Run every cell of SPEC.toml (a grid and/or random samples over training, quarter-car and "
                    "full-vehicle simulation settings) on Dask: an embedded cluster of this machine's cores, or an "
                    "existing cluster (--scheduler). Writes DIR/results.parquet and .csv (one row per cell), "
                    "summary.json and summary.txt (the best cells), sensitivity_*.png, one model directory per training cell, "
                    "and each cell's result as it finishes (DIR/cells), so --resume continues an interrupted "
                    "sweep. Progress (cells done, errors, time left) goes to stderr.")
    p.add_argument("spec", metavar="SPEC.toml", help="the sweep's spec (TOML; docs/sweeps.md)")
    p.add_argument("--out", default="sweep_out", metavar="DIR", help="the sweep directory (default sweep_out)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS|FILE",
                   help="an existing Dask cluster: its scheduler's address, e.g. tcp://host:8786, or the scheduler "
                        "file it wrote (dask scheduler --scheduler-file FILE; the usual way on HPC job queues); "
                        "its workers must run this dampnet (checked). Default: an embedded local cluster")
    p.add_argument("--worker-timeout", type=float, default=None, metavar="S",
                   help="stop (state interrupted; --resume continues) when the cluster has had no worker for S "
                        "seconds (default 600; inf: wait as long as it takes); a line says so after 10 s")
    p.add_argument("--max-cells", type=int, default=None, metavar="N",
                   help="the most cells the spec may make (default 100000, at most 10000000): a larger spec is "
                        "refused before any work")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the embedded cluster, one thread each (default: this machine's cores)")
    p.add_argument("--data", choices=("shared", "ship"), default=None,
                   help="how workers get datasets and models: by path on a shared filesystem (shared), or "
                        "shipped once to every worker (ship); default: the spec's [sweep] data, else shared")
    p.add_argument("--resume", action="store_true",
                   help="continue the sweep in DIR: skip the cells it finished, compute the others")
    p.add_argument("--force", action="store_true", help="replace DIR (a previous sweep) if it exists")
    p.add_argument("--quiet", action="store_true", help="no progress and no summary")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.commands.common import error

    if args.workers is not None and args.scheduler:
        return error("--workers: sets the embedded cluster's size; with --scheduler the cluster has its own workers")
    try:
        from dampnet.sweep import run as run_sweep
        from dampnet.sweep.runner import SweepError

        from dampnet.sweep.grid import MAX_CELLS
        from dampnet.sweep.runner import WORKER_TIMEOUT_S

        df = run_sweep(args.spec, out=args.out, resume=args.resume, force=args.force, workers=args.workers,
                       scheduler=args.scheduler, data=args.data, progress=not args.quiet,
                       worker_timeout=WORKER_TIMEOUT_S if args.worker_timeout is None else args.worker_timeout,
                       max_cells=MAX_CELLS if args.max_cells is None else args.max_cells)
    except (SweepError, ValueError, OSError) as e:   # SpecError, OutputError: ValueErrors
        return error(str(e))
    except KeyboardInterrupt as e:      # Ctrl-C, or SIGTERM (dampnet.signals.Terminated)
        import sys

        from dampnet import signals

        terminated = isinstance(e, signals.Terminated)
        print(f"dampnet: {'terminated' if terminated else 'interrupted'}: the finished cells are saved in {args.out}; the same command with "
              "--resume computes the others", file=sys.stderr)
        return signals.TERMINATED_STATUS if terminated else signals.INTERRUPTED_STATUS
    if not args.quiet:
        from pathlib import Path

        text = (Path(args.out) / "summary.txt").read_text(encoding="utf-8")
        print(text, end="")
        print(f"-> {args.out}/results.parquet, results.csv, summary.json")
    return 1 if (df["status"] != "ok").all() else 0
