"""Stage 6 of the demo: the improved model exported as an FMI 2.0 damper FMU, simulated by
FMPy (an independent FMI importer, co-simulation) on a held-out rig test, and compared with
the runtime's forces on the same samples.

FMPy's co-simulation records the force one step late: at t_k it reads the output after the
step from t_k-1, with sample k-1's inputs still set (the FMU is direct feedthrough). So the
FMU's output at t_k is compared with the runtime's force for sample k-1's inputs (and, for a
model with derived-feature states, the states after that step with those inputs held)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Sequence

import numpy as np

from dampnet.figures import save_figure
from dampnet.data import DynoTest

#: |FMU - runtime| [N] allowed: both evaluate the same double-precision code, so rounding only
TOLERANCE_N = 1e-9
#: seconds of the test simulated (2500 samples at 5 kHz: FMPy steps in Python, ~0.1 ms a step)
WINDOW_S = 0.5
NO_FMPY = "fmpy is not installed: pip install fmpy"


def rig_signals(model, test: DynoTest, window_s: float = WINDOW_S) -> dict[str, np.ndarray]:
    """The FMU's inputs over the first window_s of a rig test: t [s], x [m], v [m/s], a [m/s2]
    (the test's channel, else derived as the model's training derived it), u (the model's
    control unit), temperature [degC] (the test's channel, else 20)."""
    from dampnet.features import feature_matrix

    n = min(len(test), int(round(window_s / test.dt)) + 1)
    cols = feature_matrix([test], ["displacement", "velocity", "acceleration", test.control_name],
                          model.feature_params)[:n]
    temp = test.channels.get("temperature")
    # t exactly k * dt: FMPy's communication points are start + k * step, so its linear
    # interpolation of the inputs returns the samples themselves
    return {"t": np.arange(n) * test.dt, "x": cols[:, 0], "v": cols[:, 1], "a": cols[:, 2], "u": cols[:, 3],
            "temperature": np.full(n, 20.0) if temp is None else np.asarray(temp[:n], dtype=np.float64)}


def _states(model, sig: dict[str, np.ndarray]) -> tuple[dict, dict, np.ndarray]:
    """(loop, held, prev): the damper's states (_core.DAMPER_STATES, by name) [n] as dampnet's
    loop commits them at each sample, as FMPy reads them (held over its late step), and the
    sample whose inputs FMPy's output at each sample has (k - 1; the first its own).

    States (only those the model's features use) by dampnet.features' loop updates, from the
    runtime's reset at the first sample: over a step the control is held and the motion a ramp."""
    from dampnet import features

    t, n = sig["t"], sig["t"].size
    dt = float(t[1] - t[0])
    q = [{"x": sig["x"][k], "v": sig["v"][k], "u": sig["u"][k]} for k in range(n)]
    # a state the model does not use gets its value at rest (a lag its source, the Dahl state 0;
    # not read by the network)
    loop = {field: np.array([state.first(qk) for qk in q])
            for field, (state, _param) in features.damper_states().items()}
    held = dict(loop)
    for name in model.features:
        f = features.feature(name)
        if f.state is None:
            continue
        p = float(model.feature_params[f.param])
        y, h = np.empty(n), np.empty(n)
        y[0] = h[0] = f.state.first(q[0])
        for k in range(1, n):
            y[k] = f.state.step(y[k - 1], q[k - 1], q[k], dt, p)      # committed at t_k (the loop's)
            h[k] = f.state.step(y[k - 1], q[k - 1], q[k - 1], dt, p)  # what FMPy reads at t_k
        loop[f.field], held[f.field] = y, h
    prev = np.concatenate([[0], np.arange(n - 1)])  # FMPy's output at t_k has sample k-1's inputs (t_0: its own)
    return loop, held, prev


def runtime_forces(model, sig: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(loop, as_fmpy, status): the runtime damper's (dampnet.sim.quarter_car.loop.damper_from_model) force
    [N] at each sample with the states dampnet's loop keeps (_states), and the force FMPy's
    co-simulation should record at each sample (one step late, see the module docstring);
    status of the latter."""
    from dampnet.sim.quarter_car.loop import damper_from_model

    loop, held, prev = _states(model, sig)
    damper = damper_from_model(model)
    f_loop = damper.forces(x=sig["x"], v=sig["v"], a=sig["a"], u=sig["u"], temperature=sig["temperature"],
                           **loop)[0]
    f_fmpy, status, _ = damper.forces(x=sig["x"][prev], v=sig["v"][prev], a=sig["a"][prev], u=sig["u"][prev],
                                      temperature=sig["temperature"][prev], **held)
    return f_loop, f_fmpy, status


def fmpy_inputs(model, sig: dict[str, np.ndarray]) -> np.ndarray:
    """The network's inputs [n, n_inputs] behind FMPy's record at each sample (sample k-1's
    inputs with the states held over the step: _states), by each feature's dn_damper_input
    field (dampnet.features registry)."""
    from dampnet.features import feature

    _, held, prev = _states(model, sig)
    fields = {"x": sig["x"][prev], "v": sig["v"][prev], "a": sig["a"][prev], "u": sig["u"][prev],
              "temperature": sig["temperature"][prev], **held}
    return np.stack([np.asarray(fields[feature(f).field], dtype=np.float64) for f in model.features], axis=1)


def simulate(path: Path, sig: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """FMPy's co-simulation of the FMU at a fixed step = the sample time; the force [N] and the
    envelope flags it records."""
    from fmpy import simulate_fmu

    names = ("x", "v", "a", "u", "temperature")
    inp = np.zeros(sig["t"].size, dtype=[("time", float)] + [(nm, float) for nm in names])
    inp["time"] = sig["t"]
    for nm in names:
        inp[nm] = sig[nm]
    dt = float(sig["t"][1] - sig["t"][0])
    res = simulate_fmu(str(path), start_time=0.0, stop_time=float(sig["t"][-1]), step_size=dt,
                       output_interval=dt, input=inp, output=["force", "envelope_flags"],
                       fmi_type="CoSimulation")
    return np.asarray(res["force"], dtype=np.float64), np.asarray(res["envelope_flags"], dtype=np.uint32)


def _flags_check(model, envelope, sig: dict, flags: np.ndarray) -> dict:
    """The FMU's envelope_flags against the runtime check's on the inputs FMPy's record has."""
    from dampnet import _core
    from dampnet.envelope.grid import ranges_check, runtime_envelope

    check = runtime_envelope(envelope) if envelope is not None else ranges_check(model.sat_lo, model.sat_hi)
    expected = check.check(fmpy_inputs(model, sig))
    return {"grid": envelope is not None, "share_flagged": float(np.mean(flags != 0)),
            "share_outside_joint": float(np.mean((flags & _core.ENV_OUTSIDE_JOINT) != 0)),
            "match": bool(flags.shape == expected.shape and np.array_equal(flags, expected))}


def plot(sig: dict, f_loop: np.ndarray, f_fmu: np.ndarray, diff: np.ndarray, path: Path, title: str) -> None:
    """The FMU's force trace (shifted back FMPy's one step) over the runtime's, and FMU - runtime."""
    import matplotlib

    matplotlib.use("Agg")  # files only, no display
    import matplotlib.pyplot as plt

    t = sig["t"]
    fig, ax = plt.subplots(2, 1, figsize=(9, 5), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    ax[0].plot(t, f_loop, lw=2.5, color="#9ab", label="runtime (dampnet.sim.quarter_car.loop damper)")
    ax[0].plot(t[:-1], f_fmu[1:], lw=0.9, ls="--", color="#a00", label="FMU run by FMPy (one step late, shifted back)")
    ax[0].set_ylabel("damper force [N]")
    ax[0].legend(loc="best", fontsize=8, framealpha=0.9)
    ax[0].set_title(title)
    ax[1].plot(t, diff, lw=0.8, color="#444")
    ax[1].set_ylabel("FMU - runtime [N]")
    ax[1].set_xlabel("time [s]")
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, 110)


def check_fmu(model, tests: Sequence[DynoTest], out_fmu: Path, fig_path: Path,
              window_s: float = WINDOW_S, envelope=None) -> dict:
    """Build out_fmu (FMI 2.0) from the model (with `envelope`, the model's dampnet.envelope
    Envelope, its envelope_flags output checks the training envelope's grid), simulate it with
    FMPy on the test among `tests` with the widest measured force range in its first window_s,
    compare with the runtime.

    Returns {path, fmi_version, test, samples, step_s, max_abs_diff_n, tolerance_n, match,
    force_range_n, build_time_s, simulate_time_s, time_s, figure, envelope_flags}
    (envelope_flags: {grid, share_flagged, share_outside_joint, match}: the FMU's flags against the
    runtime check's on the same inputs; ranges only without an envelope); when the check cannot run,
    {skipped: why} (the FMU refuses the model or no compiler: FmuError's message; no fmpy),
    with path and fmi_version if the FMU was built."""
    from dampnet.export.fmu import FmuError, build_damper_fmu

    t0 = time.perf_counter()
    try:
        import fmpy  # noqa: F401  (an optional test extra, not a runtime dependency)
        have_fmpy = True
    except ImportError:
        have_fmpy = False
    out_fmu.parent.mkdir(parents=True, exist_ok=True)
    try:
        path = build_damper_fmu(model, out_fmu, envelope=envelope)
    except FmuError as e:
        return {"skipped": f"the FMU could not be built: {e}", "time_s": round(time.perf_counter() - t0, 2)}
    built = {"path": str(path), "fmi_version": "2.0", "build_time_s": round(time.perf_counter() - t0, 2)}
    if not have_fmpy:
        return {**built, "skipped": NO_FMPY, "time_s": built["build_time_s"]}
    from fmpy import read_model_description

    built["fmi_version"] = read_model_description(str(path)).fmiVersion

    n = int(round(window_s / tests[0].dt)) + 1
    test = max(tests, key=lambda tt: float(np.ptp(tt.channels["force"][:n])) if "force" in tt.channels else 0.0)
    sig = rig_signals(model, test, window_s)
    t1 = time.perf_counter()
    f_fmu, flags = simulate(path, sig)
    t_sim = time.perf_counter() - t1
    f_loop, f_expected, status = runtime_forces(model, sig)
    if f_fmu.size != f_expected.size:
        raise RuntimeError(f"FMPy recorded {f_fmu.size} forces for {f_expected.size} samples")
    diff = f_fmu - f_expected
    worst = float(np.max(np.abs(diff)))
    plot(sig, f_loop, f_fmu, diff, fig_path,
         f"rig test {test.test_id}: FMU in FMPy vs runtime, max |difference| {worst:.3g} N")
    return {**built, "interface": "co-simulation", "test": test.test_id, "samples": int(sig["t"].size),
            "envelope_flags": _flags_check(model, envelope, sig, flags),
            "step_s": float(sig["t"][1] - sig["t"][0]), "max_abs_diff_n": worst, "tolerance_n": TOLERANCE_N,
            "match": bool(worst <= TOLERANCE_N), "force_range_n": float(np.ptp(f_loop)),
            "runtime_status_ok": bool(np.all(status >= 0)), "simulate_time_s": round(t_sim, 2),
            "time_s": round(time.perf_counter() - t0, 2), "figure": str(fig_path)}
