"""Instructions per step of a loop configuration, under callgrind: a count, not a time, so two
trees compare exactly on a loaded machine (bench/RESULTS.md, "The runtime's steps before and
after the valve term": how the quarter-car HIL step's lost inlining was found).

    python bench/experiments/step_instructions.py [CONFIG ...] [--steps N]

CONFIG: bench/footprint_steps.c's configurations (default: the quarter-car HIL step, the
quarter car per stage and the full-car HIL step). Run with each tree's own python to compare
trees. The driver and the collection are dampnet.latency.footprint's (--dynamic): the steps
after 2000 settling steps, inside dn_fp_measured; every instruction there counts (the library's,
libm's and the driver's loop).
"""

from __future__ import annotations

import argparse
import re
import tempfile
from pathlib import Path

DEFAULT = ("loop_step_rk4_per_step_eval_neural_float_skyhook_linear_accel", "loop_step_rk4_neural_float_skyhook",
           "fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel")


def main(argv=None) -> int:
    from dampnet import paths
    from dampnet.latency import footprint as fp

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("configs", nargs="*", default=list(DEFAULT))
    ap.add_argument("--steps", type=int, default=200)
    a = ap.parse_args(argv)
    lib = paths.shared_library()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        exe = fp.build_driver(lib, work)
        for cfg in a.configs:
            fp.executed_addresses(exe, lib, cfg, a.steps, work)
            text = (work / f"callgrind.{cfg}.out").read_text()
            total = int(re.search(r"^(?:summary|totals): (\d+)", text, re.M).group(1))
            print(f"{cfg}: {total / a.steps:.1f} instructions a step")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
