"""`dampnet evaluate MODEL DATA`: error tables (thesis Tables 3-4) beside the lookup-table baseline.

JSON (--json FILE, stable keys): model, data, overall {nrmse, rmse_n, max_abs_error_n,
mean_pct_error, ...}, per_frequency, per_frequency_control, per_test, lookup {the same
tables for the lookup-table baseline, and its source}, noise_floor (rig data), regions {the
error at rest and outside the model's training envelope: dampnet.evaluation.regions}.
Definitions: dampnet.evaluation.metrics.
"""

from __future__ import annotations

import argparse

from dampnet.commands.common import DATA_HELP, add_channel_map_option, add_data_fix_options, apply_data_fixes, error, load_data
from dampnet.outputs import json_text


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the `evaluate` subcommand; its handler is `run`."""
    p = subparsers.add_parser(
        "evaluate", help="evaluate a trained model on dyno data, beside the lookup-table baseline",
        description="Evaluate MODEL on every test of DATA (or only the model's hold-out tests with "
                    "--holdout): RMSE, NRMSE (RMSE / measured force range), maximum error and average "
                    "%% error, overall, per test and per frequency, and the same for the industry's "
                    "lookup-table model.")
    p.add_argument("model", help="model directory (or its model.json)")
    p.add_argument("data", help=f"dataset: {DATA_HELP}")
    add_channel_map_option(p)
    p.add_argument("--holdout", action="store_true", help="only the tests the model held out in training")
    p.add_argument("--json", metavar="FILE", help="write the report as JSON to FILE ('-' for stdout)")
    p.add_argument("--plots", metavar="DIR", help="write PNG figures to DIR")
    p.add_argument("--plot-tests", default="", help="comma-separated test ids to draw (default: up to 4)")
    p.add_argument("--no-lookup", action="store_true", help="skip the lookup-table baseline")
    p.add_argument("--lbf", action="store_true", help="print forces in lbf (as the thesis's Table 4)")
    p.add_argument("--force", action="store_true", help="replace the JSON file if it exists")
    add_data_fix_options(p)
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.data import DataError
    from dampnet.evaluation.metrics import format_table
    from dampnet.envelope import load_envelope
    from dampnet.evaluation.regions import summary_lines
    from dampnet.evaluation.report import evaluation, lookup_for, write_plots
    from dampnet.features import check_features
    from dampnet.model import MlpModel, ModelError
    from dampnet.outputs import check_output_file, write_json
    from dampnet.training.pipeline import noise_floors

    try:
        if args.json and args.json != "-":
            check_output_file(args.json, [args.model, args.data])
        model = MlpModel.load(args.model)
        ds = apply_data_fixes(load_data(args.data, args.channel_map), args)
        held = model.meta.get("data", {}).get("holdout_tests", [])
        tests = ds.tests
        if args.holdout:
            if not held:
                raise DataError(f"{args.model}: the model records no hold-out tests")
            tests = [t for t in ds.tests if t.test_id in set(held)]
            if not tests:
                raise DataError(f"{args.data}: none of the model's hold-out tests "
                                f"({', '.join(held[:5])}{'...' if len(held) > 5 else ''}) are in the data")
        sub = ds.subset(tests, note="evaluate")
        check_features(model, sub)
        lookup, lookup_src = (None, None) if args.no_lookup else lookup_for(args.model, ds, held)
        envelope, envelope_note = load_envelope(args.model, model)
        rep = evaluation(model, tests, lookup, envelope)
        rep["regions"]["envelope_note"] = envelope_note
        rep["data"] = {"source": ds.source, "n_tests": len(tests), "holdout_only": bool(args.holdout)}
        if lookup is not None:
            rep["lookup"]["source"] = lookup_src
        nf = noise_floors(sub)
        if nf:
            rep["noise_floor"] = nf
        if args.json:
            if args.json == "-":
                print(json_text(rep), end="")
            else:
                write_json(args.json, rep, overwrite=args.force)
        paths = []
        if args.plots:
            wanted = [s.strip() for s in args.plot_tests.split(",") if s.strip()]
            paths = write_plots(model, tests, rep, args.plots, lookup, wanted)
    except (DataError, ModelError, FileExistsError, ValueError, OSError) as e:
        return error(str(e))
    if args.json != "-":
        o = rep["overall"]
        print(f"model {rep['model']['id']} on {len(tests)} test(s) of {ds.source}")
        print(format_table(rep, "MLP:", lbf=args.lbf))
        if lookup is not None:
            print(format_table(rep["lookup"], f"lookup table ({lookup_src}):", lbf=args.lbf))
            print(f"MLP NRMSE {o['nrmse']:.4f} vs lookup table {rep['lookup']['overall']['nrmse']:.4f}")
        if "noise_floor" in rep:
            print(f"noise floor (rig sensor noise): NRMSE {rep['noise_floor']['nrmse_range']:.4f}")
        for line in summary_lines(rep["regions"]):
            print(line)
        for p in paths:
            print(f"wrote {p}")
    return 0
