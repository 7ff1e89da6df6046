#!/usr/bin/env python3
"""Before/after of bench/embedded.py's results (issue 30: the Cortex-M4F step's instructions and
flash/RAM not worse by more than 2 %).

Usage: python bench/compare_embedded.py BEFORE.json AFTER.json [--core cortex-m4] [--limit-pct 2]
           [--md OUT.md]

Reads two `bench/embedded.py --json` files and prints a markdown table per core: the forward's and
the step's instructions (QEMU -icount), the kernel's and the loop's flash, RAM (static + stack) and
stack, and the cycle estimates when present, with the change in % (after / before - 1); rows over
--limit-pct worse are marked. Always exits 0.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROWS = [  # (label, path in the core's dict, the 2 % rule applies)
    ("forward instructions", ("instructions", "forward"), True),
    ("step instructions", ("instructions", "step"), True),
    ("kernel flash [B]", ("kernel", "flash"), True),
    ("kernel RAM (static + stack) [B]", ("kernel", "ram"), True),
    ("kernel stack [B]", ("kernel", "stack"), False),
    ("loop flash [B]", ("loop", "flash"), True),
    ("loop RAM static [B]", ("loop", "ram_static"), False),
    ("loop RAM (static + peak stack) [B]", ("loop", "ram"), True),
    ("loop stack, set-up [B]", ("loop", "stack_setup"), False),
    ("loop stack, step [B]", ("loop", "stack_step"), False),
    ("forward cycles (estimate)", ("cycles", "forward"), False),
    ("step cycles (estimate)", ("cycles", "step"), False),
    ("sizeof dn_damper [B]", ("sizes", "damper"), False),
    ("sizeof dn_loop_model [B]", ("sizes", "loop_model"), False),
    ("sizeof dn_loop_data [B]", ("sizes", "loop_data"), False),
]


def get(d: dict, path: tuple):
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def fmt(v) -> str:
    if v is None:
        return "-"
    return f"{v:,.1f}" if isinstance(v, float) and v != int(v) else f"{int(v):,}"


def table(before: dict, after: dict, core: str, limit: float) -> str:
    b, a = before.get(core, {}), after.get(core, {})
    out = [f"**{core}**", "", "| quantity | before | after | change |", "|---|---:|---:|---:|"]
    for label, path, ruled in ROWS:
        vb, va = get(b, path), get(a, path)
        if vb is None and va is None:
            continue
        if vb and va is not None:
            pct = 100.0 * (va / vb - 1.0)
            mark = " **over limit**" if ruled and pct > limit else ""
            ch = f"{pct:+.2f} %{mark}"
        else:
            ch = "-"
        out.append(f"| {label} | {fmt(vb)} | {fmt(va)} | {ch} |")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--core", action="append", help="core(s) to show (default: every core in both files)")
    ap.add_argument("--limit-pct", type=float, default=2.0)
    ap.add_argument("--md", type=Path)
    args = ap.parse_args(argv)
    before, after = json.loads(args.before.read_text()), json.loads(args.after.read_text())
    cores = args.core or [c for c in before if c in after and isinstance(before[c], dict) and "instructions" in before[c]]
    md = "\n".join(table(before, after, c, args.limit_pct) for c in cores)
    for k in ("fp_contract", "loop_float"):
        if before.get(k) != after.get(k):
            md += f"\nnote: {k} differs: before {before.get(k)}, after {after.get(k)}\n"
    print(md)
    if args.md:
        args.md.write_text(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
