"""`dampnet bench`: per-call latency of the MLP forward and the quarter-car step against the
HIL budget; a go/no-go check (exit 1 when the budget is missed)."""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path


def add_parser(subparsers):
    p = subparsers.add_parser("bench", help="latency check against the HIL budget (exit 1 if missed)")
    p.add_argument("--quick", action="store_true", help="2e5 timed calls per case instead of 1e6")
    p.add_argument("--calls", type=int, default=None, help="timed calls per case (overrides --quick)")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.benchmark import quick_latency

    n = args.calls or (200_000 if args.quick else 1_000_000)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            res = quick_latency(Path(tmp), n_calls=n)
    except (RuntimeError, FileNotFoundError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    m = res["machine"]
    print(f"machine: {m.get('cpu')} ({m.get('simd')}), gcc {m.get('compiler')}, flags '{m.get('flags')}', "
          f"load {m.get('loadavg')}")
    print(f"{'case':52s} {'p50':>8s} {'p99':>8s} {'p99.9':>8s} {'max':>10s}  [ns]")
    for name, r in res["results"].items():
        print(f"{name:52s} {r['p50_ns']:8.0f} {r['p99_ns']:8.0f} {r['p999_ns']:8.0f} {r['max_ns']:10.0f}")
    b, h = res["budget"], res["headroom"]
    print(f"HIL budget: {b['case']} p99.9 <= {b['p999_budget_ns']:.0f} ns ({100 * b['share']:.0f} % of a "
          f"{1e6 / b['step_rate_hz']:.0f} us step): measured {h['p999_ns']:.0f} ns, headroom x{h['headroom_factor']:.2f}"
          f" -> {'GO' if h['within_budget'] else 'NO-GO'}")
    for name, t in res["targets"].items():
        print(f"target {name} {t['metric']} <= {t['target_ns']:.0f} ns: measured {t['measured_ns']:.0f} ns")
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1))
    return 0 if h["within_budget"] else 1
