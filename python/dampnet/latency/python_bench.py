"""Python-level latency of single-sample forward calls of the default 3-30-1 model, side by
side: dampnet's own pybind11 call (`_core.Mlp.forward`), a numpy forward, torch eager,
TorchScript and onnxruntime; plus the pybind11 quarter-car `Loop.step` latency and
`Loop.simulate` throughput.

Every alternative computes the same function as the C++ kernel: clamp each input to
[sat_lo, sat_hi], mapminmax-scale, tanh hidden layer, linear output, unscale. Each is
checked against `MlpModel.predict` (the kernel) on the benchmark inputs before it is timed
(`check_references`), and a failed check raises instead of timing a different function.

Timing: warm-up calls first, then every call timed on its own with time.perf_counter_ns
(the figures include the two clock reads; the `python_clock_overhead` row measures them).
Python-level figures include the interpreter's call overhead; the C++ kernel figure comes
from the C++ harness (bench/bench_mlp.cpp), timed with steady_clock inside C++.

Torch, TorchScript and onnxruntime run single-threaded (torch.set_num_threads(1), an ORT
session with intra/inter-op threads 1) in float32, the usual inference precision, so they
compare with dampnet's float kernel; the numpy forward and `_core.Mlp.forward` (double
path) are float64.
"""

from __future__ import annotations

import gc
import json
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any, Callable

import numpy as np

from dampnet.model import MlpModel
from dampnet.modeldir import default_model
from dampnet.reference import forward_of

N_INPUT_SETS = 1024  # inputs cycled, as in the C++ harness
STEP_TARGET_NS = 1000.0  # pybind11 Loop.step median target
SIMULATE_TARGET_STEPS_PER_S = 5e6  # Loop.simulate throughput target ...
# ... for the real-time configurations; the per-stage (offline accuracy) and double runs are reported
SIMULATE_TARGET_RUNS = ("linear", "neural_float_hil", "neural_float_hil_out")
# Agreement with MlpModel.predict (the float64 kernel), as a fraction of the model's output
# range (2 / out_gain): float32 implementations and float64 ones.
TOL_FLOAT32 = 1e-5
TOL_FLOAT64 = 1e-10
QUANTILES = {"p50_ns": 0.50, "p99_ns": 0.99, "p999_ns": 0.999}


# ---- the model and the inputs -------------------------------------------------------------

def harness_inputs(model: MlpModel, n: int = N_INPUT_SETS, seed: int = 1) -> np.ndarray:
    """The C++ harness's inputs [n, n_inputs]: std::mt19937(seed) and one
    std::uniform_real_distribution<double>(sat_lo[i], sat_hi[i]) draw per input, in order.

    libstdc++'s generate_canonical<double, 53> takes two 32-bit draws r0, r1 and returns
    (r0 + r1 2^32) / 2^64 (clamped below 1); numpy's MT19937 with legacy seeding is the same
    engine as std::mt19937.
    """
    bg = np.random.MT19937(0)
    bg._legacy_seeding(seed)
    k = model.n_inputs
    raw = bg.random_raw(2 * n * k).astype(np.float64).reshape(n * k, 2)
    u = (raw[:, 0] + raw[:, 1] * 4294967296.0) / 18446744073709551616.0
    u = np.minimum(u, np.nextafter(1.0, 0.0)).reshape(n, k)
    return model.sat_lo + (model.sat_hi - model.sat_lo) * u


# ---- the reference implementations ----------------------------------------------------------

def numpy_forward(model: MlpModel) -> Callable[[np.ndarray], float]:
    """A float64 numpy forward of one sample x [n_inputs]: dampnet.reference's, the kernel's
    function in numpy (NaN to the range's centre, clamp, scale, layers, unscale).

    The candidate is the package's own numpy forward rather than a separate naive copy, so the
    figure is the latency of the numpy implementation dampnet actually uses (diagnosis, the
    reference loop); its NaN replacement costs one np.where per call."""
    forward = forward_of(model)
    return lambda x: float(forward(x))


def torch_module(model: MlpModel, dtype=None):
    """nn.Sequential computing the kernel's function: clamp, mapminmax (a diagonal Linear),
    the hidden layer(s), the output Linear, unscaling (a 1x1 Linear). float32 by default."""
    import torch
    from torch import nn

    dtype = dtype or torch.float32
    t = lambda a: torch.as_tensor(np.asarray(a, dtype=np.float64), dtype=dtype)  # noqa: E731

    class Clamp(nn.Module):
        def __init__(self, lo, hi):
            super().__init__()
            self.register_buffer("lo", lo)
            self.register_buffer("hi", hi)

        def forward(self, x):
            return torch.maximum(torch.minimum(x, self.hi), self.lo)

    def linear(w, b):
        w = np.atleast_2d(np.asarray(w, dtype=np.float64))
        lin = nn.Linear(w.shape[1], w.shape[0]).to(dtype)
        with torch.no_grad():
            lin.weight.copy_(t(w))
            lin.bias.copy_(t(b))
        return lin

    n = model.n_inputs
    act = nn.Tanh if model.activation == "tanh" else nn.Sigmoid
    layers = [Clamp(t(model.sat_lo), t(model.sat_hi)),
              linear(np.diag(model.in_gain), model.in_ymin - model.in_offset * model.in_gain),
              linear(model.w1, model.b1), act()]
    if model.w2 is not None:
        layers += [linear(model.w2, model.b2), act()]
    layers += [linear(model.w_out[None, :], [model.b_out]),
               linear([[1.0 / model.out_gain]], [model.out_offset - model.out_ymin / model.out_gain])]
    assert n == layers[1].in_features
    return nn.Sequential(*layers).eval()


def onnx_session(module, n_inputs: int, path: Path):
    """Export `module` (float32) with torch.onnx.export and open a single-threaded session."""
    import onnxruntime as ort
    import torch

    example = torch.zeros(1, n_inputs, dtype=torch.float32)
    kwargs: dict[str, Any] = dict(input_names=["x"], output_names=["force"], opset_version=17)
    with warnings.catch_warnings():  # the TorchScript-based exporter is deprecated, not gone
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            torch.onnx.export(module, (example,), str(path), dynamo=False, **kwargs)
        except TypeError:  # an older torch without the dynamo switch
            torch.onnx.export(module, (example,), str(path), **kwargs)
    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.inter_op_num_threads = 1
    so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])


# ---- statistics -------------------------------------------------------------------------------

def percentile(sorted_ns: np.ndarray, q: float) -> float:
    """Nearest rank on a sorted sample, as bench/latency.hpp (rank q (n-1), rounded half up)."""
    if len(sorted_ns) == 0:
        return 0.0
    return float(sorted_ns[int(q * (len(sorted_ns) - 1) + 0.5)])


def summarise(ns) -> dict[str, float]:
    s = np.sort(np.asarray(ns, dtype=np.float64))
    out = {k: percentile(s, q) for k, q in QUANTILES.items()}
    out.update(max_ns=float(s[-1]) if len(s) else 0.0, mean_ns=float(s.mean()) if len(s) else 0.0,
               n=int(len(s)))
    return out


def time_calls(call: Callable[[int], Any], n: int, warmup: int) -> dict[str, float]:
    """Warm up, then time each of n calls call(i) individually with perf_counter_ns."""
    for i in range(warmup):
        call(i)
    ns = np.empty(n, dtype=np.int64)
    clock = time.perf_counter_ns
    gc_was = gc.isenabled()
    gc.disable()  # no collector pauses inside the timed calls
    try:
        for i in range(n):
            t0 = clock()
            call(i)
            ns[i] = clock() - t0
    finally:
        if gc_was:
            gc.enable()
    return summarise(ns)


# ---- the forward-call comparison ----------------------------------------------------------

def build_candidates(model: MlpModel, X: np.ndarray, tmp: Path) -> dict[str, dict[str, Any]]:
    """name -> {"call": call(i) timing one forward of input i mod len(X), "eval": x -> force,
    "dtype": "float32"|"float64", "what": description}. torch/onnxruntime rows are left out
    (with a note under "skipped") when the package is not installed."""
    n = len(X)
    core = model.core()
    xs64 = [np.ascontiguousarray(x) for x in X]
    xs32 = [np.ascontiguousarray(x[None, :], dtype=np.float32) for x in X]
    cands: dict[str, dict[str, Any]] = {}

    cands["dampnet_pybind_forward_float"] = {
        "what": "dampnet _core.Mlp.forward(x, single=True): float kernel via pybind11",
        "dtype": "float32",
        "eval": lambda x: core.forward(np.ascontiguousarray(x, dtype=np.float64), True)[0],
        "call": lambda i: core.forward(xs64[i % n], True)}
    cands["dampnet_pybind_forward"] = {
        "what": "dampnet _core.Mlp.forward(x, single=False): double kernel (tanh_d) via pybind11",
        "dtype": "float64",
        "eval": lambda x: core.forward(np.ascontiguousarray(x, dtype=np.float64), False)[0],
        "call": lambda i: core.forward(xs64[i % n], False)}
    npf = numpy_forward(model)
    cands["numpy_forward"] = {"what": "numpy float64 forward, dampnet.reference (NaN to mid-range, clip, scale, w1 @ x, tanh, w_out @ h)",
                              "dtype": "float64", "eval": npf, "call": lambda i: npf(xs64[i % n])}
    try:
        import torch
    except ImportError as e:
        cands["skipped"] = {"torch_eager": str(e), "torch_script": str(e), "onnxruntime": str(e)}
        return cands
    torch.set_num_threads(1)
    ts32 = [torch.from_numpy(x) for x in xs32]
    mod = torch_module(model)

    def torch_call(m):
        def call(i):
            with torch.inference_mode():
                return m(ts32[i % n])
        return call

    def torch_eval(m):
        def ev(x):
            with torch.inference_mode():
                return float(m(torch.as_tensor(np.asarray(x, dtype=np.float32)[None, :]))[0, 0])
        return ev

    cands["torch_eager"] = {"what": "torch nn.Sequential, eager, float32, 1 thread, inference_mode",
                            "dtype": "float32", "eval": torch_eval(mod), "call": torch_call(mod)}
    with warnings.catch_warnings():  # TorchScript is deprecated in favour of torch.compile
        warnings.simplefilter("ignore", DeprecationWarning)
        scripted = torch.jit.freeze(torch.jit.script(mod))
    cands["torch_script"] = {"what": "the same module, torch.jit.script + freeze, float32, 1 thread",
                             "dtype": "float32", "eval": torch_eval(scripted), "call": torch_call(scripted)}
    try:
        sess = onnx_session(mod, model.n_inputs, tmp / "dn_model_default.onnx")
    except ImportError as e:
        cands["skipped"] = {"onnxruntime": str(e)}
        return cands
    in_name, out_name = sess.get_inputs()[0].name, sess.get_outputs()[0].name
    run = sess.run
    cands["onnxruntime"] = {
        "what": "the same module via torch.onnx.export, onnxruntime CPU, float32, 1 thread, sess.run",
        "dtype": "float32",
        "eval": lambda x: float(run([out_name], {in_name: np.asarray(x, dtype=np.float32)[None, :]})[0][0, 0]),
        "call": lambda i: run([out_name], {in_name: xs32[i % n]})}
    return cands


def check_references(model: MlpModel, cands: dict[str, dict[str, Any]], X: np.ndarray) -> dict[str, dict]:
    """Max |candidate - MlpModel.predict| over X, as a fraction of the output range; raises
    RuntimeError when a candidate is outside its tolerance (it would time another function)."""
    ref = model.predict(X)
    span = 2.0 / abs(model.out_gain)
    out = {}
    for name, c in cands.items():
        if name == "skipped":
            continue
        got = np.array([c["eval"](x) for x in X])
        err = float(np.max(np.abs(got - ref)) / span)
        tol = TOL_FLOAT32 if c["dtype"] == "float32" else TOL_FLOAT64
        out[name] = {"max_abs_err_N": float(np.max(np.abs(got - ref))), "max_err_of_range": err,
                     "tolerance_of_range": tol, "ok": bool(err <= tol)}
        if err > tol:
            raise RuntimeError(f"{name}: differs from MlpModel.predict by {err:.3g} of the output "
                               f"range (tolerance {tol:g}); not timing a different function")
    return out


class _torch_threads_restored:
    """Restores torch's thread count (build_candidates sets it to 1) on exit."""

    def __enter__(self):
        try:
            import torch
            self.n = torch.get_num_threads()
        except ImportError:
            self.n = None
        return self

    def __exit__(self, *exc):
        if self.n is not None:
            import torch
            torch.set_num_threads(self.n)


def forward_comparison(n_calls: int, model: MlpModel | None = None) -> dict[str, Any]:
    """Check, then time every candidate's single-sample call; plus the perf_counter_ns pair."""
    model = model or default_model()
    X = harness_inputs(model)
    warm = max(1000, n_calls // 10)
    with tempfile.TemporaryDirectory() as tmp, _torch_threads_restored():
        cands = build_candidates(model, X, Path(tmp))
        checks = check_references(model, cands, X)
        results = {"python_clock_overhead": time_calls(lambda i: None, n_calls, warm)}
        results["python_clock_overhead"]["what"] = "two perf_counter_ns reads around an empty lambda call"
        skipped = cands.pop("skipped", {})
        for name, c in cands.items():
            r = time_calls(c["call"], n_calls, warm)
            r["what"] = c["what"]
            r["dtype"] = c["dtype"]
            results[name] = r
    versions = {"numpy": np.__version__}
    for pkg in ("torch", "onnxruntime"):
        try:
            versions[pkg] = __import__(pkg).__version__
        except ImportError:
            versions[pkg] = None
    return {"model_id": model.model_id(), "n_calls": n_calls, "warmup": warm, "checks": checks,
            "results": results, "skipped": skipped, "versions": versions,
            "threads": {"torch": 1, "onnxruntime": 1}}


# ---- the quarter-car loop through pybind11 -----------------------------------------------------

def harness_road(dt: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The C++ harness's road: 20 mm of 1.3 Hz and 11 Hz content, at the loop's step."""
    t = np.arange(1, n + 1) * dt
    w1, w2 = 2 * np.pi * 1.3, 2 * np.pi * 11.0
    return (0.015 * np.sin(w1 * t) + 0.005 * np.sin(w2 * t),
            0.015 * w1 * np.cos(w1 * t) + 0.005 * w2 * np.cos(w2 * t))


def _loops(model: MlpModel):
    from dampnet import _core
    from dampnet.latency.harness import HIL_VEHICLE, hil_controller
    from dampnet.sim.quarter_car.loop import damper_from_model

    ctrl = hil_controller(model).core_dict()   # the linear damper takes no control: it ignores it
    hil = HIL_VEHICLE  # the configuration of dampnet.latency.harness.BUDGET_CASE
    return {"linear": _core.LoopModel(_core.Damper.linear(1500.0), {}, ctrl),
            "neural_float": _core.LoopModel(damper_from_model(model, single=True), {}, ctrl),
            "neural_double": _core.LoopModel(damper_from_model(model, single=False), {}, ctrl),
            "neural_float_hil": _core.LoopModel(damper_from_model(model, single=True), hil, ctrl)}


def loop_step_latency(n_calls: int, model: MlpModel | None = None, damper: str = "neural_float",
                      method: str = "step") -> dict:
    """pybind11 `Loop.step(z_r, v_r, u)` (returns a StepReport) or `Loop.step_force` (returns the
    force only) per call, RK4, skyhook on-off; the state is restored every 1000 calls outside
    the timed region, as in the C++ harness."""
    from dampnet import _core

    model = model or default_model()
    lm = _loops(model)[damper]
    loop = _core.Loop(lm)
    z, v = harness_road(float(lm.vehicle["dt"]), 4096)
    zl, vl = z.tolist(), v.tolist()
    for k in range(2000):
        loop.step(zl[k], vl[k], 0.0)
    saved = loop.state
    step = getattr(loop, method)

    warm = max(1000, n_calls // 10)
    for i in range(warm):
        if i % 1000 == 0:
            loop.state = saved
        step(zl[i & 4095], vl[i & 4095], 0.0)
    ns = np.empty(n_calls, dtype=np.int64)
    clock = time.perf_counter_ns
    gc_was = gc.isenabled()
    gc.disable()
    try:
        for i in range(n_calls):
            if i % 1000 == 0:
                loop.state = saved
            j = i & 4095
            a, b = zl[j], vl[j]
            t0 = clock()
            step(a, b, 0.0)
            ns[i] = clock() - t0
    finally:
        if gc_was:
            gc.enable()
    r = summarise(ns)
    r.update(what=f"_core.Loop.{method}(z_r, v_r, u) -> {'StepReport' if method == 'step' else 'float'}, RK4, "
                  f"{damper} damper, skyhook on-off",
             target_ns=STEP_TARGET_NS, metric="p50_ns")
    return r


def simulate_records(n_features: int) -> str:
    """What `Loop.simulate` records per step (the benchmark states it with its figure)."""
    from dampnet import _core

    n_state = len(_core.STATE_NAMES)
    return (f"the state ({n_state} columns, STATE_NAMES) before each step and the step's force, control, "
            f"x, v, a, acc_s, acc_us, {n_features} features and status: "
            f"{8 * (n_state + 7 + n_features) + 4} bytes per step")


def simulate_throughput(n_steps: int, repeats: int = 5, model: MlpModel | None = None) -> dict:
    """`Loop.simulate(road, road_rate)` steps per second (wall clock of the whole call,
    including the output arrays: fresh ones, whose first touch costs page faults and the
    kernel's zeroing), per damper; median and best of `repeats` runs. For the HIL
    configuration also `simulate(..., out=previous result)` (the same results written
    into the arrays of the run before, as a sweep over many roads would), interleaved with
    the fresh runs so both see the same machine."""
    from dampnet import _core

    model = model or default_model()
    out = {}
    for name, lm in _loops(model).items():
        loop = _core.Loop(lm)
        z, v = harness_road(float(lm.vehicle["dt"]), n_steps)
        loop.simulate(z[: min(n_steps, 10_000)], v[: min(n_steps, 10_000)], None, True)  # warm
        reuse = loop.simulate(z, v, None, True) if name == "neural_float_hil" else None
        records = simulate_records(int(loop.simulate(z[:2], v[:2], None, True)["features"].shape[1]))
        secs, secs_out = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = loop.simulate(z, v, None, True)
            secs.append(time.perf_counter() - t0)
            del res  # freed before the next run, as a caller that keeps one result at a time
            if reuse is not None:
                t0 = time.perf_counter()
                loop.simulate(z, v, None, True, reuse)
                secs_out.append(time.perf_counter() - t0)
        for key, ss, how in ((name, secs, "into fresh arrays"), (f"{name}_out", secs_out,
                                                                  "into the previous run's arrays (out=)")):
            if not ss:
                continue
            ss = np.array(ss)
            out[key] = {"n_steps": n_steps, "repeats": repeats,
                        "steps_per_s_median": float(n_steps / np.median(ss)),
                        "steps_per_s_best": float(n_steps / ss.min()),
                        "ns_per_step_median": float(np.median(ss) / n_steps * 1e9),
                        "target_steps_per_s": SIMULATE_TARGET_STEPS_PER_S if key in SIMULATE_TARGET_RUNS else None,
                        "what": f"_core.Loop.simulate over a {n_steps}-sample road, RK4, {name} damper, "
                                f"skyhook on-off, GIL released, recording {records}, {how}"}
            if key in SIMULATE_TARGET_RUNS:
                out[key]["meets_target"] = out[key]["steps_per_s_median"] >= SIMULATE_TARGET_STEPS_PER_S
    return out


def python_benchmarks(n_calls: int, n_sim_steps: int, repeats: int = 5) -> dict[str, Any]:
    """Everything above; the machine's load average at the start and at the end."""
    model = default_model()
    load0 = _loadavg()
    res = forward_comparison(n_calls, model)
    res["loop_step"] = {d: loop_step_latency(n_calls, model, d) for d in ("neural_float", "linear")}
    res["loop_step"]["neural_float_hil_step_force"] = loop_step_latency(n_calls, model, "neural_float_hil",
                                                                        method="step_force")
    res["simulate"] = simulate_throughput(n_sim_steps, repeats, model)
    res["loadavg"] = {"start": load0, "end": _loadavg()}
    return res


def _loadavg() -> str:
    try:
        return Path("/proc/loadavg").read_text().strip()
    except OSError:
        return "unknown"


def ratios(py: dict[str, Any], kernel_p50_ns: float | None) -> None:
    """Add each forward row's median as a ratio to the C++ kernel's and to dampnet's own
    Python-level call's (in place)."""
    own = py["results"].get("dampnet_pybind_forward", {}).get("p50_ns")
    for name, r in py["results"].items():
        r["ratio_to_kernel_p50"] = (r["p50_ns"] / kernel_p50_ns) if kernel_p50_ns else None
        r["ratio_to_dampnet_pybind_p50"] = (r["p50_ns"] / own) if own else None


def header_model_id() -> str | None:
    """DN_MODEL_DEFAULT_ID of the header the C++ harness is compiled with."""
    import re

    from dampnet.latency.harness import harness_sources

    try:
        text = (harness_sources()[1] / "dn_model_default.h").read_text()
    except (FileNotFoundError, OSError):
        return None
    m = re.search(r'#define DN_MODEL_DEFAULT_ID "([0-9a-f]+)"', text)
    return m.group(1) if m else None


KERNEL_CASE = "dampnet_static_float"  # the C++ harness row every forward is compared with


def table(res: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per figure: name, scope (C++/Python), p50/p99/p99.9/max [ns] (or steps/s), the
    budget or target, and the headroom (target / measured, > 1 met) or the ratio to the
    kernel's median. `res` is quick_latency's result with the Python results under "python"."""
    from dampnet.latency.harness import TARGETS_NS

    cpp = res.get("results", {})
    kernel = cpp.get(KERNEL_CASE, {}).get("p50_ns")
    rows: list[dict[str, Any]] = []

    def lat_row(scope, name, r, target=None, budget=None):
        forward = not name.startswith(("clock", "python_clock", "loop_", "pybind_"))
        row = {"scope": scope, "name": name, "p50_ns": r.get("p50_ns"), "p50_net_ns": r.get("p50_net_ns"),
               "p99_ns": r.get("p99_ns"),
               "p999_ns": r.get("p999_ns"), "max_ns": r.get("max_ns"), "target": None, "headroom": None,
               "ratio_to_kernel_p50": (r["p50_ns"] / kernel) if forward and kernel and r.get("p50_ns") else None}
        if budget is not None:
            metric, limit = budget
            row["target"] = f"{metric.replace('_ns', '')} <= {limit:.0f} ns (HIL budget)"
            row["headroom"] = limit / r[metric] if r.get(metric) else None
        elif target is not None:
            metric, limit = target
            row["target"] = f"{metric.replace('_ns', '')} <= {limit:.0f} ns"
            row["headroom"] = limit / r[metric] if r.get(metric) else None
        rows.append(row)

    budget = res.get("budget", {})
    for name, r in cpp.items():
        if name == budget.get("case"):
            lat_row("C++", name, r, budget=("p999_ns", budget["p999_budget_ns"]))
            if name in TARGETS_NS:
                lat_row("C++", name + " (median target)", r, target=TARGETS_NS[name])
        else:
            lat_row("C++", name, r, target=TARGETS_NS.get(name))
    py = res.get("python")
    if py:
        for name, r in py["results"].items():
            lat_row("Python", name, r)
        for damper, r in py["loop_step"].items():
            lat_row("Python", f"pybind_loop_step_{damper}", r, target=(r["metric"], r["target_ns"]))
        for damper, r in py["simulate"].items():
            rows.append({"scope": "Python", "name": f"pybind_simulate_{damper}",
                         "steps_per_s": r["steps_per_s_median"], "steps_per_s_best": r["steps_per_s_best"],
                         "ns_per_step": r["ns_per_step_median"],
                         "target": f">= {r['target_steps_per_s']:.3g} steps/s" if r["target_steps_per_s"] else "-",
                         "headroom": (r["steps_per_s_median"] / r["target_steps_per_s"]
                                      if r["target_steps_per_s"] else None),
                         "ratio_to_kernel_p50": None})
    return rows


def format_table(rows: list[dict[str, Any]]) -> str:
    def f(v, fmt="{:.0f}"):
        return "-" if v is None else fmt.format(v)

    out = [f"{'scope':6s} {'figure':52s} {'p50':>9s} {'net p50':>8s} {'p99':>9s} {'p99.9':>9s} {'max':>10s}  "
           f"{'x kernel p50':>12s}  {'budget / target':30s} headroom",
           f"{'':6s} {'':52s} {'[ns]':>9s} {'[ns]':>8s} {'[ns]':>9s} {'[ns]':>9s} {'[ns]':>10s}"]
    for r in rows:
        hr = "-" if r["headroom"] is None else f"x{r['headroom']:.2f}" + ("" if r["headroom"] >= 1 else " (not met)")
        if "steps_per_s" in r:
            body = (f"{f(r['steps_per_s'], '{:.3g}'):>9s} steps/s median (best {r['steps_per_s_best']:.3g}, "
                    f"{r['ns_per_step']:.0f} ns/step)")
            out.append(f"{r['scope']:6s} {r['name']:52s} {body:76s}  {r['target']:30s} {hr}")
            continue
        p50 = f(r["p50_ns"], "{:.1f}") if r["name"].endswith("_chained") else f(r["p50_ns"])
        out.append(f"{r['scope']:6s} {r['name']:52s} {p50:>9s} {f(r.get('p50_net_ns')):>8s} {f(r['p99_ns']):>9s} "
                   f"{f(r['p999_ns']):>9s} {f(r['max_ns']):>10s}  {f(r['ratio_to_kernel_p50'], '{:.1f}'):>12s}  "
                   f"{r['target'] or '-':30s} {hr}")
    return "\n".join(out)


if __name__ == "__main__":  # python -m dampnet.latency.python_bench [N]
    import sys

    n = int(sys.argv[1]) if len(sys.argv) > 1 else 20000
    print(json.dumps(python_benchmarks(n, 200_000), indent=1))
