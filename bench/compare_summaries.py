#!/usr/bin/env python3
"""Compare two `dampnet demo` summary.json files value by value (issue 30, "Must not move").

Usage: python bench/compare_summaries.py BEFORE/summary.json AFTER/summary.json
           [--json OUT.json] [--ignore-timing] [--quiet-same]

Walks both JSON documents recursively (dicts by key, lists by index) and compares every leaf:
numbers exactly first (bit for bit, float(a) == float(b) and the same repr), then by their
relative difference |a - b| / max(|a|, |b|) and their distance in units in the last place (ulp,
for floats). Prints every leaf that differs (path, before, after, relative difference, ulps),
every key present on one side only, and a count of the bit-identical leaves. Keys that are
wall-clock timings or dates (latency, seconds, timestamps: see TIMING_HINTS) are listed in their
own section, since they move with the machine, not with the arithmetic; --ignore-timing drops
them. Always exits 0 (it reports, it does not judge); exit status 2 on unreadable input.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import struct
import sys
from pathlib import Path

# Leaf paths whose values are measurements of the machine, not results of the arithmetic.
TIMING_HINTS = re.compile(
    r"(^|[.\[_])(latency|bench|elapsed|seconds|wall|timestamp|date|loadavg|machine|cpu|"
    r"stage_times_s|total_time_s|time_s|[a-z0-9]*_ns|ns_per_call|per_call_ns|speedup|"
    r"duration_s|created|version)([.\[_]|$)",
    re.IGNORECASE)


def _ulps(a: float, b: float) -> int | None:
    """Distance of two finite doubles in units in the last place (ordered integer mapping)."""
    if not (math.isfinite(a) and math.isfinite(b)):
        return None

    def key(x: float) -> int:
        i = struct.unpack("<q", struct.pack("<d", x))[0]
        return i if i >= 0 else -(i & 0x7FFFFFFFFFFFFFFF)

    return abs(key(a) - key(b))


def _is_num(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def walk(a, b, path: str, out: dict) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            p = f"{path}.{k}" if path else str(k)
            if k not in a:
                out["only_after"].append((p, b[k]))
            elif k not in b:
                out["only_before"].append((p, a[k]))
            else:
                walk(a[k], b[k], p, out)
        return
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out["length"].append((path, len(a), len(b)))
        for i in range(min(len(a), len(b))):
            walk(a[i], b[i], f"{path}[{i}]", out)
        return
    if _is_num(a) and _is_num(b):
        fa, fb = float(a), float(b)
        same = (fa == fb and repr(a) == repr(b)) or (math.isnan(fa) and math.isnan(fb))
        if same:
            out["same"].append(path)
            return
        den = max(abs(fa), abs(fb))
        rel = abs(fa - fb) / den if den > 0 and math.isfinite(den) else math.inf
        out["diff"].append({"path": path, "before": a, "after": b, "rel": rel,
                            "abs": abs(fa - fb) if math.isfinite(den) else math.inf,
                            "ulps": _ulps(fa, fb)})
        return
    if a == b:
        out["same"].append(path)
    else:
        out["diff"].append({"path": path, "before": a, "after": b, "rel": None, "abs": None, "ulps": None})


def compare(before, after) -> dict:
    out = {"same": [], "diff": [], "only_before": [], "only_after": [], "length": []}
    walk(before, after, "", out)
    return out


def _fmt(v) -> str:
    s = json.dumps(v) if not isinstance(v, float) else repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--json", type=Path, help="also write the comparison to this JSON file")
    ap.add_argument("--ignore-timing", action="store_true",
                    help="leave out the leaves whose path looks like a timing/date (TIMING_HINTS)")
    ap.add_argument("--quiet-same", action="store_true", help="do not list the identical leaves")
    args = ap.parse_args(argv)
    try:
        before = json.loads(args.before.read_text())
        after = json.loads(args.after.read_text())
    except (OSError, ValueError) as e:
        print(f"compare_summaries: {e}", file=sys.stderr)
        return 2
    res = compare(before, after)
    timing = [d for d in res["diff"] if TIMING_HINTS.search(d["path"])]
    values = [d for d in res["diff"] if not TIMING_HINTS.search(d["path"])]

    def show(rows, title):
        print(f"\n## {title}: {len(rows)}")
        if rows:
            print(f"{'path':70s} {'before':>24s} {'after':>24s} {'rel diff':>10s} {'ulps':>8s}")
        for d in sorted(rows, key=lambda d: d["path"]):
            rel = "-" if d["rel"] is None else f"{d['rel']:.3e}"
            ulps = "-" if d["ulps"] is None else str(d["ulps"])
            print(f"{d['path']:70s} {_fmt(d['before']):>24s} {_fmt(d['after']):>24s} {rel:>10s} {ulps:>8s}")

    n_leaves = len(res["same"]) + len(res["diff"])
    print(f"# {args.before} vs {args.after}")
    print(f"leaves compared: {n_leaves}; bit-identical: {len(res['same'])}; differing: {len(res['diff'])} "
          f"({len(values)} values, {len(timing)} timing/date-like)")
    show(values, "differing values (arithmetic)")
    if not args.ignore_timing:
        show(timing, "differing timing/date-like leaves (move with the machine)")
    if values:
        rels = [d["rel"] for d in values if d["rel"] is not None]
        if rels:
            print(f"\nlargest relative difference among values: {max(rels):.3e}")
    for title, rows in (("only in before", res["only_before"]), ("only in after", res["only_after"])):
        if rows:
            print(f"\n## keys {title}: {len(rows)}")
            for p, v in rows:
                print(f"  {p} = {_fmt(v)}")
    if res["length"]:
        print(f"\n## lists of different length: {len(res['length'])}")
        for p, la, lb in res["length"]:
            print(f"  {p}: {la} vs {lb}")
    if not args.quiet_same:
        print(f"\n## bit-identical leaves: {len(res['same'])}")
        for p in res["same"]:
            print(f"  {p}")
    if args.json:
        args.json.write_text(json.dumps({"before": str(args.before), "after": str(args.after),
                                         "n_leaves": n_leaves, "n_same": len(res["same"]),
                                         "values": values, "timing": timing, "same": res["same"],
                                         "only_before": res["only_before"], "only_after": res["only_after"],
                                         "length": res["length"]}, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
