"""`dampnet compare-algorithms DATA`: the thesis's Table 3 for dampnet (NRMSE and training time per algorithm).

Every algorithm trains on the same data, hold-out, decimation, seed and hence the same
70/15/15 split; NRMSE is reported on fit()'s random 15 % test subset (the thesis's
Table 3) and on the held-out tests, with the lookup-table baseline's hold-out NRMSE beside.
"""

from __future__ import annotations

import argparse
import time

from dampnet.commands.common import error
from dampnet.commands.training_options import (
    Progress,
    add_training_options,
    training_kwargs,
)


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "compare-algorithms", help="train with each algorithm on the same split (thesis Table 3)",
        description="Train the same network with lm, br, scg and adam on the same split and report "
                    "NRMSE and training time per algorithm (the thesis's Table 3).")
    p.add_argument("data", help="dataset: a directory, CSV/text file or .mat file")
    p.add_argument("--algorithms", default="lm,br,scg,adam", help="comma-separated (default lm,br,scg,adam)")
    add_training_options(p, algorithm=False)
    p.add_argument("--json", metavar="FILE", help="write the table as JSON")
    p.add_argument("--force", action="store_true", help="replace the JSON file if it exists")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(handler=run)
    return p


def compare_algorithms(ds, algorithms, progress_factory=None, **kw) -> dict:
    """{"rows": [{algorithm, nrmse_test, nrmse_holdout, time_s, epochs, stop_reason}], "lookup_holdout_nrmse"}."""
    from dampnet.evaluation.lookup import fit_lookup
    from dampnet.evaluation.metrics import evaluate_model
    from dampnet.predict import predict_force
    from dampnet.training.pipeline import train_dataset

    rows, split = [], None
    for algo in algorithms:
        bar = progress_factory(algo) if progress_factory else None
        t0 = time.perf_counter()
        model, info, split = train_dataset(ds, algorithm=algo, progress=bar, **kw)
        wall = time.perf_counter() - t0
        if bar is not None:
            bar.close()
        row = {"algorithm": algo, "nrmse_test": info.metrics.get("test"), "nrmse_val": info.metrics.get("val"),
               "time_s": info.time_s, "wall_time_s": wall, "epochs": info.epochs,
               "stop_reason": info.stop_reason}
        if split.holdout is not None:
            row["nrmse_holdout"] = evaluate_model(lambda t: predict_force(model, t),
                                                  split.holdout.tests)["overall"]["nrmse"]
        rows.append(row)
    out = {"rows": rows, "n_train_samples": None if split is None else len(split.train_used.concat("force")),
           "decimate": None if split is None else split.decimate}
    if split is not None and split.holdout is not None:
        table = fit_lookup(split.train)
        out["lookup_holdout_nrmse"] = evaluate_model(table.predict_test, split.holdout.tests)["overall"]["nrmse"]
    return out


def run(args) -> int:
    from dampnet.data import DataError, load_dataset
    from dampnet.model import ModelError
    from dampnet.outputs import write_json
    from dampnet.training import ALGORITHMS

    algos = [a.strip() for a in args.algorithms.split(",") if a.strip()]
    bad = [a for a in algos if a not in ALGORITHMS]
    if bad or not algos:
        return error(f"--algorithms: unknown {bad}; expected some of {', '.join(sorted(ALGORITHMS))}")
    from dampnet.outputs import check_output_file

    try:
        if args.json:
            check_output_file(args.json, [args.data])
        ds = load_dataset(args.data)
        kw, _ = training_kwargs(args, ds)
        res = compare_algorithms(ds, algos, lambda a: Progress(kw["max_epochs"], f"train {a}", not args.quiet),
                                 **kw)
        if args.json:
            write_json(args.json, res, overwrite=args.force)
    except (DataError, ModelError, FileExistsError, ValueError, OSError) as e:
        return error(str(e))
    print(f"{'algorithm':>9}  {'NRMSE test':>10}  {'NRMSE hold-out':>14}  {'time [s]':>8}  {'epochs':>6}  stop")
    for r in res["rows"]:
        ho = r.get("nrmse_holdout")
        print(f"{r['algorithm']:>9}  {r['nrmse_test']:>10.4f}  {'-' if ho is None else f'{ho:.4f}':>14}  "
              f"{r['time_s']:>8.1f}  {r['epochs']:>6}  {r['stop_reason']}")
    if "lookup_holdout_nrmse" in res:
        print(f"lookup-table baseline, hold-out NRMSE {res['lookup_holdout_nrmse']:.4f}")
    return 0
