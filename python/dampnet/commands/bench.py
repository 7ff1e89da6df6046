"""`dampnet bench`: per-call latency of the MLP forward and the quarter-car step against the
HIL budget (the C++ harness; exit 1 when the budget is missed), the HIL configuration on a
recorded set of hard inputs (exit 1 when a force leaves the model's range by more than a margin
or a step fails), and beside them, in the same
run, Python-level figures: dampnet's pybind11 forward, numpy, torch eager, TorchScript and
onnxruntime on the same model and inputs (as ratios to the C++ kernel's median), the pybind11
`Loop.step` latency and `Loop.simulate` throughput against their targets."""

from __future__ import annotations

from dampnet.commands.common import error
from dampnet.outputs import check_output_file, write_json


def add_parser(subparsers):
    p = subparsers.add_parser("bench", help="latency check against the HIL budget (exit 1 if missed)")
    p.add_argument("--quick", action="store_true",
                   help="2e5 timed C++ calls per case instead of 1e6, 2e4 Python calls instead of 1e5, "
                        "2e5-step roads instead of 1e6 (under a minute)")
    p.add_argument("--calls", type=int, default=None, help="timed C++ calls per case (overrides --quick)")
    p.add_argument("--py-calls", type=int, default=None,
                   help="timed Python-level calls per case (default: a tenth of the C++ calls)")
    p.add_argument("--sim-steps", type=int, default=None,
                   help="road length of the simulate throughput runs (default: the C++ calls)")
    p.add_argument("--cpp-only", action="store_true", help="only the C++ harness (no Python-level rows)")
    p.add_argument("--budget-ns", type=float, default=None,
                   help="p99.9 budget of the HIL step [ns] (default: 1 %% of a 10 kHz step, 1000 ns)")
    p.add_argument("--hil-margin", type=float, default=None,
                   help="hard-input check: how far [fraction of the model's force range] a force may "
                        "leave that range (default 0.25)")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Check the options and the JSON output, measure (dampnet.latency.report.measure), print its
    report; 0 when GO, 1 when NO-GO (the reasons printed), 2 on bad input."""
    from dampnet.latency.harness import HIL_FORCE_MARGIN
    from dampnet.latency.report import measure, no_go, report

    n = args.calls or (200_000 if args.quick else 1_000_000)
    n_py = args.py_calls or max(1000, n // 10)  # Python calls are ~10-400x slower than C++ ones
    n_sim = args.sim_steps or n
    if args.budget_ns is not None and not args.budget_ns > 0:
        return error(f"--budget-ns: expected a positive number of ns, got {args.budget_ns}")
    if args.json:  # before the minutes of timing, not after
        try:
            check_output_file(args.json)
        except OSError as e:
            return error(str(e))
    margin = HIL_FORCE_MARGIN if args.hil_margin is None else args.hil_margin
    if not -1.0 < margin < 100.0:
        return error(f"--hil-margin: expected a fraction in (-1, 100), got {margin}")
    try:
        res = measure(n, n_py, n_sim, args.budget_ns, margin, args.quick, args.cpp_only)
    except (RuntimeError, FileNotFoundError) as e:
        return error(str(e))
    for line in report(res):
        print(line)
    if args.json:
        write_json(args.json, res, overwrite=True)  # atomically
    why = no_go(res)
    for reason in why:
        print(f"NO-GO: {reason}")
    return 1 if why else 0
