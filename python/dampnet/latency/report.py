"""`dampnet bench` as a library call: every measurement of one run, and its report in lines.

    measure(n_calls, n_py, n_sim, budget_ns=None, margin=HIL_FORCE_MARGIN, quick=False, cpp_only=False)
        -> res   the C++ harness (per-call latency against the HIL budget), the HIL configuration
                 and every timed configuration on hard inputs, the Python-level rows (unless
                 cpp_only), the hot path's code footprint; RuntimeError / FileNotFoundError
                 when the harness cannot run
    report(res) -> [lines]          what the command prints
    no_go(res) -> [reasons]         why the run misses its budget or fails a check (empty: GO)
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from dampnet.latency import footprint
from dampnet.latency import python_bench as bench_python
from dampnet.latency.harness import (
    HIL_FORCE_MARGIN,
    fullcar_hard_input_check,
    hil_hard_input_check,
    quick_latency,
    timed_configs_hard_input_check,
)


def measure(n_calls: int, n_py: int, n_sim: int, budget_ns: float | None = None, margin: float = HIL_FORCE_MARGIN,
            quick: bool = False, cpp_only: bool = False) -> dict[str, Any]:
    """Every measurement of `dampnet bench` (see the module docstring)."""
    hard = hil_hard_input_check(margin=margin)
    timed = timed_configs_hard_input_check(margin=margin)
    timed.update(fullcar_hard_input_check(margin=margin))
    with tempfile.TemporaryDirectory() as tmp:
        res = quick_latency(Path(tmp), n_calls=n_calls, budget_ns=budget_ns)
    res["hard_inputs"] = hard
    res["hard_inputs_timed_configs"] = timed
    res["calls"] = {"cpp": n_calls, "python": n_py, "sim_steps": n_sim, "budget_given": budget_ns is not None}
    if not cpp_only:
        res["python"] = bench_python.python_benchmarks(n_py, n_sim, repeats=3 if quick else 5)
        kernel = res["results"].get(bench_python.KERNEL_CASE, {}).get("p50_ns")
        bench_python.ratios(res["python"], kernel)
        res["python"]["kernel_case"] = bench_python.KERNEL_CASE
        res["python"]["header_model_id"] = bench_python.header_model_id()
    try:  # the code one step can touch (issue 30: <= 16 KB for the full car); needs binutils
        res["footprint"] = footprint.summary(footprint.measure())
    except (RuntimeError, OSError) as e:
        res["footprint"] = {"unavailable": str(e)}
    res["table"] = bench_python.table(res)
    return res


def report(res: dict[str, Any]) -> list[str]:
    """The lines `dampnet bench` prints (see measure)."""
    lines: list[str] = []
    out = lines.append
    n, n_py = res["calls"]["cpp"], res["calls"]["python"]
    hard, timed = res["hard_inputs"], res["hard_inputs_timed_configs"]
    m = res["machine"]
    out(f"machine: {m.get('cpu')} ({m.get('simd')}), gcc {m.get('compiler')}, flags '{m.get('flags')}', "
          f"load {m.get('loadavg')}")
    rt = res.get("runtime", {})
    out(f"kernel SIMD path: harness {m.get('isa', '?')}, installed runtime {rt.get('kernel_isa', '?')} "
          f"(runtime SIMD flags '{rt.get('isa_flags', '')}'; CMake options DAMPNET_AVX2=AUTO|ON|OFF, DAMPNET_AVX512=OFF|AUTO|ON)")
    py = res.get("python")
    if py:
        out(f"Python: load {py['loadavg']['start']} at start, {py['loadavg']['end']} at end; "
              + ", ".join(f"{k} {v}" for k, v in py["versions"].items() if v) + "; 1 thread each")
        same = py["header_model_id"] == py["model_id"]
        out(f"model {py['model_id']} (C++ harness header: {py['header_model_id']}"
              f"{'' if same else ' -- DIFFERENT MODEL, ratios are not like for like'}); "
              f"C++ rows: {n} calls each (steady_clock); Python rows: {n_py} calls each (perf_counter_ns), "
              "the same 1024 inputs cycled")
        out("references checked against MlpModel.predict before timing (max error / output range): "
              + ", ".join(f"{k} {c['max_err_of_range']:.1e}" for k, c in py["checks"].items()))
        for k, why in py.get("skipped", {}).items():
            out(f"skipped {k}: {why}")
    out(bench_python.format_table(res["table"]))
    out("All latencies include the clock reads around each call (C++: clock_overhead row; Python: "
          "python_clock_overhead row, an empty call); 'net p50' = p50 minus the C++ clock's median. "
          "'*_chained' rows: loops of single-sample calls, each input chosen by the previous output "
          "(latency, not throughput), 100 calls per clock pair, percentiles over the batches' per-call means. "
          "'x kernel p50' = median / the C++ kernel's "
          f"median ({bench_python.KERNEL_CASE}); Python-level calls include the interpreter's call overhead.")
    av = res.get("averaged", {})
    if av.get("widths") or av.get("refused"):
        out("averaged networks (dampnet train --average; C ABI float forward, the default network repeated: "
              f"the same force): single {av['single_p50_ns']:.0f} ns p50; "
              + ", ".join(f"{r['neurons']} neurons p50 {r['p50_ns']:.0f} ns (x{r['x_single_p50']:.1f}), "
                          f"p99.9 {r['p999_ns']:.0f} ns, force off by {r['max_diff_n']:.2g} N" for r in av["widths"])
              + "".join(f"; {n} neurons refused by this build ({why}: DN_MAX_HIDDEN)" for n, why in av["refused"].items()))
    b, h = res["budget"], res["headroom"]
    source = ("set by --budget-ns" if res["calls"]["budget_given"]
              else f"{100 * b['share']:.0f} % of a {1e6 / b['step_rate_hz']:.0f} us step")
    out(f"HIL budget: {b['case']} p99.9 <= {b['p999_budget_ns']:.0f} ns ({source}): measured {h['p999_ns']:.0f} ns, headroom x{h['headroom_factor']:.2f}"
          f" -> {'GO' if h['within_budget'] else 'NO-GO'}")
    for name, t in res["targets"].items():
        out(f"target {name} {t['metric']} <= {t['target_ns']:.0f} ns: measured {t['measured_ns'] if t['measured_ns'] is not None else float('nan'):.1f} ns")
    fc = res.get("fullcar", {})
    if fc.get("p50_ns") is not None:
        out(f"full vehicle: {fc['case']} p50 {fc['p50_ns']:.0f} ns (target <= {fc['p50_target_ns']:.0f}), "
              f"p99.9 {fc['p999_ns']:.0f} ns (target <= {fc['p999_target_ns']:.0f}) -> "
              f"{'met' if fc['within_target'] else 'MISSED'}")
    if fc.get("cold_reps"):
        out(f"full vehicle cold-cache step (median / p99 of {fc['cold_reps']} single steps, each after an "
              f"eviction): code sweep {fc['cold_code_p50_ns']:.0f} / {fc['cold_code_p99_ns']:.0f} ns, "
              f"4 MB data + code {fc['cold_4mb_p50_ns']:.0f} / {fc['cold_4mb_p99_ns']:.0f} ns, "
              f"64 MB data + code {fc['cold_64mb_p50_ns']:.0f} / {fc['cold_64mb_p99_ns']:.0f} ns "
              f"(warm p50 {fc['p50_ns']:.0f} ns; code sweep: {fc['code_sweep_bytes'] / 1024:.0f} KB of distinct code)")
    fp = res["footprint"]
    if "unavailable" in fp:
        out(f"hot-path code footprint: unavailable ({fp['unavailable']})")
    else:
        out(f"hot-path code footprint (bytes of the functions the step's static call graph reaches, "
              f"python -m dampnet.latency.footprint): full-car step {fp['dn_fullcar_step_bytes']} B "
              f"(target <= {footprint.FULLCAR_STEP_CEILING_BYTES} B), quarter-car step {fp['dn_loop_step_bytes']} B")
    lo, hi = hard["bounds_n"]
    out(f"hard inputs through the HIL configuration ({', '.join(f'{k} {v}' for k, v in hard['vehicle'].items())}, "
          f"{hard['controller']['kind']}): forces must stay within the model's range "
          f"[{hard['force_range_n'][0]:.0f}, {hard['force_range_n'][1]:.0f}] N +- {100 * hard['margin']:.0f} % "
          f"of its width = [{lo:.0f}, {hi:.0f}] N, no step error")
    for name, r in hard["inputs"].items():
        detail = (f"force {r['f_min']:.0f}..{r['f_max']:.0f} N, linearised step fell back in "
                  f"{r['fallback_steps']} of {r['steps']} steps" if "f_min" in r else "")
        out(f"  {name}: {'ok' if r['ok'] else 'FAILED: ' + r['why']}{'; ' + detail if detail and r['ok'] else ''}")
    out("the same hard inputs through every configuration the harness times (accel_feature_damper_eval): "
          + ", ".join(f"{cfg} {'ok' if r['passed'] else 'FAILED'}" for cfg, r in timed.items()))
    return lines


def no_go(res: dict[str, Any]) -> list[str]:
    """Why the run is NO-GO: the HIL budget missed, a hard input failed; empty when GO."""
    h, b, hard = res["headroom"], res["budget"], res["hard_inputs"]
    timed_failures = [f"{cfg}: {f}" for cfg, r in res["hard_inputs_timed_configs"].items() for f in r["failures"]]
    why = []
    if not h["within_budget"]:
        why.append(f"the HIL step's p99.9 {h['p999_ns']:.0f} ns exceeds the budget {b['p999_budget_ns']:.0f} ns")
    if not hard["passed"]:
        why.append("the hard-input check failed: " + "; ".join(hard["failures"]))
    if timed_failures:
        why.append("a timed configuration failed the hard-input check: " + "; ".join(timed_failures))
    return why
