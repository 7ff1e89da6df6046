"""`dampnet demo`: the whole story on the virtual rig's data, written as a report."""

from __future__ import annotations

from dampnet.commands.common import error


def add_parser(subparsers):
    p = subparsers.add_parser(
        "demo", help="run the whole story end to end and write report.html",
        description="Generate the thesis's dyno campaign with a hidden effect, train the 3-30-1 MLP, "
                    "diagnose it, add the missing effect, export to C, run the quarter-car study "
                    "and the latency benchmark; write DIR/report.html and DIR/summary.json.")
    p.add_argument("--out", default="dampnet-demo", help="output directory (default ./dampnet-demo)")
    p.add_argument("--quick", action="store_true", help="small plan and short training (under a minute)")
    p.add_argument("--force", action="store_true", help="replace the output directory if it exists")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.data import DataError
    from dampnet.demo import DemoError, run_demo

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
