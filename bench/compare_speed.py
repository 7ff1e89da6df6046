#!/usr/bin/env python3
"""Before/after speed of the C++ runtime, interleaved on one machine (issue 30, "Must not move").

Usage:
  python bench/compare_speed.py --before /work/wt-before --after /work/main \
      [--rounds 5] [--calls 200000] [--cases KEY|all|NAME,...] [--json OUT.json] [--md OUT.md]

--before/--after each take a source tree with its .venv (python/env.sh has built it; --rebuild
runs it again first, and a warning names the headers when the install is older than the tree's
sources: the commit is then labelled "+stale-install"; the C++
latency harness bench/bench_mlp.cpp is compiled by that tree's own
dampnet.latency.harness.build_harness, i.e. exactly as `dampnet bench` compiles it, against that
tree's installed runtime with its SIMD flags) or an already built harness binary (dn_bench_mlp).
Each harness is copied with the libdampnet.so it links into a snapshot directory first and run
from there (LD_LIBRARY_PATH overrides the harness's RUNPATH), so a rebuild of a tree during the
rounds does not change what is measured.

Then `--rounds` rounds, each running the before harness and then the after harness (order
"alternate": B A B A ...; "abba": B A, A B, B A ... so a slow drift of the machine's load falls on
both sides equally), each run `dn_bench_mlp CALLS` timing every case the harness has (CALLS
individually timed calls per case; the chained MLP cases time CALLS/100 batches of 100 calls).
Per case and round: median (p50) and p99.9. The table gives, per side, the median over the
rounds of the per-run p50 and p99.9, the after/before ratio of those medians, and in brackets the
min-max across rounds of the per-round ratios (round i's after run over round i's before run; the
JSON also has their median). The machine's 1-minute load average is recorded at every run.
The harness's clock reads are ~10 ns apart on some VMs, so the one-by-one timed rows move in 10 ns
steps; the chained MLP rows (100 calls per clock pair) resolve well below that.

Exit 0 when both sides ran; 1 on a build or run failure.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

# The cases issue 30's speed rule names (MLP forward float/double, quarter-car HIL step,
# full-car step), in table order; "--cases all" adds every other case the harnesses share.
KEY_CASES = [
    "dampnet_static_float_chained",       # MLP forward 3-30-1 float, chained single-sample calls
    "dampnet_static_double_chained",      # MLP forward 3-30-1 double, chained
    "dampnet_static_float",               # MLP forward float, each call timed (clock pair included)
    "dampnet_static_double",              # MLP forward double, each call timed
    "loop_step_rk4_per_step_eval_neural_float_skyhook_linear_accel",   # quarter-car HIL step
    "loop_step_rk4_neural_float_skyhook",                              # quarter car, per stage, implicit a
    "fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel",  # full-car HIL step
    "fullcar_step_rk4_per_step_eval_neural_double_skyhook_linear_accel",
    "fullcar_step_rk4_neural_float_skyhook_linear_accel",
]
LABELS = {
    "dampnet_static_float_chained": "MLP fwd float (chained)",
    "dampnet_static_double_chained": "MLP fwd double (chained)",
    "dampnet_static_float": "MLP fwd float (timed 1 by 1)",
    "dampnet_static_double": "MLP fwd double (timed 1 by 1)",
    "loop_step_rk4_per_step_eval_neural_float_skyhook_linear_accel": "quarter-car HIL step",
    "loop_step_rk4_neural_float_skyhook": "quarter-car step, per stage, implicit a",
    "fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel": "full-car HIL step (float)",
    "fullcar_step_rk4_per_step_eval_neural_double_skyhook_linear_accel": "full-car HIL step (double)",
    "fullcar_step_rk4_neural_float_skyhook_linear_accel": "full-car step, per stage (float)",
}

_BUILD = r"""
import sys
from pathlib import Path
from dampnet import paths
from dampnet.latency.harness import build_harness, kernel_flags
exe = build_harness(Path(sys.argv[1]))
print(exe)
print(paths.shared_library())
print(kernel_flags()[1])
"""


def _git(tree: Path) -> str:
    try:
        rev = subprocess.run(["git", "-C", str(tree), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(tree), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip()
        return rev + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _linked_lib(exe: Path) -> Path | None:
    """The libdampnet.so the binary resolves (ldd)."""
    try:
        out = subprocess.run(["ldd", str(exe)], capture_output=True, text=True).stdout
    except OSError:
        return None
    for line in out.splitlines():
        if "libdampnet" in line and "=>" in line:
            p = line.split("=>")[1].split("(")[0].strip()
            return Path(p) if p and p != "not" else None
    return None


def stale_headers(tree: Path) -> list[str]:
    """The runtime headers whose installed copy (the .venv's dampnet/include, what the harness is
    compiled against) differs from the tree's cpp/include: the install is older than the sources
    (run python/env.sh, or --rebuild). [] when they agree or no installed copy is found."""
    inst = next(iter(sorted((tree / ".venv").glob("lib/python3*/site-packages/dampnet/include/dampnet"))), None)
    srcd = tree / "cpp" / "include" / "dampnet"
    if inst is None or not srcd.is_dir():
        return []
    out = []
    for f in sorted(srcd.rglob("*.h*")):
        g = inst / f.relative_to(srcd)
        if not g.is_file() or g.read_bytes() != f.read_bytes():
            out.append(str(f.relative_to(srcd)))
    return out


def prepare(side: str, src: Path, snap_root: Path, rebuild: bool = False) -> dict:
    """Build (a tree) or take (a binary) a harness and snapshot it with its library."""
    src = src.resolve()
    info: dict = {"side": side, "source": str(src)}
    if src.is_dir():
        py = src / ".venv" / "bin" / "python"
        if not py.is_file():
            raise RuntimeError(f"{side}: {src} has no .venv (run: cd {src} && bash python/env.sh true)")
        if rebuild:  # the tree's incremental rebuild (python/env.sh: the install follows the sources)
            proc = subprocess.run(["bash", "python/env.sh", "true"], cwd=src, capture_output=True, text=True)
            if proc.returncode != 0:
                raise RuntimeError(f"{side}: python/env.sh in {src} failed:\n{proc.stderr[-3000:]}")
        stale = stale_headers(src)
        if stale:
            print(f"[compare_speed] WARNING {side}: the installed runtime of {src} is not its HEAD's sources "
                  f"({len(stale)} headers differ: {', '.join(stale[:6])}); run python/env.sh there or pass "
                  "--rebuild", file=sys.stderr)
        info["stale_install_headers"] = stale
        build_dir = snap_root / f"{side}-build"
        env = {k: v for k, v in os.environ.items() if k != "DAMPNET_BENCH_HARNESS_DIR"}
        proc = subprocess.run([str(py), "-c", _BUILD, str(build_dir)], capture_output=True, text=True,
                              cwd=src, env=env)
        if proc.returncode != 0:
            raise RuntimeError(f"{side}: building the harness in {src} failed:\n{proc.stderr[-3000:]}")
        exe_s, lib_s, isa = proc.stdout.strip().splitlines()[-3:]
        exe, lib = Path(exe_s), Path(lib_s)
        info.update(commit=_git(src) + ("+stale-install" if stale else ""), kernel_isa=isa)
    else:
        exe, lib = src, _linked_lib(src)
        if lib is None:
            raise RuntimeError(f"{side}: cannot find the libdampnet.so {src} links (ldd)")
        tree = next((p for p in src.parents if (p / ".git").exists()), None)
        info.update(commit=_git(tree) if tree else "unknown")
    snap = snap_root / side
    snap.mkdir(parents=True, exist_ok=True)
    shutil.copy2(exe, snap / "dn_bench_mlp")
    shutil.copy2(lib, snap / lib.name)
    info.update(exe=str(snap / "dn_bench_mlp"), lib=str(snap / lib.name), built_from=str(exe),
                lib_from=str(lib))
    return info


def run_once(info: dict, calls: int, cpu: str | None) -> dict:
    env = dict(os.environ)
    env["LD_LIBRARY_PATH"] = str(Path(info["lib"]).parent) + (
        ":" + env["LD_LIBRARY_PATH"] if env.get("LD_LIBRARY_PATH") else "")
    cmd = [info["exe"], str(int(calls))]
    if cpu is not None:
        cmd = ["taskset", "-c", cpu, *cmd]
    t0 = _dt.datetime.now(_dt.timezone.utc)
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(f"{info['side']}: harness failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    machine, results = {}, {}
    for line in proc.stdout.splitlines():
        rec = json.loads(line)
        if "machine" in rec:
            machine = rec["machine"]
        else:
            results[rec.pop("name")] = rec
    return {"side": info["side"], "start": t0.isoformat(timespec="seconds"),
            "seconds": (_dt.datetime.now(_dt.timezone.utc) - t0).total_seconds(),
            "loadavg_start": machine.get("loadavg", ""), "loadavg_end": Path("/proc/loadavg").read_text().strip(),
            "machine": machine, "results": results}


def summarise(runs: list[dict], cases: list[str]) -> list[dict]:
    before = [r for r in runs if r["side"] == "before"]
    after = [r for r in runs if r["side"] == "after"]
    rows = []
    for c in cases:
        b50 = [r["results"][c]["p50_ns"] for r in before if c in r["results"]]
        a50 = [r["results"][c]["p50_ns"] for r in after if c in r["results"]]
        b999 = [r["results"][c]["p999_ns"] for r in before if c in r["results"]]
        a999 = [r["results"][c]["p999_ns"] for r in after if c in r["results"]]
        if not (b50 and a50):
            continue
        bl = [r["results"][c].get("loop_ns_per_call", 0.0) for r in before if c in r["results"]]
        al = [r["results"][c].get("loop_ns_per_call", 0.0) for r in after if c in r["results"]]
        rl = [a / b for a, b in zip(al, bl) if b > 0]
        r50 = [a / b for a, b in zip(a50, b50) if b > 0]
        r999 = [a / b for a, b in zip(a999, b999) if b > 0]
        rows.append({
            "case": c, "label": LABELS.get(c, c),
            "before_p50_ns": statistics.median(b50), "before_p999_ns": statistics.median(b999),
            "after_p50_ns": statistics.median(a50), "after_p999_ns": statistics.median(a999),
            "before_p50_rounds": b50, "after_p50_rounds": a50,
            "before_p999_rounds": b999, "after_p999_rounds": a999,
            "before_loop_mean_ns": statistics.median(bl), "after_loop_mean_ns": statistics.median(al),
            "before_loop_mean_rounds": bl, "after_loop_mean_rounds": al,
            "ratio_loop_mean": (statistics.median(al) / statistics.median(bl)) if rl else None,
            "ratio_loop_mean_rounds_min": min(rl, default=None), "ratio_loop_mean_rounds_max": max(rl, default=None),
            "ratio_p50": statistics.median(a50) / statistics.median(b50),
            "ratio_p50_rounds_median": statistics.median(r50), "ratio_p50_rounds_min": min(r50),
            "ratio_p50_rounds_max": max(r50),
            "ratio_p999": statistics.median(a999) / statistics.median(b999),
            "ratio_p999_rounds_median": statistics.median(r999), "ratio_p999_rounds_min": min(r999),
            "ratio_p999_rounds_max": max(r999),
        })
    return rows


def _ns(v: float) -> str:
    return f"{v:.1f}" if v < 100 else f"{v:,.0f}"


def markdown(rows: list[dict], meta: dict) -> str:
    b, a = meta["before"], meta["after"]
    loads = [float(r["loadavg_start"].split()[0]) for r in meta["runs"] if r.get("loadavg_start")]
    out = [f"Before: {b.get('commit')} ({b['source']}, kernel {b.get('kernel_isa', '?')}); "
           f"after: {a.get('commit')} ({a['source']}, kernel {a.get('kernel_isa', '?')}). "
           f"{meta['rounds']} rounds ({meta['order']}: {' '.join(r['side'][0].upper() for r in meta['runs'])}), "
           f"{meta['calls']:,} timed calls per case and run; {meta['cpu_model']}; "
           f"1-min load average at the runs' starts {min(loads, default=float('nan')):.2f}-{max(loads, default=float('nan')):.2f}; "
           f"{meta['date']}.",
           "",
           "Medians over the rounds of each run's p50 and p99.9 [ns]; ratio = after / before of those medians, in "
           "brackets the min-max across rounds of the per-round ratios (round i's after run over its before run).",
           "",
           "| case | before p50 | before p99.9 | after p50 | after p99.9 | ratio p50 (min-max) | ratio p99.9 (min-max) |",
           "|---|---:|---:|---:|---:|---|---|"]
    for r in rows:
        out.append(f"| {r['label']} | {_ns(r['before_p50_ns'])} | {_ns(r['before_p999_ns'])} | "
                   f"{_ns(r['after_p50_ns'])} | {_ns(r['after_p999_ns'])} | "
                   f"{r['ratio_p50']:.3f} ({r['ratio_p50_rounds_min']:.3f}-{r['ratio_p50_rounds_max']:.3f}) | "
                   f"{r['ratio_p999']:.3f} ({r['ratio_p999_rounds_min']:.3f}-{r['ratio_p999_rounds_max']:.3f}) |")
    out += ["", "Best round (the smallest p50 over the rounds, per side: on a loaded machine the least disturbed "
            "runs) and the untimed loop's mean per call (the harness's loop_ns_per_call: the same calls with no "
            "clock read between them, so not quantised by the clock's tick, but wall time: it includes every "
            "preemption, so it means something only on a quiet machine; median over the rounds, in brackets "
            "the per-round ratios' min-max). Ratios after / before.", "",
            "| case | before best p50 | after best p50 | ratio | before loop mean | after loop mean | ratio (min-max) |",
            "|---|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        bb, ab = min(r["before_p50_rounds"]), min(r["after_p50_rounds"])
        lm = "-" if r["ratio_loop_mean"] is None else (
            f"{r['ratio_loop_mean']:.3f} ({r['ratio_loop_mean_rounds_min']:.3f}-{r['ratio_loop_mean_rounds_max']:.3f})")
        out.append(f"| {r['label']} | {_ns(bb)} | {_ns(ab)} | {ab / bb:.3f} | {_ns(r['before_loop_mean_ns'])} | "
                   f"{_ns(r['after_loop_mean_ns'])} | {lm} |")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", type=Path, required=True, help="source tree (with .venv) or harness binary")
    ap.add_argument("--after", type=Path, required=True, help="source tree (with .venv) or harness binary")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--calls", type=int, default=200_000, help="timed calls per case and run (default 2e5)")
    ap.add_argument("--order", choices=("alternate", "abba"), default="alternate")
    ap.add_argument("--cases", default="key",
                    help="'key' (issue 30's cases, default), 'all' (every case both harnesses have) or a "
                         "comma-separated list of case names")
    ap.add_argument("--rebuild", action="store_true",
                    help="run `bash python/env.sh true` in each tree first (incremental), so the installed "
                         "runtime is the tree's sources")
    ap.add_argument("--cpu", help="pin each run to these CPUs (taskset -c LIST)")
    ap.add_argument("--snapshot-dir", type=Path, help="where the harness snapshots go (default: a temp dir)")
    ap.add_argument("--json", type=Path, help="write every run's results and the summary to this JSON file")
    ap.add_argument("--md", type=Path, help="also write the markdown table to this file")
    args = ap.parse_args(argv)
    if args.rounds < 1 or args.calls < 1000:
        ap.error("--rounds >= 1 and --calls >= 1000")

    tmp = None
    snap_root = args.snapshot_dir
    if snap_root is None:
        tmp = tempfile.TemporaryDirectory(prefix="dn-compare-speed-")
        snap_root = Path(tmp.name)
    snap_root.mkdir(parents=True, exist_ok=True)
    try:
        sides = {s: prepare(s, p, snap_root, args.rebuild) for s, p in (("before", args.before), ("after", args.after))}
        for s in sides.values():
            print(f"[compare_speed] {s['side']}: {s['source']} ({s.get('commit')}, kernel {s.get('kernel_isa', '?')}) "
                  f"-> {s['exe']}", file=sys.stderr)
        runs = []
        for i in range(args.rounds):
            order = ("before", "after") if args.order == "alternate" or i % 2 == 0 else ("after", "before")
            for side in order:
                r = run_once(sides[side], args.calls, args.cpu)
                r["round"] = i
                runs.append(r)
                print(f"[compare_speed] round {i + 1}/{args.rounds} {side}: {r['seconds']:.1f} s, "
                      f"load {r['loadavg_start'].split(' ')[0] if r['loadavg_start'] else '?'}", file=sys.stderr)
    except (RuntimeError, OSError, subprocess.SubprocessError) as e:
        print(f"compare_speed: {e}", file=sys.stderr)
        return 1
    finally:
        if tmp is not None:
            tmp.cleanup()

    for r in runs:  # a binary given: its kernel path from its own machine line
        sides[r["side"]].setdefault("kernel_isa", r["machine"].get("isa", "?"))
    common = [c for c in runs[0]["results"] if all(c in r["results"] for r in runs)]
    if args.cases == "key":
        cases = [c for c in KEY_CASES if c in common]
    elif args.cases == "all":
        cases = [c for c in KEY_CASES if c in common] + [c for c in common if c not in KEY_CASES]
    else:
        cases = [c for c in args.cases.split(",") if c in common]
    missing = [c for c in (KEY_CASES if args.cases in ("key", "all") else args.cases.split(",")) if c not in common]
    rows = summarise(runs, cases)
    meta = {"date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "rounds": args.rounds, "calls": args.calls, "order": args.order, "cpu_pin": args.cpu,
            "cpu_model": runs[0]["machine"].get("cpu", "?"), "before": sides["before"], "after": sides["after"],
            "runs": [{k: r[k] for k in ("round", "side", "start", "seconds", "loadavg_start", "loadavg_end")}
                     for r in runs]}
    md = markdown(rows, meta)
    if missing:
        md += f"\nCases not in both harnesses' output: {', '.join(missing)}\n"
    print(md)
    if args.md:
        args.md.write_text(md)
    if args.json:
        args.json.write_text(json.dumps({**meta, "rows": rows, "machine": {r["side"]: r["machine"] for r in runs},
                                         "raw": runs}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
