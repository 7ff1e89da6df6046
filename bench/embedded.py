"""Flash, RAM, instructions and a cycle estimate of dampnet on Cortex-M4F and Cortex-M7 (QEMU),
beside emlearn's C for the same 3-30-1 network (bench/RESULTS.md, "On a microcontroller").

    python bench/embedded.py [--json FILE] [--fp-contract off|fast] [--loop-float 0|1] [--out-dir DIR]
                             [--no-worst-step]  # ~10 min (the per-step traces; ~1 min without);
                                                # needs the cross toolchain, QEMU and emlearn
                                                # (python/env.sh installs all three)
    python bench/embedded.py --unroll-sweep [--json FILE] [--fp-contract off|fast]  # the kernel's
                                                # flash against instructions, DN_KERNEL_UNROLL 1/2/4/8
    python bench/embedded.py --inverse-only [--json FILE]  # the damper inverse's instructions alone
                                                # (~1 min; also part of the full run)
    python bench/embedded.py --step-model MODEL [--json FILE] [--no-worst-step]  # the quarter-car
                                                # step of a hybrid MODEL (its physics terms, e.g. a
                                                # valve) beside its network alone (~2 min)

What it does, per core (cortex-m4: mps2-an386, cortex-m7: mps2-an500), with the presets'
configuration (bench/firmware_lab.py: DEFAULT_CAPS; python/dampnet/export/mcu.py: DEFAULT_KERNEL; -O3, -ffp-contract=off);
builds go to --out-dir (default build/bench-embedded), so that runs with different options or
from different checkouts need not share one:

* builds the firmware of cpp/embedded/ three ways: the harness alone (DN_FW_PART 0), + the MLP
  (1: dn_mlp_init_folded on the model header's folded float weights, dn_mlp_forward_f), + the
  MLP, neural damper, quarter-car loop and skyhook controller (2);
* flash = .text (code and constants) + .ARM.exidx + .init_array + .data's load image, the stored
  test data (dn_fw_x_, dn_fw_road) excluded, minus the harness's (whose printing and timing
  helpers are functions of their own in every variant, firmware.c HARNESS: a part's flash is the
  code and data it adds, not inlined copies of them); RAM = .data + .bss minus the
  harness's (the objects' static storage) + the peak stack measured by painting (the largest of
  set-up and run);
* runs it under QEMU -icount shift=0: SysTick then counts instructions (the firmware's
  calibration loop gives 40 per tick on both boards); per call = (timed loop - the same loop
  calling an empty function) / calls, over the 1,000 stored inputs and the 10,000 steps;
* compiles emlearn's generated C (its "loadable" eml_net, tanhf from newlib's libm) for the same
  folded weights with the same flags into the same harness (DN_FW_PART 3) and measures it the
  same way, and from an execution trace the share of its instructions inside newlib's tanhf;
* the worst step: the instructions of each of the 10,000 steps, exact, from a QEMU execution
  trace (-d exec: every translation block's instructions, counted inside the functions reachable
  from dn_loop_step, one count per call), on the stored thesis rough road and on an ISO 8608
  class D road (200 m, seed 1) at the same speed, whose firmware's loop is also checked against
  the host's; the mean of those counts is a little above the SysTick figure (the call's own
  instructions); the M4F's worst-case cycles are the worst step's instructions times the step's
  mean cycles per instruction;
* the damper's inverse (issue 55): the full build once more with the stored inverse cases
  (dampnet.export.mcu.inverse_vectors: 300, reachable, unreachable and non-finite; the builds
  above have none, so their sizes are the loop's alone), its results first checked against the
  host's inverse (firmware_lab.inverse_vs_host); instructions per call of dn_damper_force at the
  cases' inputs (the forward through the damper API: the reference) and of dn_damper_inverse
  (SysTick loops, stub subtracted: means; each call's own ticks, corrected by the difference of
  their mean from the loop's, for medians per kind of case), their ratio (the issue's target:
  <= 3x on the M4F), the evaluations per inverse (n_evals: the limits' included), the instructions of
  one more evaluation (a least-squares line through the reachable cases), the flash the part adds
  (dampnet::Damper::search and eval_u, the inverse's code, whose sizes the symbol table gives: the loop's build leaves the force
  laws out, DN_CONTROLLER_KINDS; dn_damper_init_neural and the call sites) and its peak stack
  (the damper, 1,184 B on the M4F, on the stack);
* the cycle estimate (Cortex-M4F only): the instructions times the mean cycles per instruction
  of the executed instruction mix, taken from a QEMU execution trace (-d exec) of the functions
  reachable from dn_mlp_forward_f / dn_loop_step, each instruction weighted by the Cortex-M4
  Technical Reference Manual's timings (ALU 1, load/store 2, LDM/STM/PUSH/POP 1+N, branch 2
  (1 not taken, 2-4 taken), SDIV/UDIV 12 (2-12), VADD/VMUL 1, VMLA/VFMA 3, VDIV/VSQRT 14,
  VLDR/VSTR 2, VLDM/VSTM/VPUSH/VPOP 1+N). An estimate: no wait states, no cache, no interrupts.

--step-model MODEL builds the full firmware (no inverse cases) twice per core from MODEL's header
(dampnet.export.write_header; firmware_lab.model_defines): with its physics terms (the library's
DN_CAP_TERMS their number; the firmware sets its loop up through a damper, dn_damper_add_term) and
without them (the presets' capacities, the folded set-up), each with the controller made for it and
its loop checked against the host's; per build the SysTick mean step, kernel + loop + controller
flash and RAM, and (unless --no-worst-step) every step's instructions on both roads from the traces
(the terms' functions, called through their table's pointers, counted in: INDIRECT), on the M4F
each step's cycles too (the TRM timings) with the functions they go to, mean and worst step. Its M4F
cycles: the SysTick mean and the worst step's instructions at the traced steps' mean cycles per
instruction (as above, but from both roads' 20,000 steps, not the short road), and the most cycles
of one traced step.

--unroll-sweep builds only the harness and the MLP part, per core, for DN_KERNEL_SMALL 1 with
DN_KERNEL_UNROLL 1, 2, 4 and 8 and for DN_KERNEL_SMALL 0 (two forwards, 8 neurons per pass), and
prints each one's kernel flash and forward instructions (about two minutes).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))

import firmware_lab as emb  # noqa: E402  (bench/, this script's folder)
from dampnet.modeldir import load_model  # noqa: E402

OUT_DEFAULT = ROOT / "build" / "bench-embedded"
SYMS_DATA = ("dn_fw_x_", "dn_fw_road", "dn_fw_inv_")
BUDGET_HZ, CLOCK_HZ = 10_000, 168e6  # the 10 kHz step on a 168 MHz Cortex-M4F


def _out(cmd) -> str:
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, check=True).stdout


def sizes(elf: Path) -> dict:
    """Flash and static RAM of an image, the stored test data excluded."""
    sec = {}
    for line in _out(["arm-none-eabi-size", "-A", elf]).splitlines():
        f = line.split()
        if len(f) >= 2 and f[0].startswith("."):
            sec[f[0]] = int(f[1])
    data = 0
    for line in _out(["arm-none-eabi-nm", "-S", elf]).splitlines():
        f = line.split()
        if len(f) == 4 and f[3] in SYMS_DATA:
            data += int(f[1], 16)
    flash = sec.get(".text", 0) + sec.get(".ARM.exidx", 0) + sec.get(".init_array", 0) + sec.get(".data", 0) - data
    return {"flash": flash, "ram_static": sec.get(".data", 0) + sec.get(".bss", 0)}


# ---- the cycle estimate: the executed instruction mix under the M4's documented timings ----

def _disassembly(elf: Path):
    """address -> (mnemonic, operands, function) for every instruction; the function symbols."""
    ins, funcs = {}, {}
    cur = None
    for line in _out(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", elf]).splitlines():
        m = re.match(r"^([0-9a-f]+) <([^>]+)>:$", line)
        if m:
            cur = m.group(2)
            funcs[cur] = int(m.group(1), 16)
            continue
        m = re.match(r"^\s+([0-9a-f]+):\s+(\S+)\s*(.*)$", line)
        if m and cur:
            ins[int(m.group(1), 16)] = (m.group(2), m.group(3), cur)
    return ins, funcs


def _cycles(mn: str, ops: str) -> float:
    m = mn.split(".")[0]
    n_regs = ops.count(",") + 1 if "{" in ops else 1
    if m in ("vdiv", "vsqrt"):
        return 14
    if m in ("vmla", "vmls", "vfma", "vfms", "vnmla", "vnmls", "vfnma", "vfnms"):
        return 3
    if m in ("vldr", "vstr"):
        return 2
    if m in ("vldm", "vstm", "vpush", "vpop", "vldmia", "vstmia", "vldmdb", "vstmdb"):
        return 1 + n_regs
    if m in ("ldm", "stm", "push", "pop", "ldmia", "stmia", "ldmdb", "stmdb"):
        return 1 + n_regs
    if m in ("ldrd", "strd"):
        return 3
    if m.startswith(("ldr", "str")):
        return 2
    if m in ("sdiv", "udiv"):
        return 12
    if m in ("b", "bl", "bx", "blx", "cbz", "cbnz") or (m.startswith("b") and len(m) <= 3 and m not in ("bic", "bfi", "bfc")):
        return 2
    return 1


def _is_branch(mn: str, ops: str) -> bool:
    m = mn.split(".")[0]
    if m in ("b", "bl", "bx", "blx", "cbz", "cbnz", "bkpt", "tbb", "tbh") or re.fullmatch(r"b(eq|ne|cs|cc|hs|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le)", m):
        return True
    return ("pc" in ops and (m.startswith(("pop", "ldm", "ldr", "mov", "add")) and ops.split(",")[0].strip("{} ") == "pc")) or \
        (m == "pop" and "pc" in ops)


def _call_graph(ins: dict) -> dict[str, set[str]]:
    """function -> the functions it calls or jumps to directly (bl/b/blx to a symbol)."""
    calls: dict[str, set[str]] = {}
    for mn, ops, fn in ins.values():
        m = re.search(r"<([^>+]+)>", ops)
        if m and mn.split(".")[0] in ("bl", "b", "blx") and m.group(1) != fn:
            calls.setdefault(fn, set()).add(m.group(1))
    return calls


#: functions a step calls through pointers, which the call graph (direct bl/b) does not see: the
#: physics terms' table (terms.hpp: force_/grad_<kind id>, and what they call: log1pf, expm1f)
INDIRECT = re.compile(r"_DN_TERM_")


def _reach(calls: dict[str, set[str]], root: str) -> set[str]:
    """root and the functions it reaches directly, with the indirect ones (INDIRECT) of the image
    and theirs when the image has any (only a hybrid model's firmware calls them)."""
    seen, todo = set(), [root, *(f for f in calls if INDIRECT.search(f))]
    while todo:
        f = todo.pop()
        if f not in seen:
            seen.add(f)
            todo.extend(calls.get(f, ()))
    return seen


def _trace_blocks(elf: Path, cpu: str, log: Path, ins: dict):
    """(pc, instructions, M4 cycles, function) of every translation block the firmware executes,
    in order, from a QEMU -d exec,nochain trace (a block: from its pc to the first branch)."""
    subprocess.run(["qemu-system-arm", "-M", emb.CPUS[cpu]["machine"], "-nographic", "-monitor", "none",
                    "-serial", "none", "-semihosting-config", "enable=on,target=native", "-kernel", str(elf),
                    "-d", "exec,nochain", "-D", str(log)], capture_output=True, timeout=900, check=True)
    addrs = sorted(ins)
    index = {a: i for i, a in enumerate(addrs)}
    tb_cost: dict[int, tuple[int, float, str]] = {}
    pc_re = re.compile(r"\[[0-9a-f]+/([0-9a-f]+)/")
    try:
        with open(log) as fh:
            for line in fh:
                m = pc_re.search(line)
                if not m:
                    continue
                pc = int(m.group(1), 16)
                if pc not in tb_cost:
                    i, n, c = index.get(pc), 0, 0.0
                    fn = ins[pc][2] if pc in ins else ""
                    while i is not None and i < len(addrs) and n < 512:
                        mn, ops, _ = ins[addrs[i]]
                        n += 1
                        c += _cycles(mn, ops)
                        # QEMU ends a block at a branch, and where the next instruction starts on
                        # another page (1 KB on M-profile): the next block is logged on its own
                        if _is_branch(mn, ops) or (i + 1 < len(addrs) and addrs[i + 1] >> 10 != pc >> 10):
                            break
                        i += 1
                    tb_cost[pc] = (n, c, fn)
                yield (pc, *tb_cost[pc])
    finally:
        log.unlink(missing_ok=True)


def trace_mix(elf: Path, cpu: str, roots: dict[str, str], log: Path, after: dict | None = None) -> dict:
    """{name: (instructions, M4 cycles)} executed inside the functions reachable from each root
    (name -> function), from a QEMU execution trace of the firmware. after[name] = (function,
    True/False): count that root's instructions only after (True) / before (False) the trace
    first enters the function: the firmware runs the MLP part before the loop part, and both
    reach the same kernel, so the loop's mix is taken from the steps only and the forward's from
    the MLP part only."""
    ins, funcs = _disassembly(elf)
    calls = _call_graph(ins)
    reach_sets = {k: _reach(calls, r) for k, r in roots.items()}
    acc = {k: [0, 0.0] for k in roots}
    after = after or {}
    gates = {f: funcs.get(f) for f, _ in after.values()}
    entered = {f: False for f in gates}
    for pc, n, c, fn in _trace_blocks(elf, cpu, log, ins):
        for f, addr in gates.items():
            if pc == addr:
                entered[f] = True
        for k, s in reach_sets.items():
            if k in after and entered[after[k][0]] != after[k][1]:
                continue
            if fn in s:
                acc[k][0] += n
                acc[k][1] += c
    return {k: (n, c) for k, (n, c) in acc.items()}


def trace_cpi(elf: Path, cpu: str, roots: dict[str, str], log: Path, after: dict | None = None) -> dict:
    """Mean cycles per instruction (M4 timings) of each root's executed mix (trace_mix)."""
    return {k: (c / n if n else float("nan")) for k, (n, c) in trace_mix(elf, cpu, roots, log, after).items()}


def per_call_instructions(elf: Path, cpu: str, root: str, log: Path) -> np.ndarray:
    """The instructions of every call of `root` (the function and what it calls), in order, from
    a QEMU execution trace: exact per call, where SysTick (40 instructions a tick) gives means.
    Counting starts at the first call (the MLP part's forwards, before, reach the same kernel)."""
    return per_call_trace(elf, cpu, root, log)["instructions"]


def per_call_trace(elf: Path, cpu: str, root: str, log: Path) -> dict:
    """per_call_instructions with the M4 cycles (TRM timings, _cycles) of every call, and per
    function (demangled) its instructions and cycles summed over the calls ("functions") and those
    of the call with the most instructions ("functions_worst")."""
    ins, funcs = _disassembly(elf)
    inside = _reach(_call_graph(ins), root) | {f for f in funcs if INDIRECT.search(f)}
    entry = funcs[root]
    counts: list[int] = []
    cycles: list[float] = []
    total: dict[str, list] = {}
    cur: dict[str, list] = {}
    worst: dict[str, list] = {}
    for pc, n, c, fn in _trace_blocks(elf, cpu, log, ins):
        if pc == entry:
            if counts and (len(counts) == 1 or counts[-1] > max(counts[:-1])):
                worst = cur
            counts.append(0)
            cycles.append(0.0)
            cur = {}
        if counts and fn in inside:
            counts[-1] += n
            cycles[-1] += c
            for acc in (total, cur):
                a = acc.setdefault(fn, [0, 0.0])
                a[0] += n
                a[1] += c
    if counts and (len(counts) == 1 or counts[-1] > max(counts[:-1])):
        worst = cur
    names = _demangle(list(total))
    return {"instructions": np.array(counts), "cycles": np.array(cycles),
            "functions": {names[f]: v for f, v in total.items()},
            "functions_worst": {names[f]: v for f, v in worst.items()}}


def _demangle(symbols: list[str]) -> dict[str, str]:
    if not symbols:
        return {}
    out = subprocess.run(["arm-none-eabi-c++filt"], input="\n".join(symbols), capture_output=True, text=True).stdout
    lines = out.splitlines()
    return dict(zip(symbols, lines)) if len(lines) == len(symbols) else {f: f for f in symbols}


# ---- emlearn ----

def emlearn_sources(model, out_dir: Path) -> Path:
    """emlearn's C for the default model's network, the mapminmax scalings folded into the first
    and last layers (as dampnet's load() folds them), and the glue dn_fw_emlearn_forward."""
    import emlearn.net

    w1 = np.asarray(model.w1, float) * np.asarray(model.in_gain, float)[None, :]
    b1 = np.asarray(model.b1, float) + np.asarray(model.w1, float) @ (
        model.in_ymin - np.asarray(model.in_gain) * np.asarray(model.in_offset))
    w_out = np.asarray(model.w_out, float).reshape(-1) / model.out_gain
    b_out = (float(np.asarray(model.b_out).reshape(-1)[0]) - model.out_ymin) / model.out_gain + model.out_offset
    net = emlearn.net.Wrapper(["tanh", "identity"], [w1.T.astype(np.float32), w_out.reshape(-1, 1).astype(np.float32)],
                              [b1.astype(np.float32), np.array([b_out], np.float32)], classifier="loadable",
                              return_type="regressor")
    out_dir.mkdir(parents=True, exist_ok=True)
    net.save(name="dnmodel", file=str(out_dir / "dnmodel.h"))
    glue = out_dir / "emlearn_glue.c"
    glue.write_text('#include "dnmodel.h"\n'
                    "float dn_fw_emlearn_forward(const float* x) { return eml_net_regress1(&dnmodel, x, 3); }\n")
    return glue


def build_manual(cpu: str, part: int, bdir: Path, vectors: Path, extra_src=(), extra_inc=(),
                 fp_contract: str = "off") -> Path:
    """firmware.c + startup.c (+ extra sources) with the CMake build's flags, by hand."""
    import emlearn

    flags = emb.CPUS[cpu]["flags"].split() + ["-O3", "-DNDEBUG", "-std=gnu99", "-ffunction-sections",
                                              "-fdata-sections", f"-ffp-contract={fp_contract}"]
    inc = [f"-I{ROOT / 'cpp' / 'include'}", f"-I{ROOT / 'export'}", f"-I{bdir / 'cpp' / 'embedded'}",
           f"-I{Path(emlearn.__file__).parent}", *[f"-I{d}" for d in extra_inc]]
    elf = bdir / f"manual_part{part}.elf"
    subprocess.run(["arm-none-eabi-gcc", *flags, *inc, f"-DDN_FW_PART={part}", f'-DDN_FW_CPU="{cpu}"',
                    f'-DDN_FW_VECTORS="{vectors}"', "-DDN_STATIC", "--specs=nano.specs", "-nostartfiles",
                    "-Wl,--gc-sections", f"-T{ROOT / 'cpp' / 'embedded' / 'mps2.ld'}",
                    str(ROOT / "cpp" / "embedded" / "firmware.c"), str(ROOT / "cpp" / "embedded" / "startup.c"),
                    *map(str, extra_src), "-lm", "-o", str(elf)], check=True, capture_output=True, text=True)
    return elf


def worst_steps(cpu: str, roads: dict[str, tuple[Path, object]], model, out: Path, fp_contract: str,
                loop_float: int | None, first_elf: Path, tag: str = "", profile: bool = False, **build) -> dict:
    """Per road (name -> (vectors header, Vectors)): the instructions of every quarter-car step
    (per_call_instructions: exact, from an execution trace), their mean and maximum and where it
    is. The first road's firmware is `first_elf`; each other one is built (with `build`'s options,
    in a directory named with `tag`) and its loop checked against the host's on that road.
    profile (--step-model): also the steps' M4 cycles (per_call_trace) and where they go."""
    res = {}
    tag = ("" if loop_float is None else f"-loopfloat{int(loop_float)}") + tag
    for k, (name, (header, vec)) in enumerate(roads.items()):
        elf = first_elf
        if k:
            bdir = emb.build(cpu, out / f"{cpu}-{fp_contract}{tag}-{name}", vectors=header, fp_contract=fp_contract,
                             loop_float=loop_float, targets=("dn_firmware",), **build)
            elf = emb.firmware_path(bdir)
            host = emb.loop_vs_host(model, vec.road, emb.parse_output(emb.run(elf, cpu)))
            if not host["within"]:
                raise SystemExit(f"{cpu} on {name}: the firmware's loop differs from the host's: {host}")
        tr = per_call_trace(elf, cpu, "dn_loop_step", out / "trace.log")
        steps = tr["instructions"]
        assert len(steps) == len(vec.road), (len(steps), len(vec.road))
        res[name] = {"mean": float(steps.mean()), "max": int(steps.max()), "min": int(steps.min()),
                     "max_at_step": int(steps.argmax()) + 1, "max_over_mean": float(steps.max() / steps.mean())}
        if profile:
            cyc, n = tr["cycles"], len(steps)
            res[name].update({
                "cpi": float(cyc.sum() / steps.sum()), "cycles_mean": float(cyc.mean()), "cycles_max": float(cyc.max()),
                "cycles_max_at_step": int(cyc.argmax()) + 1,
                # per function: instructions and cycles of the mean step, and of the step with the most instructions
                "functions_mean_step": {f: [v[0] / n, v[1] / n] for f, v in
                                        sorted(tr["functions"].items(), key=lambda kv: -kv[1][1])},
                "functions_worst_step": {f: [v[0], v[1]] for f, v in
                                         sorted(tr["functions_worst"].items(), key=lambda kv: -kv[1][1])}})
    return res


def measure_step_model(cpu: str, model, name: str, out: Path, fp_contract: str = "off",
                       loop_float: int | None = None, worst: bool = True) -> dict:
    """--step-model: the quarter-car step of `model` (a hybrid model's terms included: the library
    built with DN_CAP_TERMS = its number of terms, the presets' capacities otherwise), on the
    thesis rough road and the ISO 8608 class D road: the SysTick mean, each step's instructions and
    (M4 timings) cycles from the traces, their worst, where they go, and kernel + loop + controller
    flash and RAM (the harness's subtracted)."""
    from dampnet.export import write_header
    from dampnet.sim.roads import iso8608

    mdir = out / f"model-{name}"
    mdir.mkdir(parents=True, exist_ok=True)
    header = write_header(model, mdir / "model.h", overwrite=True)
    build = {"caps": {**emb.DEFAULT_CAPS, "TERMS": len(model.terms)},
             "firmware_defines": emb.model_defines(header, model)}
    roads = {"thesis_rough": (mdir / "vectors.h", emb.make_vectors(model, n_inv=0)),
             "iso8608_D": (mdir / "vectors_iso8608_D.h", emb.make_vectors(model, road=iso8608("D", 200.0, seed=1),
                                                                        n_inv=0))}
    for h, vec in roads.values():
        emb.write_vectors(h, vec, model=model)
    tag = "" if loop_float is None else f"-loopfloat{int(loop_float)}"
    bdir = emb.build(cpu, out / f"{cpu}-{fp_contract}{tag}-step-{name}", vectors=roads["thesis_rough"][0],
                     fp_contract=fp_contract, loop_float=loop_float, targets=("dn_firmware", "dn_firmware_base"),
                     **build)
    elf = emb.firmware_path(bdir)
    fw = emb.parse_output(emb.run(elf, cpu))
    assert fw.errors == 0
    host = emb.loop_vs_host(model, roads["thesis_rough"][1].road, fw)
    if not host["within"]:
        raise SystemExit(f"{cpu} ({name}): the firmware's loop differs from the host's: {host['error_over_peak']}")
    full, base = sizes(elf), sizes(emb.firmware_path(bdir, "dn_firmware_base"))
    r = {"terms": model.terms, "caps_terms": len(model.terms), "loop_vs_host_error_over_peak": host["error_over_peak"],
         "step_systick_mean": fw.instructions("step"),
         "loop": {"flash": full["flash"] - base["flash"], "ram_static": full["ram_static"] - base["ram_static"],
                  "stack_setup": max(fw.stack["mlp_init"], fw.stack["loop_setup"]), "stack_step": fw.stack["step"]}}
    if worst:
        r["step_per_road"] = worst_steps(cpu, roads, model, out, fp_contract, loop_float, elf, tag=f"-step-{name}",
                                         profile=cpu == "cortex-m4", **build)
        r["step_worst"] = max(v["max"] for v in r["step_per_road"].values())
        if cpu == "cortex-m4":  # the step's mean cycles per instruction over both roads' steps
            pr = r["step_per_road"].values()
            cpi = sum(v["cpi"] * v["mean"] for v in pr) / sum(v["mean"] for v in pr)
            budget = CLOCK_HZ / BUDGET_HZ
            r["cpi"] = cpi
            r["cycles"] = {"step": r["step_systick_mean"] * cpi, "step_worst": r["step_worst"] * cpi,
                           "step_worst_traced": max(v["cycles_max"] for v in pr)}
            r["step_budget_cycles"] = budget
            r["step_margin"] = budget / r["cycles"]["step"]
            r["step_margin_worst"] = budget / r["cycles"]["step_worst"]
            r["step_margin_worst_traced"] = budget / r["cycles"]["step_worst_traced"]
    return r


def symbol_size(elf: Path, pattern: str) -> int:
    """Bytes of the symbols of an image whose (mangled) name matches pattern (a regex)."""
    total = 0
    for line in _out(["arm-none-eabi-nm", "-S", elf]).splitlines():
        f = line.split()
        if len(f) == 4 and re.search(pattern, f[3]):
            total += int(f[1], 16)
    return total


def library_state() -> dict:
    """The commit measured, and the library's files (cpp/include, cpp/src) that differ from it."""
    def git(*args):
        return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True).stdout.strip()

    return {"commit": git("rev-parse", "--short", "HEAD"),
            "library_files_modified": git("diff", "--name-only", "HEAD", "--", "cpp/include", "cpp/src").split()}


def measure_inverse(cpu: str, inv_vectors: tuple[Path, object], model, out: Path, fp_contract: str = "off",
                    loop_float: int | None = None, without: Path | None = None) -> dict:
    """The damper inverse's cost on a core: the full firmware built on inv_vectors (header, Vectors
    with inverse cases), checked against the host's inverse, then its forward (dn_damper_force) and
    inverse instructions (module docstring). without: the same firmware built without inverse
    cases (its flash is subtracted)."""
    tag = "" if loop_float is None else f"-loopfloat{int(loop_float)}"
    header, vec = inv_vectors
    bdir = emb.build(cpu, out / f"{cpu}-{fp_contract}{tag}-inverse", vectors=header, fp_contract=fp_contract,
                     loop_float=loop_float, targets=("dn_firmware",),
                     caps={**emb.DEFAULT_CAPS, **emb.INVERSE_GRID_CAPS})  # (the host's first-iterate grid)
    elf = emb.firmware_path(bdir)
    fw = emb.parse_output(emb.run(elf, cpu))
    assert fw.errors == 0 and fw.inv_u is not None
    host = emb.inverse_vs_host(model, vec, fw)
    if not host["within"]:
        raise SystemExit(f"{cpu}: the firmware's inverse differs from the host's: {host}")
    fwd, inv = fw.instructions("damper_force"), fw.instructions("inverse")
    st, n_evals = fw.inv_status, fw.inv_evals
    # each call's instructions: its ticks (timer reads around it) less their mean excess over the
    # timed loop's mean (the loop minus its stub: the call alone)
    per = fw.inv_ticks * fw.instructions_per_tick
    per = per - (per.mean() - inv)
    kinds = {"all": np.ones(len(st), bool), "reachable": (st >= 0) & (st & 16 == 0),
             "unreachable": (st >= 0) & (st & 16 > 0), "error": st < 0}
    reach = kinds["reachable"]
    slope, intercept = np.polyfit(n_evals[reach], per[reach], 1)
    r = {"n": int(len(st)), "cases": {k: int(m.sum()) for k, m in kinds.items()},
         "damper_force_instructions": fwd, "inverse_instructions_mean": inv, "ratio_mean": inv / fwd,
         "inverse_instructions_median": {k: float(np.median(per[m])) for k, m in kinds.items() if m.any()},
         "ratio_median": {k: float(np.median(per[m])) / fwd for k, m in kinds.items() if m.any()},
         "evaluations_per_inverse": {"all_but_errors": float(np.mean(n_evals[st >= 0])),
                                     "reachable": float(np.mean(n_evals[reach])),
                                     "reachable_max": int(n_evals[reach].max())},
         "instructions_per_newton_evaluation": float(slope),
         "instructions_reachable_at_0_newton_evaluations": float(intercept),
         "per_call_timer_excess": float(fw.inv_ticks.mean() * fw.instructions_per_tick - inv),
         "stack": fw.stack["inverse"], "stack_setup": fw.stack["inverse_setup"],
         "damper_inverse_code_bytes": symbol_size(elf, r"Damper(7inverse|6search|6eval_u)E"),
         "vs_host": {k: host[k] for k in ("u_error_over_range", "force_error_over_range", "evals_host",
                                          "evals_firmware")},
         "target_ratio": 3.0}
    if "inverse_near" in fw.time:  # the warm call a controller makes: its next step (firmware.c)
        near = fw.instructions("inverse_near")
        r["inverse_near_instructions_mean"] = near
        r["inverse_near_ratio_mean"] = near / fwd
    r["meets_target"] = bool(r["ratio_median"]["all"] <= 3.0 and r["ratio_mean"] <= 3.0)
    if without is not None:
        r["flash_added"] = sizes(elf)["flash"] - sizes(without)["flash"]
    return r


def measure(cpu: str, vectors: Path, tiny: Path, model, out: Path, fp_contract: str = "off",
            loop_float: int | None = None, roads: dict | None = None, inv_vectors=None) -> dict:
    """loop_float None: the core's preset (dampnet.export.mcu.LOOP_FLOAT). roads: name -> (vectors
    header, Vectors) of the roads the worst step is looked for on (the first: `vectors`'s)."""
    tag = "" if loop_float is None else f"-loopfloat{int(loop_float)}"
    bdir = emb.build(cpu, out / f"{cpu}-{fp_contract}{tag}", vectors=vectors, fp_contract=fp_contract,
                     loop_float=loop_float,
                     targets=("dn_firmware", "dn_firmware_kernel", "dn_firmware_base"))
    path = lambda n: emb.firmware_path(bdir, n)  # noqa: E731
    base, kern, full = sizes(path("dn_firmware_base")), sizes(path("dn_firmware_kernel")), sizes(path("dn_firmware"))
    fw = emb.parse_output(emb.run(path("dn_firmware"), cpu))
    assert fw.errors == 0
    # a configuration measured must also compute the loop: its states against the host's double
    # loop on the same road (every option measured here: --fp-contract, --loop-float, each core)
    host = emb.loop_vs_host(model, emb.make_vectors(model).road, fw)
    if not host["within"]:
        raise SystemExit(f"{cpu} (fp-contract {fp_contract}, loop-float {loop_float}): the firmware's loop differs "
                         f"from the host's beyond {emb.HOST_TOLERANCE:g} of the peaks: {host['error_over_peak']}")
    r = {"sizes": fw.sizes, "stack": fw.stack,
         "loop_vs_host_error_over_peak": host["error_over_peak"],
         "instructions": {"forward": fw.instructions("forward"), "step": fw.instructions("step")},
         "kernel": {"flash": kern["flash"] - base["flash"], "ram_static": kern["ram_static"] - base["ram_static"],
                    "stack": max(fw.stack["mlp_init"], fw.stack["forward"])},
         "loop": {"flash": full["flash"] - base["flash"], "ram_static": full["ram_static"] - base["ram_static"],
                  "stack_setup": max(fw.stack["mlp_init"], fw.stack["loop_setup"]), "stack_step": fw.stack["step"]}}
    r["kernel"]["ram"] = r["kernel"]["ram_static"] + r["kernel"]["stack"]
    r["loop"]["ram"] = r["loop"]["ram_static"] + max(r["loop"]["stack_setup"], r["loop"]["stack_step"])
    r["loop"]["ram_run"] = r["loop"]["ram_static"] + r["loop"]["stack_step"]
    # emlearn: the same harness, its forward instead
    edir = bdir / "emlearn"
    glue = emlearn_sources(model, edir)
    ebase = build_manual(cpu, 0, bdir, vectors, fp_contract=fp_contract)
    eelf = build_manual(cpu, 3, bdir, vectors, extra_src=[glue], extra_inc=[edir], fp_contract=fp_contract)
    eo = emb.parse_output(emb.run(eelf, cpu))
    es, ebs = sizes(eelf), sizes(ebase)
    # emlearn's forward: how much of it is newlib's tanhf (and what that calls)
    emix = trace_mix(eelf, cpu, {"forward": "dn_fw_emlearn_forward", "tanhf": "tanhf"}, out / "trace.log")
    x = emb.make_vectors(model).x
    ok = np.all(np.isfinite(x), axis=1)
    r["emlearn"] = {"instructions": eo.instructions("forward"), "flash": es["flash"] - ebs["flash"],
                    "ram_static": es["ram_static"] - ebs["ram_static"], "stack": eo.stack["forward"],
                    "max_diff_vs_dampnet_in_range_N": float(np.max(np.abs(
                        eo.forces[ok & (fw.status == 0)] - fw.forces[ok & (fw.status == 0)]))),
                    "tanhf_share_of_instructions": emix["tanhf"][0] / emix["forward"][0]}
    if inv_vectors is not None:
        r["inverse"] = measure_inverse(cpu, inv_vectors, model, out, fp_contract, loop_float, path("dn_firmware"))
    if roads:
        r["step_per_road"] = worst_steps(cpu, roads, model, out, fp_contract, loop_float, path("dn_firmware"))
        r["instructions"]["step_worst"] = max(v["max"] for v in r["step_per_road"].values())
    if cpu == "cortex-m4":
        tdir = emb.build(cpu, out / f"{cpu}-{fp_contract}{tag}-trace", vectors=tiny, fp_contract=fp_contract,
                         loop_float=loop_float,
                         targets=("dn_firmware",))
        cpi = trace_cpi(emb.firmware_path(tdir), cpu, {"forward": "dn_mlp_forward_f", "step": "dn_loop_step"},
                        out / "trace.log", after={"forward": ("dn_loop_step", False), "step": ("dn_loop_step", True)})
        ecpi = {"forward": emix["forward"][1] / emix["forward"][0]}
        r["cpi"] = cpi
        r["cycles"] = {k: r["instructions"][k] * cpi[k] for k in cpi}
        r["emlearn"]["cycles"] = r["emlearn"]["instructions"] * ecpi["forward"]
        r["step_budget_cycles"] = CLOCK_HZ / BUDGET_HZ
        r["step_margin"] = r["step_budget_cycles"] / r["cycles"]["step"]
        if roads:  # the worst step at the step's mean cycles per instruction
            r["cycles"]["step_worst"] = r["instructions"]["step_worst"] * cpi["step"]
            r["step_margin_worst"] = r["step_budget_cycles"] / r["cycles"]["step_worst"]
    return r


UNROLL_SWEEP = [(1, 1), (1, 2), (1, 4), (1, 8), (0, 8)]  # (DN_KERNEL_SMALL, DN_KERNEL_UNROLL)


def unroll_sweep(cpu: str, vectors: Path, out: Path, fp_contract: str = "off") -> list[dict]:
    """Kernel flash and forward instructions for each (small, unroll) of UNROLL_SWEEP."""
    rows = []
    for small, unroll in UNROLL_SWEEP:
        bdir = emb.build(cpu, out / f"{cpu}-{fp_contract}-small{small}-unroll{unroll}", vectors=vectors,
                         fp_contract=fp_contract, kernel={"SMALL": small, "UNROLL": unroll},
                         targets=("dn_firmware_kernel", "dn_firmware_base"))
        kern = sizes(emb.firmware_path(bdir, "dn_firmware_kernel"))
        base = sizes(emb.firmware_path(bdir, "dn_firmware_base"))
        fw = emb.parse_output(emb.run(emb.firmware_path(bdir, "dn_firmware_kernel"), cpu))
        assert fw.errors == 0
        rows.append({"small": small, "unroll": unroll, "flash": kern["flash"] - base["flash"],
                     "instructions": fw.instructions("forward")})
    return rows



def _report(res: dict, a) -> int:
    """A measurement's result with its build's floating-point contraction and the library's state,
    printed and written to --json: the exit status 0."""
    res["fp_contract"] = a.fp_contract
    res["source"] = library_state()
    print(json.dumps(res, indent=1))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1) + "\n")
    return 0

def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--json", help="write the results here")
    p.add_argument("--fp-contract", choices=("off", "fast"), default="off",
                   help="-ffp-contract of the builds (the presets: off; fast lets GCC fuse multiply-adds)")
    p.add_argument("--out-dir", default=str(OUT_DEFAULT),
                   help="the builds' directory (default build/bench-embedded)")
    p.add_argument("--loop-float", type=int, choices=(0, 1), default=None,
                   help="DN_LOOP_FLOAT on both cores (default: the presets', float on the M4F, double on the M7)")
    p.add_argument("--unroll-sweep", action="store_true",
                   help="only the kernel's flash and instructions for DN_KERNEL_UNROLL 1/2/4/8 (and DN_KERNEL_SMALL 0)")
    p.add_argument("--no-worst-step", action="store_true",
                   help="skip the per-step instruction traces (the worst step on two roads: a few minutes)")
    p.add_argument("--inverse-only", action="store_true",
                   help="only the damper inverse's instructions against the forward's (and its check against the host)")
    p.add_argument("--step-model", metavar="MODEL",
                   help="only the quarter-car step (mean, worst of two roads, M4F cycles and where they go, flash) of "
                        "MODEL (a model.json or its directory) with its physics terms (e.g. a valve term) beside its "
                        "network alone (the terms left out), in one run")
    a = p.parse_args(argv)
    why = emb.toolchain_missing()
    if why:
        print(f"bench/embedded.py: {why}", file=sys.stderr)
        return 2
    if emb.mcu.ROOT != ROOT:  # an editable install of another checkout shadows this one's python/
        print(f"bench/embedded.py: dampnet is imported from {emb.mcu.ROOT}, not {ROOT}: its sources would be built",
              file=sys.stderr)
        return 2
    out = Path(a.out_dir).resolve()
    model = load_model(ROOT / "export" / "dn_model_default.json")
    out.mkdir(parents=True, exist_ok=True)
    vectors, tiny = out / "vectors.h", out / "vectors_tiny.h"
    # no inverse cases: the sizes are the kernel's and the loop's; the inverse's build has its own
    emb.write_vectors(vectors, emb.make_vectors(model, n_inv=0), model=model)
    inv_header = out / "vectors_inverse.h"
    inv_vectors = (inv_header, emb.write_vectors(inv_header, emb.make_vectors(model), model=model))
    if a.inverse_only:
        res = {}
        tag = "" if a.loop_float is None else f"-loopfloat{int(a.loop_float)}"
        for cpu in sorted(emb.CPUS):  # the full build without the cases (measure's), for the flash added
            bdir = emb.build(cpu, out / f"{cpu}-{a.fp_contract}{tag}", vectors=vectors, fp_contract=a.fp_contract,
                             loop_float=a.loop_float, targets=("dn_firmware",))
            res[cpu] = measure_inverse(cpu, inv_vectors, model, out, a.fp_contract, a.loop_float,
                                       emb.firmware_path(bdir))
        return _report(res, a)
    if a.step_model:
        import dataclasses

        hybrid = load_model(a.step_model)
        if not hybrid.terms:
            print(f"bench/embedded.py: --step-model {a.step_model}: the model has no physics terms", file=sys.stderr)
            return 2
        alone = dataclasses.replace(hybrid, terms=[])
        res = {cpu: {"without_terms": measure_step_model(cpu, alone, "network", out, a.fp_contract, a.loop_float,
                                                         not a.no_worst_step),
                     "with_terms": measure_step_model(cpu, hybrid, "hybrid", out, a.fp_contract, a.loop_float,
                                                      not a.no_worst_step)}
               for cpu in sorted(emb.CPUS)}
        res["model"] = str(a.step_model)
        return _report(res, a)
    if a.unroll_sweep:
        res = {cpu: unroll_sweep(cpu, vectors, out, a.fp_contract) for cpu in sorted(emb.CPUS)}
        res["fp_contract"] = a.fp_contract
        for cpu in sorted(emb.CPUS):
            for r in res[cpu]:
                print(f"{cpu} {a.fp_contract} small {r['small']} unroll {r['unroll']}: kernel flash {r['flash']} B, "
                      f"forward {r['instructions']:.1f} instructions")
        if a.json:
            Path(a.json).write_text(json.dumps(res, indent=1) + "\n")
        return 0
    emb.write_vectors(tiny, emb.make_vectors(model, n_x=50, seconds=0.2, n_inv=0))
    roads = {}
    if not a.no_worst_step:  # the worst step on the stored road and on a rougher one
        from dampnet.sim.roads import iso8608

        iso_d = out / "vectors_iso8608_D.h"
        roads = {"thesis_rough": (vectors, emb.make_vectors(model, n_inv=0)),
                 "iso8608_D": (iso_d, emb.write_vectors(iso_d, emb.make_vectors(model, road=iso8608("D", 200.0, seed=1),
                                                                                n_inv=0)))}
    res = {cpu: measure(cpu, vectors, tiny, model, out, a.fp_contract, a.loop_float, roads, inv_vectors)
           for cpu in sorted(emb.CPUS)}
    res["fp_contract"] = a.fp_contract
    res["loop_float"] = {cpu: emb.LOOP_FLOAT[cpu] if a.loop_float is None else a.loop_float for cpu in sorted(emb.CPUS)}
    res["source"] = library_state()
    print(json.dumps(res, indent=1))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
