"""Hot-path code footprint: the bytes of machine code one call of an entry point can touch,
from the built library's symbol table and its disassembly (binutils' nm, objdump, readelf).

From the entry symbol (e.g. dn_fullcar_step), the static call graph is walked over every
direct call or jump whose target lies in another function of the library (a tail call, a
jump into a function's `.cold` part, a call through the PLT to a function the library itself
defines), and over two kinds of indirect edge, so that a function reached only through a
pointer is not missed: a function whose address the code takes (`lea fn(%rip)`), and every
function in a table of pointers the code reads (a data object, e.g. dampnet::terms::table()'s,
whose dynamic relocations point at functions). The footprint is the sum of the reachable
functions' symbol sizes (nm --size; alignment padding between functions not counted).
Calls out of the library (libm's exp/tanh, memcpy, ...) are listed by name, not counted;
indirect calls whose target the walk cannot know (a user's callback) are counted per function.

It is an upper bound on what one call runs (every branch of every reachable function counts,
including the ones the configuration never takes: other damper kinds, double precision, error
paths). The `.cold` parts (gcc's split-off unlikely paths) are in the total and also reported
apart.

--dynamic: the code the steps of one configuration actually call. bench/footprint_steps.c
(compiled here against the library read) sets up one of dampnet bench's configurations
(DYNAMIC_CONFIGS: by default the full car's five, a shared float damper reading a per step
and per stage, four separate damper objects per step and per stage, a shared double damper),
settles it over 2000 steps, then runs `--steps` steps (default 10) inside one function that
`valgrind --tool=callgrind --toggle-collect` collects in. Every library function with at least
one executed instruction there counts with its whole symbol size (nm), the same unit as the
static walk: the bytes of the functions one step calls, not only the lines it runs. Calls out
of the library (libm) are not counted. **This is the measure of issue 30's "the code one
full-car step touches <= 16 KB" (FULLCAR_STEP_CEILING_BYTES): the largest over the full car's
configurations** (tests/python/test_bench_footprint.py asserts it).

    python -m dampnet.latency.footprint [LIBRARY] [--entry dn_fullcar_step ...] [--json FILE]
    python -m dampnet.latency.footprint [LIBRARY] --dynamic [--config NAME ...] [--steps N] [--json FILE]

LIBRARY defaults to the runtime dampnet uses (dampnet.paths.shared_library()); an installed
library is stripped of its local symbols, so its unstripped twin in the source tree's build/
directory (the same GNU build ID) is read instead.
"""

from __future__ import annotations

import argparse
import bisect
import json
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

ENTRIES = ("dn_fullcar_step", "dn_loop_step")
# issue 30's ceiling on the full-car step's footprint, judged on the dynamic measure (--dynamic):
# the symbol sizes of the functions one step calls, the largest over FULLCAR_CONFIGS
FULLCAR_STEP_CEILING_BYTES = 16 * 1024

_FUNC_TYPES = set("tTwWi")
_DATA_TYPES = set("dDrRbBvV")
_INSN = re.compile(r"^\s*([0-9a-f]+):\s+(.*)$")
_BRANCH = re.compile(r"^(?:notrack\s+|bnd\s+)?(call|jmp|j[a-z]{1,3})q?\s+([0-9a-f]+)\s+<([^>]+)>")
_INDIRECT = re.compile(r"^(?:notrack\s+|bnd\s+)?(call|jmp)q?\s+\*")
_RIPREF = re.compile(r"#\s+([0-9a-f]+)\s+<([^>]+)>\s*$")


@dataclass
class Function:
    addr: int
    size: int
    name: str  # mangled
    demangled: str = ""
    calls: set[int] = field(default_factory=set)  # direct: other functions' start addresses
    taken: set[int] = field(default_factory=set)  # address taken or in a table of pointers read
    plt: set[str] = field(default_factory=set)  # calls out of the library, by name
    indirect_calls: int = 0  # call *... sites (jump tables' jmp * are inside the function)



def _function_at(funcs: dict[int, Function], starts: list[int], addr: int) -> Function | None:
    """The function whose code holds address addr (starts: the functions' sorted start addresses)."""
    i = bisect.bisect_right(starts, addr) - 1
    if i >= 0:
        f = funcs[starts[i]]
        if f.addr <= addr < f.addr + f.size:
            return f
    return None

def _tool(name: str) -> str:
    path = shutil.which(name)
    if not path:
        raise RuntimeError(f"{name} not found: the footprint needs binutils (apt-get install binutils)")
    return path


def _run(*cmd: str) -> str:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {proc.stderr.strip()[-2000:]}")
    return proc.stdout


def build_id(lib: Path) -> str | None:
    m = re.search(r"Build ID:\s*([0-9a-f]+)", _run(_tool("readelf"), "-n", str(lib)))
    return m.group(1) if m else None


def has_symtab(lib: Path) -> bool:
    return ".symtab" in _run(_tool("readelf"), "-S", "-W", str(lib))


def find_library(lib: Path | None = None) -> Path:
    """The library to read: `lib` (default: the runtime dampnet uses) when it has a symbol
    table, else its unstripped twin in the source tree's build/ directory (same build ID)."""
    if lib is None:
        from dampnet import paths

        lib = paths.shared_library()
    lib = Path(lib).resolve()
    if has_symtab(lib):
        return lib
    want = build_id(lib)
    root = Path(__file__).resolve().parents[3]
    for cand in sorted((root / "build").glob("*/libdampnet.so*"), key=lambda p: -p.stat().st_mtime):
        cand = cand.resolve()
        if cand.is_file() and want and build_id(cand) == want and has_symtab(cand):
            return cand
    raise RuntimeError(f"{lib} has no symbol table (stripped at install) and no unstripped build of it "
                       f"(GNU build ID {want}) is in {root / 'build'}: pass an unstripped libdampnet.so")


def _symbols(lib: Path) -> tuple[dict[int, Function], list[tuple[int, int, str]]]:
    funcs: dict[int, Function] = {}
    data: list[tuple[int, int, str]] = []
    for line in _run(_tool("nm"), "-S", "--defined-only", str(lib)).splitlines():
        parts = line.split()
        if len(parts) != 4:
            continue  # no size: linker-made labels
        addr, size, kind, name = int(parts[0], 16), int(parts[1], 16), parts[2], parts[3]
        if kind in _FUNC_TYPES and size > 0:
            old = funcs.get(addr)  # aliases: keep the global name
            if old is None or (kind.isupper() and not old.name.startswith("dn_")):
                funcs[addr] = Function(addr, size, name)
        elif kind in _DATA_TYPES and size > 0:
            data.append((addr, size, name))
    names = [f.name for f in funcs.values()]
    cxxfilt = shutil.which("c++filt")
    demangled = (subprocess.run([cxxfilt], input="\n".join(names), capture_output=True, text=True)
                 .stdout.splitlines() if cxxfilt else names)
    for f, d in zip(funcs.values(), demangled if len(demangled) == len(names) else names):
        f.demangled = d
    data.sort()
    return funcs, data


def _relative_relocs(lib: Path) -> list[tuple[int, int]]:
    """(where, target) of the R_*_RELATIVE dynamic relocations: the pointers in the data."""
    out = []
    for line in _run(_tool("objdump"), "-R", str(lib)).splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[1].endswith("_RELATIVE") and "+0x" in parts[2]:
            out.append((int(parts[0], 16), int(parts[2].split("+0x")[1], 16)))
    out.sort()
    return out


def analyse(lib: Path) -> dict[int, Function]:
    """Every sized function of the library with its outgoing edges."""
    funcs, data = _symbols(lib)
    starts = sorted(funcs)
    names_defined = {f.name: a for a, f in funcs.items()}
    relocs = _relative_relocs(lib)
    rel_where = [w for w, _ in relocs]
    data_starts = [a for a, _, _ in data]

    def func_at(addr: int) -> Function | None:
        return _function_at(funcs, starts, addr)

    def table_targets(addr: int) -> list[int]:
        i = bisect.bisect_right(data_starts, addr) - 1
        if i < 0 or not data[i][0] <= addr < data[i][0] + data[i][1]:
            return []
        lo, hi = data[i][0], data[i][0] + data[i][1]
        j = bisect.bisect_left(rel_where, lo)
        out = []
        while j < len(relocs) and relocs[j][0] < hi:
            if relocs[j][1] in funcs:
                out.append(relocs[j][1])
            j += 1
        return out

    cur: Function | None = None
    for line in _run(_tool("objdump"), "-d", "--no-show-raw-insn", "-j", ".text", str(lib)).splitlines():
        m = _INSN.match(line)
        if not m:
            continue
        addr, insn = int(m.group(1), 16), m.group(2).strip()
        if cur is None or not cur.addr <= addr < cur.addr + cur.size:
            cur = func_at(addr)
            if cur is None:
                continue
        b = _BRANCH.match(insn)
        if b:
            target, label = int(b.group(2), 16), b.group(3)
            if label.endswith("@plt"):
                name = label[:-4]
                if name in names_defined:  # the library's own exported function, through its PLT
                    cur.calls.add(names_defined[name])
                else:
                    cur.plt.add(name)
                continue
            callee = func_at(target)
            if callee is not None and callee is not cur:
                cur.calls.add(callee.addr)
            continue
        if _INDIRECT.match(insn):
            if insn.split()[0].endswith("call") or insn.startswith(("call", "notrack call")):
                cur.indirect_calls += 1
            continue
        r = _RIPREF.search(insn)
        if r:
            ref = int(r.group(1), 16)
            if ref in funcs and ref != cur.addr:
                cur.taken.add(ref)  # lea fn(%rip): the address of a function
            else:
                cur.taken.update(t for t in table_targets(ref) if t != cur.addr)
    return funcs


def footprint(funcs: dict[int, Function], entry: str) -> dict:
    """The functions reachable from `entry`, their sizes and the total [bytes]."""
    by_name = {f.name: f for f in funcs.values()}
    if entry not in by_name:
        raise RuntimeError(f"{entry} is not a function of the library")
    root = by_name[entry]
    seen = {root.addr: "entry"}
    todo = [root.addr]
    while todo:
        f = funcs[todo.pop()]
        for kind, targets in (("call", f.calls), ("pointer", f.taken)):
            for t in sorted(targets):
                if t not in seen:
                    seen[t] = kind
                    todo.append(t)
    rows = sorted(({"function": funcs[a].demangled or funcs[a].name, "symbol": funcs[a].name,
                    "address": f"{a:#x}", "bytes": funcs[a].size, "reached_by": how, "cold": funcs[a].name.endswith(".cold"),
                    "indirect_calls": funcs[a].indirect_calls} for a, how in seen.items()),
                  key=lambda r: (-r["bytes"], r["function"]))
    # local functions of one name in several translation units (a template's .isra clone, an
    # inline function kept local): each copy is code of its own
    count: dict[str, int] = {}
    for r in rows:
        count[r["symbol"]] = count.get(r["symbol"], 0) + 1
    for r in rows:
        r["copies"] = count[r["symbol"]]
    total = sum(r["bytes"] for r in rows)
    cold = sum(r["bytes"] for r in rows if r["cold"])
    plt = sorted(set().union(*(funcs[a].plt for a in seen)))
    return {"entry": entry, "total_bytes": total, "cold_bytes": cold, "hot_bytes": total - cold,
            "entry_bytes": root.size, "n_functions": len(rows), "functions": rows,
            "duplicate_bytes": sum(r["bytes"] for r in rows if r["copies"] > 1)
            - sum({r["symbol"]: r["bytes"] for r in rows if r["copies"] > 1}.values()),
            "external_calls": plt, "unresolved_indirect_calls": sum(r["indirect_calls"] for r in rows)}


def measure(lib: Path | None = None, entries=ENTRIES) -> dict:
    path = find_library(lib)
    funcs = analyse(path)
    return {"library": str(path), "build_id": build_id(path),
            "entries": {e: footprint(funcs, e) for e in entries}}


def summary(res: dict) -> dict:
    """The totals only (for `dampnet bench`'s JSON)."""
    return {"library": res["library"], "build_id": res["build_id"],
            **{f"{e}_bytes": r["total_bytes"] for e, r in res["entries"].items()},
            **{f"{e}_hot_bytes": r["hot_bytes"] for e, r in res["entries"].items()}}


# ---- the dynamic footprint: the functions one configuration's steps actually call ----------

#: the configurations of bench/footprint_steps.c (dampnet bench's case names): the full car's
#: five (a shared float damper reading a per step (the HIL case) and per stage, four separate
#: damper objects per step and per stage, a shared double-precision damper), two quarter cars
DYNAMIC_CONFIGS = (
    "fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel",
    "fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel_four_calls",
    "fullcar_step_rk4_per_step_eval_neural_double_skyhook_linear_accel",
    "fullcar_step_rk4_neural_float_skyhook_linear_accel",
    "fullcar_step_rk4_neural_float_skyhook_linear_accel_four_calls",
    "loop_step_rk4_per_step_eval_neural_float_skyhook_linear_accel",
    "loop_step_rk4_neural_float_skyhook",
)
FULLCAR_CONFIGS = tuple(c for c in DYNAMIC_CONFIGS if c.startswith("fullcar_"))
DRIVER_SOURCE = "footprint_steps.c"
MEASURED_FN = "dn_fp_measured"
_CG_POS = re.compile(r"^(?:\+|-)?(0x[0-9a-f]+|\d+)\s")


def driver_source() -> tuple[Path, Path]:
    """bench/footprint_steps.c and the default model's header directory (installed or in the
    source tree, as the latency harness's)."""
    from dampnet.latency.harness import harness_sources

    bench_src, header_dir = harness_sources()
    src = bench_src.parent / DRIVER_SOURCE
    if not src.is_file():
        src = Path(__file__).resolve().parents[3] / "bench" / DRIVER_SOURCE
    if not src.is_file():
        raise RuntimeError(f"{DRIVER_SOURCE} not found beside {bench_src}")
    return src, header_dir


def build_driver(lib: Path, out_dir: Path) -> Path:
    """Compile bench/footprint_steps.c against `lib` (run with it: rpath)."""
    from dampnet import paths

    cc = shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise RuntimeError("no C compiler (cc) found: install the Debian package build-essential")
    src, header_dir = driver_source()
    out_dir.mkdir(parents=True, exist_ok=True)
    exe = out_dir / "footprint_steps"
    cmd = [cc, "-std=c11", "-O1", "-g0", *[f"-I{d}" for d in paths.include_dirs()], f"-I{header_dir}",
           str(src), "-o", str(exe), str(lib), f"-Wl,-rpath,{lib.parent}", "-lm", "-ldl"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"building the footprint driver failed:\n{' '.join(cmd)}\n{proc.stderr[-3000:]}")
    return exe


def executed_addresses(exe: Path, lib: Path, config: str, n_steps: int, out_dir: Path) -> tuple[int, dict[int, int]]:
    """Run `config`'s n_steps under callgrind, collecting only inside dn_fp_measured (the timed
    steps; the set-up and 2000 settling steps before it are not collected). Returns the
    library's load address and {instruction address in `lib`: times executed} (callgrind
    writes a shared object's addresses relative to its load address: the symbol table's)."""
    valgrind = shutil.which("valgrind")
    if not valgrind:
        raise RuntimeError("valgrind not found: the dynamic footprint runs callgrind (install the Debian "
                           "package valgrind)")
    out = out_dir / f"callgrind.{config}.out"
    cmd = [valgrind, "--tool=callgrind", f"--callgrind-out-file={out}", "--dump-instr=yes",
           "--compress-pos=no", "--compress-strings=no", "--collect-atstart=no",
           f"--toggle-collect={MEASURED_FN}", str(exe), config, str(n_steps)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    m = re.search(r"^BASE (0x[0-9a-f]+)", proc.stdout, re.M)
    if not m:
        raise RuntimeError(f"the footprint driver printed no BASE line: {proc.stdout[-500:]}")
    hits: dict[int, int] = {}
    events = None
    want = lib.resolve()
    ours: dict[str, bool] = {}
    in_lib = False
    for line in out.read_text().splitlines():
        if line.startswith("events:"):
            events = line.split()[1:]
            continue
        if line.startswith("ob="):  # the object of the positions that follow (file-relative)
            name = line[3:].strip()
            if name not in ours:
                ours[name] = Path(name).exists() and Path(name).resolve() == want
            in_lib = ours[name]
            continue
        if not in_lib or not line or not (line[0].isdigit() or line[0] in "+-"):
            continue  # headers, fn=/cfn=/calls= lines, other objects (libm, libc, the driver)
        pm = _CG_POS.match(line)
        if pm:
            tok = pm.group(1)
            addr = int(tok, 16) if tok.startswith("0x") else int(tok)
            ir = int(line.split()[1]) if events and len(line.split()) > 1 else 1
            hits[addr] = hits.get(addr, 0) + ir
    return int(m.group(1), 16), hits


def dynamic_footprint(funcs: dict[int, Function], base: int, hits: dict[int, int], config: str,
                      n_steps: int) -> dict:
    """The library functions that executed at least one instruction in the measured steps,
    their symbol sizes and the total [bytes]."""
    starts = sorted(funcs)

    def func_at(off: int) -> Function | None:
        return _function_at(funcs, starts, off)

    lo, hi = starts[0], max(f.addr + f.size for f in funcs.values())
    per: dict[int, list[int]] = {}
    outside = 0
    for addr, ir in hits.items():
        # the symbol table's addresses (callgrind's for a shared object); a run-time address
        # (a callgrind that wrote those) is taken back by the load address
        off = addr if lo <= addr < hi and func_at(addr) is not None else addr - base
        f = func_at(off)
        if f is None:
            outside += 1
            continue
        row = per.setdefault(f.addr, [0, 0])
        row[0] += 1
        row[1] += ir
    rows = sorted(({"function": funcs[a].demangled or funcs[a].name, "symbol": funcs[a].name,
                    "address": f"{a:#x}", "bytes": funcs[a].size, "executed_instructions": n,
                    "instructions_run": ir, "cold": funcs[a].name.endswith(".cold")}
                   for a, (n, ir) in per.items()), key=lambda r: (-r["bytes"], r["function"]))
    total = sum(r["bytes"] for r in rows)
    return {"config": config, "n_steps": n_steps, "total_bytes": total, "n_functions": len(rows),
            "functions": rows, "instructions_outside_library": outside,
            "executed_instructions": sum(r["executed_instructions"] for r in rows)}


def measure_dynamic(lib: Path | None = None, configs=FULLCAR_CONFIGS, n_steps: int = 10,
                    work_dir: Path | None = None) -> dict:
    """The dynamic footprint of each configuration (see the module docstring)."""
    import tempfile

    path = find_library(lib)
    funcs = {a: f for a, f in _symbols(path)[0].items()}
    unknown = [c for c in configs if c not in DYNAMIC_CONFIGS]
    if unknown:
        raise RuntimeError(f"unknown configuration(s) {', '.join(unknown)}; known: {', '.join(DYNAMIC_CONFIGS)}")
    with tempfile.TemporaryDirectory(prefix="dn_footprint_") as tmp:
        wd = Path(work_dir) if work_dir else Path(tmp)
        exe = build_driver(path, wd)
        res = {}
        for c in configs:
            base, hits = executed_addresses(exe, path, c, n_steps, wd)
            res[c] = dynamic_footprint(funcs, base, hits, c, n_steps)
    fc = [res[c]["total_bytes"] for c in configs if c in FULLCAR_CONFIGS]
    return {"library": str(path), "build_id": build_id(path), "configs": res,
            "fullcar_step_max_bytes": max(fc) if fc else None,
            "ceiling_bytes": FULLCAR_STEP_CEILING_BYTES,
            "within_ceiling": bool(fc) and max(fc) <= FULLCAR_STEP_CEILING_BYTES}


def format_dynamic(res: dict, width: int = 110) -> str:
    lines = [f"library: {res['library']} (build ID {res['build_id']})",
             "dynamic footprint: symbol sizes of the library functions the steps executed (callgrind)"]
    for c, r in res["configs"].items():
        lines.append(f"\n{c} ({r['n_steps']} steps): {r['total_bytes']} bytes in {r['n_functions']} functions")
        lines.append(f"  {'bytes':>7}  {'run':>6}  function   (run: distinct instructions executed)")
        for row in r["functions"]:
            name = row["function"] if len(row["function"]) <= width else row["function"][:width - 3] + "..."
            lines.append(f"  {row['bytes']:>7}  {row['executed_instructions']:>6}  {name}")
        lines.append(f"  {r['total_bytes']:>7}  total")
    if res["fullcar_step_max_bytes"] is not None:
        verdict = "within" if res["within_ceiling"] else "ABOVE"
        lines.append(f"\nfull-car step, the largest over its configurations: {res['fullcar_step_max_bytes']} bytes, "
                     f"{verdict} issue 30's ceiling of {res['ceiling_bytes']} bytes")
    return "\n".join(lines)


def format_report(res: dict, width: int = 120) -> str:
    lines = [f"library: {res['library']} (build ID {res['build_id']})"]
    for e, r in res["entries"].items():
        lines.append(f"\n{e}: {r['total_bytes']} bytes in {r['n_functions']} functions "
                     f"({r['hot_bytes']} without the .cold parts' {r['cold_bytes']})")
        lines.append(f"  {'bytes':>7}  {'via':<7}  function")
        for row in r["functions"]:
            name = row["function"] if len(row["function"]) <= width else row["function"][:width - 3] + "..."
            extra = f"  [{row['indirect_calls']} indirect call(s)]" if row["indirect_calls"] else ""
            extra += f"  [one of {row['copies']} copies]" if row["copies"] > 1 else ""
            lines.append(f"  {row['bytes']:>7}  {row['reached_by']:<7}  {name}{extra}")
        lines.append(f"  {r['total_bytes']:>7}  total ({r['duplicate_bytes']} of it in second copies of a function)")
        lines.append(f"  calls out of the library (not counted): {', '.join(r['external_calls']) or 'none'}")
        lines.append(f"  indirect calls with unknown targets: {r['unresolved_indirect_calls']}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dampnet.latency.footprint", description=__doc__.split("\n\n")[0])
    ap.add_argument("library", nargs="?", default=None, help="libdampnet.so (default: the runtime dampnet uses)")
    ap.add_argument("--entry", action="append", default=None, help=f"entry symbol (default: {', '.join(ENTRIES)})")
    ap.add_argument("--dynamic", action="store_true",
                    help="the functions the steps actually call (callgrind), per configuration, instead of the static walk")
    ap.add_argument("--config", action="append", default=None, choices=DYNAMIC_CONFIGS, metavar="CONFIG",
                    help=f"with --dynamic: a configuration (default: the full car's {len(FULLCAR_CONFIGS)}); "
                         f"one of {', '.join(DYNAMIC_CONFIGS)}")
    ap.add_argument("--steps", type=int, default=10, help="with --dynamic: steps measured (default 10)")
    ap.add_argument("--json", default=None, help="also write the result to this JSON file")
    args = ap.parse_args(argv)
    try:
        lib = Path(args.library) if args.library else None
        if args.dynamic:
            res = measure_dynamic(lib, tuple(args.config or FULLCAR_CONFIGS), args.steps)
            print(format_dynamic(res))
        else:
            res = measure(lib, tuple(args.entry or ENTRIES))
            print(format_report(res))
    except RuntimeError as e:
        print(f"footprint: error: {e}", file=sys.stderr)
        return 2
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
