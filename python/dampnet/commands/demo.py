"""`dampnet demo`: the whole story on the virtual rig's data, written as a report; with --data,
the diagnosis loop on the user's own data (dampnet.demo.on_data)."""

from __future__ import annotations

from dampnet.commands.common import DATA_HELP, REAL_DATASETS, add_channel_map_option, error
from dampnet.commands.training_options import add_training_options, training_request
from dampnet.recipes.loop import MAX_STEPS, MAX_STEPS_LIMIT, check_max_steps


def add_parser(subparsers):
    p = subparsers.add_parser(
        "demo", help="run the whole story end to end and write report.html",
        description="Generate the thesis's dyno campaign with a hidden effect, train the 3-30-1 MLP, "
                    "diagnose it, add the missing effect, export to C, run the quarter-car study "
                    "and the latency benchmark; write DIR/report.html and DIR/summary.json. With --data, run "
                    "the diagnosis loop on your own data instead: train, diagnose the training tests, add the "
                    "effects named, retrain (up to --steps effects in all), and report each model's error on held-out "
                    "tests, before and after.")
    p.add_argument("--out", default="dampnet-demo", help="output directory (default ./dampnet-demo)")
    p.add_argument("--quick", action="store_true",
                   help="small plan and short training (under a minute); with --data: 60 epochs a training unless "
                        "--max-epochs says")
    p.add_argument("--force", action="store_true", help="replace the output directory if it exists")
    g = p.add_argument_group(
        "the loop on your data (--data)",
        "The training options are dampnet train's, with one difference: the hold-out. Without --holdout-tests "
        "or --holdout-voltage, every fifth test in the data's order (from the third) is held out: each model "
        "is scored on those and diagnosed on the others.")
    g.add_argument("--data", default=None, metavar="DATA",
                   help=f"run the loop on DATA: {DATA_HELP}, or a bundled real data set "
                        f"({', '.join(REAL_DATASETS)}, from the shared data folder)")
    add_channel_map_option(g)
    g.add_argument("--steps", type=int, default=None, metavar="N",
                   help=f"add at most N effects in all (default {MAX_STEPS}; 0..{MAX_STEPS_LIMIT}); the effects one "
                        "diagnosis names are added together, one training for them")
    add_training_options(g, train=True)
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.data import DataError
    from dampnet.demo import DemoError, run_demo

    if args.data is not None:
        return run_on_data(args)
    given = [opt for opt in _data_only() if getattr(args, opt[2:].replace("-", "_")) is not None]
    if given:
        return error(f"{', '.join(given)}: appl{'ies' if len(given) == 1 else 'y'} to the loop on your data: "
                     "add --data DATA")
    args.seed = 0 if args.seed is None else args.seed

    try:
        summary = run_demo(args.out, quick=args.quick, force=args.force, seed=args.seed,
                           log=lambda s: print(s, flush=True))
    except (FileExistsError, DataError, DemoError) as e:
        return error(str(e))
    hn = summary["holdout_nrmse"]
    print(f"summary: held-out NRMSE {hn['original']:.4f} -> {hn['improved']:.4f} after adding "
          f"'{summary['diagnosis']['verdict']}' (thesis {hn['thesis_lm']}, lookup table "
          f"{hn['lookup_table']:.4f}); C program {'matches' if summary['c_program']['match'] else 'DIFFERS from'} "
          f"Python; report rendered: {summary['report_rendered'].get('ok')}")
    return 0


#: --quick with --data: each training's epochs
QUICK_EPOCHS = 60


def _data_only() -> list[str]:
    """The options of the loop on data: dampnet train's (the options table's), but --seed, which the
    rig's demo takes too, and the loop's own."""
    from dampnet.training.settings import OPTIONS

    return [r.cli for r in OPTIONS.values() if r.cli and r.cli != "--seed"] + ["--channel-map", "--steps"]


def run_on_data(args) -> int:
    from dampnet.commands.common import load_data
    from dampnet.data import DataError
    from dampnet.demo import run_data_demo
    from dampnet.outputs import OutputError

    try:
        steps = check_max_steps(MAX_STEPS if args.steps is None else args.steps, "--steps")
    except ValueError as e:
        return error(str(e))
    try:
        request = training_request(args)
        if args.holdout_voltage is None:  # the table's 2.25 V is the thesis's level, not the user's data's
            request = request.replace(holdout_voltage=None)
        if args.quick and args.max_epochs is None:
            request = request.replace(max_epochs=QUICK_EPOCHS)
        request = request.check()
        ds = load_data(args.data, args.channel_map)
        unknown = sorted(set(request.holdout_tests) - set(ds.test_ids))
        if unknown:
            return error(f"--holdout-tests: {', '.join(unknown)} not in {args.data} (its tests: "
                         f"{', '.join(ds.test_ids[:12])}{' ...' if len(ds.test_ids) > 12 else ''})")
        summary = run_data_demo(ds, args.out, args.data, request, max_steps=steps, force=args.force,
                                log=lambda s: print(s, flush=True), workers=args.workers,
                                inputs=[] if args.data in REAL_DATASETS else [args.data])
    except (FileExistsError, OutputError, DataError, ValueError) as e:
        return error(str(e))
    first, last = summary["steps"][0], summary["steps"][-1]
    print(f"summary: held-out RMSE {first['scores']['rmse_n']:.1f} N (default model)"
          + (f" -> {last['scores']['rmse_n']:.1f} N after adding {', '.join(last['added'])}" if last["added"] else "")
          + f"; stopped: {summary['stop']}")
    return 0
