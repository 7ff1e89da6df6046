"""Interleaved A/B of latency-harness builds (bench/bench_mlp.cpp binaries built from different
sources or flags): each round runs every binary once, in turn, so that a shared machine's slow
and fast minutes fall on all of them alike; prints, per binary and figure, the median over
rounds of p50, p99 and p99.9 with their ranges.

Usage: python3 bench/experiments/ab_harness.py ROUNDS CALLS BIN [BIN ...]
  e.g. python3 bench/experiments/ab_harness.py 8 200000 build/a/bench/dn_bench_mlp build/b/bench/dn_bench_mlp
"""

from __future__ import annotations

import json
import statistics as st
import subprocess
import sys

ROWS = {"clock_overhead": "clock", "dampnet_static_float_chained": "float chained",
        "dampnet_static_float": "float one by one", "dampnet_static_double_chained": "double chained",
        "loop_step_rk4_per_step_eval_neural_float_skyhook_linear_accel": "HIL step",
        "loop_step_rk4_neural_float_skyhook": "RK4 per stage"}


def main(argv: list[str]) -> int:
    if len(argv) < 4:
        print(__doc__, file=sys.stderr)
        return 2
    rounds, calls, bins = int(argv[1]), int(argv[2]), argv[3:]
    res: dict[str, dict[str, list[tuple[float, float, float]]]] = {b: {} for b in bins}
    loads, isa = [], {}
    for _ in range(rounds):
        for b in bins:
            out = subprocess.run([b, str(calls)], capture_output=True, text=True, check=True).stdout
            for line in out.splitlines():
                d = json.loads(line)
                if "machine" in d:
                    loads.append(float(d["machine"]["loadavg"].split()[0]))
                    isa[b] = d["machine"].get("isa", "?")
                elif d.get("name") in ROWS:
                    res[b].setdefault(ROWS[d["name"]], []).append((d["p50_ns"], d["p99_ns"], d["p999_ns"]))
    print(f"{rounds} rounds of {calls} calls; 1-min load average {min(loads):.2f}-{max(loads):.2f}")
    for b in bins:
        print(f"{b} (kernel {isa.get(b, '?')})")
        for name, v in res[b].items():
            cols = []
            for k, label in enumerate(("p50", "p99", "p99.9")):
                xs = [x[k] for x in v]
                cols.append(f"{label} {st.median(xs):7.1f} [{min(xs):.1f}-{max(xs):.1f}]")
            print(f"  {name:18s} " + "  ".join(cols))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
