"""The hot-path footprint tool (dampnet.latency.footprint, bench/footprint.py) on the built
library: the walk from dn_fullcar_step and dn_loop_step is sound (it reaches what the steps
are known to call) and its arithmetic is the symbol sizes'; the dynamic measure (--dynamic,
valgrind callgrind) counts what a configuration's steps actually call, and issue 30's ceiling
holds: the code one full-car step calls is <= 16 KB (footprint.FULLCAR_STEP_CEILING_BYTES) in
every configuration of the full car (bench/RESULTS.md "Under 16 KB": 16,127 B at most with
gcc 12 -O3, x86-64 AVX2). The arithmetic must stay
-ffp-contract=off's: no multiply-add is fused outside the MLP kernels (whose FMAs are their own
intrinsics)"""

from __future__ import annotations

import json
import platform
import re
import subprocess
import sys

import pytest

from cbuild import ROOT
from dampnet.latency import footprint
from needs import need_tool


@pytest.fixture(scope="module")
def measured():
    return footprint.measure()


def _names(r):
    return [row["function"] for row in r["functions"]]


def test_the_walk_reaches_what_the_steps_call(measured):
    fc, loop = measured["entries"]["dn_fullcar_step"], measured["entries"]["dn_loop_step"]
    for r, step in ((fc, "dampnet::step(dampnet::FullCarModel const&"), (loop, "dampnet::step(dampnet::LoopModel const&")):
        names = _names(r)
        assert r["functions"][-1]["bytes"] > 0 and r["entry_bytes"] > 0
        assert r["total_bytes"] >= r["entry_bytes"] and r["total_bytes"] == sum(x["bytes"] for x in r["functions"])
        assert r["hot_bytes"] + r["cold_bytes"] == r["total_bytes"]
        assert any(n.startswith(step) for n in names), names  # the C ABI entry tail-calls the step
        assert any("Damper::force" in n for n in names), names  # the damper
        assert any("forward" in n and "MlpParams" in n for n in names), names  # the MLP kernel
        # reached only through the additive terms' table of function pointers
        assert any("terms::force_DN_TERM_BUMP_STOP" in n for n in names), names
        assert "tanh" in r["external_calls"] or "exp" in r["external_calls"]
        assert len(set(n["address"] for n in r["functions"])) == r["n_functions"]
    # the full car's step evaluates the corners' dampers four at a time: its own code on top
    assert any("forward_batch" in n for n in _names(fc)) and not any("forward_batch" in n for n in _names(loop))
    assert fc["total_bytes"] > loop["total_bytes"]


def test_sizes_are_the_symbol_tables(measured):
    """Each row's bytes are nm's size of that symbol at that address in the library read (a
    local function can have copies of one name, one per translation unit)."""
    lib = measured["library"]
    nm = subprocess.run(["nm", "-S", "--defined-only", lib], capture_output=True, text=True, check=True).stdout
    sizes = {(p[3], int(p[0], 16)): int(p[1], 16) for p in (line.split() for line in nm.splitlines()) if len(p) == 4}
    for row in measured["entries"]["dn_fullcar_step"]["functions"]:
        assert sizes[row["symbol"], int(row["address"], 16)] == row["bytes"], row


def test_script_prints_the_table_and_writes_json(tmp_path):
    out = tmp_path / "fp.json"
    proc = subprocess.run([sys.executable, str(ROOT / "bench" / "footprint.py"), "--entry", "dn_loop_step",
                           "--json", str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(out.read_text())
    assert list(res["entries"]) == ["dn_loop_step"]
    total = res["entries"]["dn_loop_step"]["total_bytes"]
    assert f"dn_loop_step: {total} bytes in " in proc.stdout and f"  {total:>7}  total" in proc.stdout
    bad = subprocess.run([sys.executable, str(ROOT / "bench" / "footprint.py"), "--entry", "no_such_fn"],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "no_such_fn is not a function of the library" in bad.stderr


HIL = "fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel"
FOUR = "fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel_four_calls"


@pytest.fixture(scope="module")
def dynamic(measured):
    need_tool("valgrind")
    need_tool("cc")
    return footprint.measure_dynamic(configs=footprint.FULLCAR_CONFIGS, n_steps=3)


def test_dynamic_counts_what_the_steps_call(measured, dynamic):
    """--dynamic: the functions the HIL configuration's steps executed, each with its whole
    symbol size; a subset of the static walk's (an upper bound), the step and the batched
    kernel in it, the other damper kinds' code not."""
    assert dynamic["library"] == measured["library"]
    static = {row["address"]: row for row in measured["entries"]["dn_fullcar_step"]["functions"]}
    for c in (HIL, FOUR):
        r = dynamic["configs"][c]
        names = [row["function"] for row in r["functions"]]
        assert r["total_bytes"] == sum(row["bytes"] for row in r["functions"]) > 0
        assert all(row["executed_instructions"] > 0 for row in r["functions"])
        assert any(n.startswith("dampnet::step(dampnet::FullCarModel const&") for n in names), names
        assert "dn_fullcar_step" in names
        for row in r["functions"]:  # every function run is one the static walk reaches
            assert row["address"] in static, row
            assert static[row["address"]]["bytes"] == row["bytes"]
        assert r["total_bytes"] < measured["entries"]["dn_fullcar_step"]["total_bytes"]
        assert not any("Damper::force(" in n or "Damper::parametric(" in n or "Damper::table(" in n for n in names), names
    hil = [row["function"] for row in dynamic["configs"][HIL]["functions"]]
    four = [row["function"] for row in dynamic["configs"][FOUR]["functions"]]
    assert any("forward_batch<float, 3" in n for n in hil) and not any("forward_batch" in n for n in four)
    assert any("Damper::force_da(" in n for n in four) and not any("Damper::force_da(" in n for n in hil)
    fc = max(r["total_bytes"] for r in dynamic["configs"].values())
    assert dynamic["fullcar_step_max_bytes"] == fc
    assert dynamic["within_ceiling"] == (fc <= footprint.FULLCAR_STEP_CEILING_BYTES)


def test_the_full_car_step_fits_the_ceiling(dynamic):
    """Issue 30: the functions one full-car step calls (whole symbol sizes) fit 16 KB, half the
    L1i, in each of the full car's configurations (per step / per stage, a shared float damper,
    four damper objects, a double damper). Measured on the x86-64 build the tests use (gcc,
    -O3, the AVX2 kernel): another compiler or backend has other sizes."""
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("the ceiling is measured on the x86-64 build")
    assert set(dynamic["configs"]) == set(footprint.FULLCAR_CONFIGS)
    sizes = {c: r["total_bytes"] for c, r in dynamic["configs"].items()}
    assert max(sizes.values()) <= footprint.FULLCAR_STEP_CEILING_BYTES, sizes
    assert dynamic["within_ceiling"]


QUARTER_HIL = "loop_step_rk4_per_step_eval_neural_float_skyhook_linear_accel"


def test_the_quarter_car_hil_step_has_its_start_inlined():
    """The quarter-car HIL step (the budget case: per-step evaluation, linearised acceleration,
    on-off skyhook, float MLP) runs its step start inside dampnet::step: gcc stopped inlining
    detail::start once it held the force laws' branch (1,017 instructions a step against 969, the
    step 14 % slower: bench/RESULTS.md), hence its always_inline on the host and the force laws'
    own out-of-line force_law_start, which an on-off law never calls. The functions the steps
    execute are the step, the damper's evaluation and the kernel, and nothing else of the loop.
    About 1 s (callgrind over 3 steps)."""
    need_tool("valgrind")
    r = footprint.measure_dynamic(configs=(QUARTER_HIL,), n_steps=3)["configs"][QUARTER_HIL]
    names = [row["function"] for row in r["functions"]]
    assert any(n.startswith("dampnet::step(dampnet::LoopModel const&") for n in names), names
    assert not any("detail::start(" in n or "force_law_start(" in n for n in names), names
    assert any("Damper::force_da(" in n for n in names) and any("forward<float" in n for n in names), names


def test_dynamic_script_prints_the_table(tmp_path):
    need_tool("valgrind")
    out = tmp_path / "dyn.json"
    proc = subprocess.run([sys.executable, str(ROOT / "bench" / "footprint.py"), "--dynamic", "--config", HIL,
                           "--steps", "2", "--json", str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(out.read_text())
    total = res["configs"][HIL]["total_bytes"]
    assert f"{HIL} (2 steps): {total} bytes in " in proc.stdout
    assert f"full-car step, the largest over its configurations: {total} bytes" in proc.stdout


_FMA = re.compile(r"\bv?f(?:n?m(?:add|sub)|maddsub|msubadd)\w*\s")


def test_no_fused_multiply_add_outside_the_mlp_kernels(measured):
    """-ffp-contract=off holds in every function of the library but the MLP kernels' (forward,
    forward_simd, forward_batch: their FMAs are intrinsics, the arithmetic they are tested for):
    no function attribute or pragma may let GCC fuse a multiply-add (GCC 12 did, in an -O2
    copy of the full car's derivative made by optimize("O2"): a vfmaddsub)."""
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("x86 disassembly")
    need_tool("objdump")
    dis = subprocess.run(["objdump", "-d", "-C", "--no-show-raw-insn", measured["library"]],
                         capture_output=True, text=True, check=True).stdout
    fused, fn = {}, None
    for line in dis.splitlines():
        m = re.match(r"^[0-9a-f]+ <(.*)>:$", line)
        if m:
            fn = m.group(1)
        elif fn and _FMA.search(line.split("\t")[-1] + " "):
            fused[fn] = fused.get(fn, 0) + 1
    assert fused, "no FMA at all: the kernels' intrinsics should show (is this the AVX2 build?)"
    outside = {f: n for f, n in fused.items() if not re.search(r"::forward(_simd|_batch)?<", f)}
    assert not outside, outside
