"""`dampnet bench`: per-call latency of the MLP forward and the quarter-car step against the
HIL budget (the C++ harness; exit 1 when the budget is missed), the HIL configuration on a
recorded set of hard inputs (exit 1 when a force leaves the model's range by more than a margin
or a step fails), and beside them, in the same
run, Python-level figures: dampnet's pybind11 forward, numpy, torch eager, TorchScript and
onnxruntime on the same model and inputs (as ratios to the C++ kernel's median), the pybind11
`Loop.step` latency and `Loop.simulate` throughput against their targets."""

from __future__ import annotations

import tempfile
from pathlib import Path

from dampnet.commands.common import error
from dampnet.outputs import check_output_file, write_json


def add_parser(subparsers):
    p = subparsers.add_parser("bench", help="latency check against the HIL budget (exit 1 if missed)")
    p.add_argument("--quick", action="store_true",
                   help="2e5 timed C++ calls per case instead of 1e6, 2e4 Python calls instead of 1e5, "
                        "2e5-step roads instead of 1e6 (under a minute)")
    p.add_argument("--calls", type=int, default=None, help="timed C++ calls per case (overrides --quick)")
    p.add_argument("--py-calls", type=int, default=None,
                   help="timed Python-level calls per case (default: a tenth of the C++ calls)")
    p.add_argument("--sim-steps", type=int, default=None,
                   help="road length of the simulate throughput runs (default: the C++ calls)")
    p.add_argument("--cpp-only", action="store_true", help="only the C++ harness (no Python-level rows)")
    p.add_argument("--budget-ns", type=float, default=None,
                   help="p99.9 budget of the HIL step [ns] (default: 1 %% of a 10 kHz step, 1000 ns)")
    p.add_argument("--hil-margin", type=float, default=None,
                   help="hard-input check: how far [fraction of the model's force range] a force may "
                        "leave that range (default 0.25)")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.latency import footprint
    from dampnet.latency import python_bench as bench_python
    from dampnet.latency.harness import (
        HIL_FORCE_MARGIN,
        fullcar_hard_input_check,
        hil_hard_input_check,
        quick_latency,
        timed_configs_hard_input_check,
    )

    n = args.calls or (200_000 if args.quick else 1_000_000)
    n_py = args.py_calls or max(1000, n // 10)  # Python calls are ~10-400x slower than C++ ones
    n_sim = args.sim_steps or n
    if args.budget_ns is not None and not args.budget_ns > 0:
        return error(f"--budget-ns: expected a positive number of ns, got {args.budget_ns}")
    if args.json:  # before the minutes of timing, not after
        try:
            check_output_file(args.json)
        except OSError as e:
            return error(str(e))
    margin = HIL_FORCE_MARGIN if args.hil_margin is None else args.hil_margin
    if not -1.0 < margin < 100.0:
        return error(f"--hil-margin: expected a fraction in (-1, 100), got {margin}")
    try:
        hard = hil_hard_input_check(margin=margin)
        timed = timed_configs_hard_input_check(margin=margin)
        timed.update(fullcar_hard_input_check(margin=margin))
        with tempfile.TemporaryDirectory() as tmp:
            res = quick_latency(Path(tmp), n_calls=n, budget_ns=args.budget_ns)
        res["hard_inputs"] = hard
        res["hard_inputs_timed_configs"] = timed
        if not args.cpp_only:
            res["python"] = bench_python.python_benchmarks(n_py, n_sim, repeats=3 if args.quick else 5)
            kernel = res["results"].get(bench_python.KERNEL_CASE, {}).get("p50_ns")
            bench_python.ratios(res["python"], kernel)
            res["python"]["kernel_case"] = bench_python.KERNEL_CASE
            res["python"]["header_model_id"] = bench_python.header_model_id()
    except (RuntimeError, FileNotFoundError) as e:
        return error(str(e))
    try:  # the code one step can touch (issue 30: <= 16 KB for the full car); needs binutils
        res["footprint"] = footprint.summary(footprint.measure())
    except (RuntimeError, OSError) as e:
        res["footprint"] = {"unavailable": str(e)}
    res["table"] = bench_python.table(res)
    m = res["machine"]
    print(f"machine: {m.get('cpu')} ({m.get('simd')}), gcc {m.get('compiler')}, flags '{m.get('flags')}', "
          f"load {m.get('loadavg')}")
    rt = res.get("runtime", {})
    print(f"kernel SIMD path: harness {m.get('isa', '?')}, installed runtime {rt.get('kernel_isa', '?')} "
          f"(runtime SIMD flags '{rt.get('isa_flags', '')}'; CMake options DAMPNET_AVX2=AUTO|ON|OFF, DAMPNET_AVX512=OFF|AUTO|ON)")
    py = res.get("python")
    if py:
        print(f"Python: load {py['loadavg']['start']} at start, {py['loadavg']['end']} at end; "
              + ", ".join(f"{k} {v}" for k, v in py["versions"].items() if v) + "; 1 thread each")
        same = py["header_model_id"] == py["model_id"]
        print(f"model {py['model_id']} (C++ harness header: {py['header_model_id']}"
              f"{'' if same else ' -- DIFFERENT MODEL, ratios are not like for like'}); "
              f"C++ rows: {n} calls each (steady_clock); Python rows: {n_py} calls each (perf_counter_ns), "
              "the same 1024 inputs cycled")
        print("references checked against MlpModel.predict before timing (max error / output range): "
              + ", ".join(f"{k} {c['max_err_of_range']:.1e}" for k, c in py["checks"].items()))
        for k, why in py.get("skipped", {}).items():
            print(f"skipped {k}: {why}")
    print(bench_python.format_table(res["table"]))
    print("All latencies include the clock reads around each call (C++: clock_overhead row; Python: "
          "python_clock_overhead row, an empty call); 'net p50' = p50 minus the C++ clock's median. "
          "'*_chained' rows: loops of single-sample calls, each input chosen by the previous output "
          "(latency, not throughput), 100 calls per clock pair, percentiles over the batches' per-call means. "
          "'x kernel p50' = median / the C++ kernel's "
          f"median ({bench_python.KERNEL_CASE}); Python-level calls include the interpreter's call overhead.")
    av = res.get("averaged", {})
    if av.get("widths") or av.get("refused"):
        print("averaged networks (dampnet train --average; C ABI float forward, the default network repeated: "
              f"the same force): single {av['single_p50_ns']:.0f} ns p50; "
              + ", ".join(f"{r['neurons']} neurons p50 {r['p50_ns']:.0f} ns (x{r['x_single_p50']:.1f}), "
                          f"p99.9 {r['p999_ns']:.0f} ns, force off by {r['max_diff_n']:.2g} N" for r in av["widths"])
              + "".join(f"; {n} neurons refused by this build ({why}: DN_MAX_HIDDEN)" for n, why in av["refused"].items()))
    b, h = res["budget"], res["headroom"]
    source = ("set by --budget-ns" if args.budget_ns is not None
              else f"{100 * b['share']:.0f} % of a {1e6 / b['step_rate_hz']:.0f} us step")
    print(f"HIL budget: {b['case']} p99.9 <= {b['p999_budget_ns']:.0f} ns ({source}): measured {h['p999_ns']:.0f} ns, headroom x{h['headroom_factor']:.2f}"
          f" -> {'GO' if h['within_budget'] else 'NO-GO'}")
    for name, t in res["targets"].items():
        print(f"target {name} {t['metric']} <= {t['target_ns']:.0f} ns: measured {t['measured_ns'] if t['measured_ns'] is not None else float('nan'):.1f} ns")
    fc = res.get("fullcar", {})
    if fc.get("p50_ns") is not None:
        print(f"full vehicle: {fc['case']} p50 {fc['p50_ns']:.0f} ns (target <= {fc['p50_target_ns']:.0f}), "
              f"p99.9 {fc['p999_ns']:.0f} ns (target <= {fc['p999_target_ns']:.0f}) -> "
              f"{'met' if fc['within_target'] else 'MISSED'}")
    if fc.get("cold_reps"):
        print(f"full vehicle cold-cache step (median / p99 of {fc['cold_reps']} single steps, each after an "
              f"eviction): code sweep {fc['cold_code_p50_ns']:.0f} / {fc['cold_code_p99_ns']:.0f} ns, "
              f"4 MB data + code {fc['cold_4mb_p50_ns']:.0f} / {fc['cold_4mb_p99_ns']:.0f} ns, "
              f"64 MB data + code {fc['cold_64mb_p50_ns']:.0f} / {fc['cold_64mb_p99_ns']:.0f} ns "
              f"(warm p50 {fc['p50_ns']:.0f} ns; code sweep: {fc['code_sweep_bytes'] / 1024:.0f} KB of distinct code)")
    fp = res["footprint"]
    if "unavailable" in fp:
        print(f"hot-path code footprint: unavailable ({fp['unavailable']})")
    else:
        print(f"hot-path code footprint (bytes of the functions the step's static call graph reaches, "
              f"python -m dampnet.latency.footprint): full-car step {fp['dn_fullcar_step_bytes']} B "
              f"(target <= {footprint.FULLCAR_STEP_CEILING_BYTES} B), quarter-car step {fp['dn_loop_step_bytes']} B")
    lo, hi = hard["bounds_n"]
    print(f"hard inputs through the HIL configuration ({', '.join(f'{k} {v}' for k, v in hard['vehicle'].items())}, "
          f"{hard['controller']['kind']}): forces must stay within the model's range "
          f"[{hard['force_range_n'][0]:.0f}, {hard['force_range_n'][1]:.0f}] N +- {100 * hard['margin']:.0f} % "
          f"of its width = [{lo:.0f}, {hi:.0f}] N, no step error")
    for name, r in hard["inputs"].items():
        detail = (f"force {r['f_min']:.0f}..{r['f_max']:.0f} N, linearised step fell back in "
                  f"{r['fallback_steps']} of {r['steps']} steps" if "f_min" in r else "")
        print(f"  {name}: {'ok' if r['ok'] else 'FAILED: ' + r['why']}{'; ' + detail if detail and r['ok'] else ''}")
    timed_failures = [f"{cfg}: {f}" for cfg, r in timed.items() for f in r["failures"]]
    print("the same hard inputs through every configuration the harness times (accel_feature_damper_eval): "
          + ", ".join(f"{cfg} {'ok' if r['passed'] else 'FAILED'}" for cfg, r in timed.items()))
    if args.json:
        write_json(args.json, res, overwrite=True)  # atomically
    go = h["within_budget"] and hard["passed"] and not timed_failures
    if not h["within_budget"]:
        print(f"NO-GO: the HIL step's p99.9 {h['p999_ns']:.0f} ns exceeds the budget {b['p999_budget_ns']:.0f} ns")
    if not hard["passed"]:
        print("NO-GO: the hard-input check failed: " + "; ".join(hard["failures"]))
    if timed_failures:
        print("NO-GO: a timed configuration failed the hard-input check: " + "; ".join(timed_failures))
    return 0 if go else 1
