"""The virtual shock dyno: runs a test plan on the truth damper and records noisy sensor data.

`generate(plan, effects, seed)` returns a Dataset whose meta records what the
rig did: plan, effects (with their parameters), seed, truth parameters,
sensor noise and resolution. Each test states its place in the order the rig ran
them (meta `run_order`, 1..n; written as the manifest's run_order column). Deterministic for a seed: every test draws its
noise from its own stream, seeded by (seed, test index).
"""

from __future__ import annotations

import time as _time

import numpy as np

from dampnet.rig.effects import get_effect
from dampnet.rig.plans import load_plan
from dampnet.rig.sensors import RESOLUTION, SensorNoise, measure, quantise
from dampnet.rig.truth import TruthParams, truth_force
from dampnet.data.types import RIG_GENERATOR, Dataset, DynoTest


def _random_motion(n, fs, rms, band, rng):
    """Band-limited Gaussian displacement [m] (RMS `rms`), its velocity and acceleration (spectral)."""
    f = np.fft.rfftfreq(n, 1.0 / fs)
    spec = (rng.normal(size=f.size) + 1j * rng.normal(size=f.size)) * ((f >= band[0]) & (f <= band[1]))
    x = np.fft.irfft(spec, n)
    scale = rms / np.sqrt(np.mean(x * x))
    w = 2j * np.pi * f
    return (x * scale, np.fft.irfft(spec * w, n) * scale, np.fft.irfft(spec * w * w, n) * scale)


def _steps(t, v0, levels, period):
    """Voltage stepping every `period` [s] through `levels`, starting at v0."""
    seq = [v0] + [lv for lv in levels if lv != v0]
    k = np.floor((t - t[0]) / period).astype(int) % len(seq)
    return np.asarray(seq, dtype=np.float64)[k]


def generate(plan="thesis", effects=(), seed: int = 0, progress: bool = False, *,
             params: TruthParams | None = None, noise: SensorNoise | None = None,
             truth_channels: bool = False) -> Dataset:
    """Run `plan` ('thesis', 'quick', a JSON plan path, or a Plan) on the truth damper.

    `effects`: names from EFFECTS (or Effect objects) to switch on. Channels
    recorded: displacement [m], velocity [m/s], force [N], voltage [V], and
    temperature [degC] when an effect makes it vary. With truth_channels, the
    noise-free 'true_force' [N] and 'true_acceleration' [m/s^2] are added.
    """
    t_start = _time.perf_counter()
    plan = load_plan(plan)
    p = params or TruthParams()
    noise = noise or SensorNoise()
    effs = [get_effect(e) for e in effects]
    names = [e.name for e in effs]
    if len(set(names)) != len(names):
        raise ValueError(f"effects: each effect once, got {names}")
    specs = plan.specs()
    fs = float(plan.sample_rate_hz)
    dt = 1.0 / fs
    levels = plan.control.get("levels_v", plan.voltages_v)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(specs), desc=f"rig {plan.name}", unit="test")
    thermal = [e for e in effs if e.varies_temperature]  # the tests carry their starting oil temperature
    tests: list[DynoTest | None] = [None] * len(specs)
    order = next((o for o in (e.run_order(len(specs), seed) for e in effs) if o is not None), None)
    place = np.argsort(order) if order is not None else np.arange(len(specs))  # spec -> run position
    groups: dict[int, list[int]] = {}
    for i, s in enumerate(specs):
        groups.setdefault(s["n"], []).append(i)
    for n, idx in groups.items():
        t = np.arange(n) * dt
        rngs = [np.random.default_rng([seed, i]) for i in idx]
        X, V, A, U, T0 = [], [], [], [], []
        for i, rng in zip(idx, rngs):
            s = specs[i]
            if plan.excitation == "sine":
                w = 2 * np.pi * s["frequency_hz"]
                amp = s["amplitude_m"]
                x, v, a = amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w * w * np.sin(w * t)
            else:
                x, v, a = _random_motion(n, fs, s["amplitude_m"], plan.band_hz, rng)
            u = np.full(n, s["voltage_v"])
            if plan.control.get("waveform") == "steps":
                u = _steps(t, s["voltage_v"], levels, float(plan.control.get("period_s", 0.5)))
            for e in effs:
                u = e.control(t, u, levels, rng)
            t0 = None
            run = place[i] / max(len(specs) - 1, 1)  # the test's place in the run order, 0..1
            for e in effs:
                t0 = e.initial_temperature(rng, run) if t0 is None else t0
            X.append(x), V.append(v), A.append(a), U.append(u), T0.append(t0)
        recorded = play(t, np.array(X), np.array(V), np.array(A), np.array(U), T0, effs, p, noise, rngs,
                        truth_channels)
        for i, ch in zip(idx, recorded):
            s = specs[i]
            tests[i] = DynoTest(test_id=s["test_id"], time=quantise(t, RESOLUTION["time"]), channels=ch,
                                frequency_hz=s["frequency_hz"], amplitude_m=s["amplitude_m"],
                                control_nominal=s["voltage_v"], control_name="voltage",
                                meta={"run_order": int(place[i]) + 1,  # the rig states the order it ran them in
                                      **({"initial_temperature_c": T0[idx.index(i)]} if thermal else {})})
        if bar is not None:
            bar.update(len(idx))
    if bar is not None:
        bar.close()
    from dampnet import __version__

    meta = {
        "generator": RIG_GENERATOR, "dampnet_version": __version__,
        "plan": plan.to_dict(), "effects": {e.name: e.params() for e in effs}, "seed": int(seed),
        "truth_params": p.to_dict(), "noise": noise.to_dict(), "resolution": dict(RESOLUTION),
        "truth_channels": bool(truth_channels),
        "generation_s": round(_time.perf_counter() - t_start, 3),
    }
    if order is not None:  # the dataset lists the tests in the order they were run
        tests = [tests[j] for j in order]
    return Dataset(tests=list(tests), source=f"dampnet rig: plan {plan.name}, effects "
                   f"{','.join(names) or 'none'}, seed {seed}", meta=meta)


def play(t: np.ndarray, X: np.ndarray, V: np.ndarray, A: np.ndarray, U: np.ndarray, T0: list, effs: list,
         p: TruthParams, noise: SensorNoise, rngs: list, truth_channels: bool = False) -> list[dict]:
    """The rig's recording of motions X [m], V [m/s], A [m/s^2] at controls U [V] (rows: tests, all
    at times `t` [s]) on the truth damper with `effs`: one channel dict per row (sensor noise from
    that row's `rngs`; temperature when an effect heats the oil from T0 [degC]). What `generate`
    and a replayed drive (dampnet.rig.replay) share."""
    dt = float(t[1] - t[0])
    n = t.shape[0]
    thermal = [e for e in effs if e.varies_temperature]
    logged = any(e.records_temperature for e in effs)  # a campaign's warming may go unlogged
    temp = None
    if thermal:
        t0 = np.array(T0, dtype=np.float64)
        temp = np.repeat(t0[:, None], n, axis=1)
        _, parts = truth_force(X, V, U, temp, dt=dt, params=p, effects=effs, return_parts=True)
        power = parts["hydraulic"] * V          # [W] dissipated by the hydraulics
        temp = thermal[0].heating(t, power, t0)
    F = truth_force(X, V, U, temp, dt=dt, params=p, effects=effs)
    out = []
    for row, rng in enumerate(rngs):
        ch = {"displacement": measure("displacement", X[row], noise, rng),
              "velocity": measure("velocity", V[row], noise, rng),
              "force": measure("force", F[row], noise, rng),
              "voltage": measure("voltage", U[row], noise, rng)}
        if temp is not None and logged:
            ch["temperature"] = measure("temperature", temp[row], noise, rng)
        if truth_channels:
            ch["true_force"] = F[row].copy()
            ch["true_acceleration"] = A[row].copy()
        out.append(ch)
    return out


def noise_floor_rmse_n(ds: Dataset) -> float:
    """The RMS [N] of what the rig's force channel adds to the true force: load-cell noise plus
    the channel's rounding, sqrt(sigma_F^2 + res^2 / 12). ValueError without the rig's meta."""
    try:
        sigma = float(ds.meta["noise"]["force_n"])
        res = float(ds.meta.get("resolution", {}).get("force", 0.0))
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{ds.source}: no rig noise record in meta['noise']: expected a dataset "
                         "made by dampnet.rig.generate") from None
    return float(np.sqrt(sigma ** 2 + res ** 2 / 12.0))


def noise_floor_nrmse(ds: Dataset) -> float:
    """The NRMSE a perfect model would score on `ds` because of load-cell noise alone.

    NRMSE = RMS(error) / std(measured force) over all samples of all tests (the
    definition dampnet reports); here error = load-cell noise plus the force
    channel's rounding (noise_floor_rmse_n). Needs the rig's meta.
    Noise on the inputs (velocity, displacement) adds to what a model really
    scores; this is the floor set by the force measurement itself.
    """
    rms = noise_floor_rmse_n(ds)
    f = ds.concat("force")
    return float(rms / np.std(f))
