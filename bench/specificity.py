"""The diagnosis's specificity panel (issue 50): clean data, no measurement fault at all, of varied
shape; per artefact detector, how often it claims an artefact (its false-positive rate at its stated
significance) and the threshold on its statistic that holds it at 1 in 20 datasets or fewer.
Prints the table bench/RESULTS.md quotes ("Specificity") and writes every number as JSON.

The panel (each shape over --seeds rig seeds; the test suite's small panel is
tests/python/test_diagnose_specificity.py):

  shapes   tests of 2.5 and 3.5 cycles (2 s at 1.25 and 1.75 Hz, the issue's shape) and whole
           cycles; run orders stated and sorted by frequency (the rig's), stated and shuffled, not
           stated (a manifest sorted by frequency without a run_order column); sample rates 500 Hz,
           1 kHz, 2 kHz; random content; ramps and rests (a rest of 1 s, a 0.5 s ramp in, the sine,
           a ramp out and a rest, on the rig's truth damper with its sensor noise)
  effects  the virtual rig with one physical effect alone, the model without it: mount_hysteresis,
           thermal (logged temperature), friction, gas_spring, valve_lag, bump_stop, each with a
           shuffled stated run order and with none (a manifest sorted by frequency); the rig's own
           oil compressibility is always on
  real     the real datasets of ../shared/data (UTFSM MTS, labcontrol), when present

Each dataset gets a small model (LM, every 8th sample, --epochs epochs: the detectors fit the data,
not the model, except the drift's and slips' residual and gain) and every artefact detector
(dampnet.diagnosis.artefacts.find_artefacts, as `dampnet diagnose` calls it). Statistics: the time
offset's |offset| / uncertainty (SHIFT_Z = 4 with the other conditions), the drift's z (score.Z_MIN),
the displacement zero's largest robust z over the tests (OFFSET_Z = 6, and beyond its own bound).

    python bench/specificity.py                       # 3 seeds, about 2 minutes
    python bench/specificity.py --seeds 1 --quick     # the shapes once, no effects: a smoke run
    python bench/specificity.py --json out.json

Run from a checkout of another commit (PYTHONPATH=<its python>), the same panel measures that
commit's detectors: what bench/RESULTS.md's "before" column is (e109bff).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

DETECTORS = ("time_offset", "run_order_drift", "sensor_offset", "sign_slip", "unit_slip")
PARTIAL = {"name": "partial", "frequencies_hz": [0.5, 1.0, 1.25, 1.75, 2.0, 3.0], "amplitudes_m": [0.0254],
           "voltages_v": [0.0, 1.0, 2.25, 3.0, 5.0], "sample_rate_hz": 1000.0, "samples": 2000, "min_cycles": 1}
WHOLE = {"name": "whole", "frequencies_hz": [0.25, 0.5, 1.0, 2.0, 3.0], "amplitudes_m": [0.0254],
         "voltages_v": [0.0, 0.5, 1.0, 2.25, 3.0, 5.0], "sample_rate_hz": 1000.0, "samples": 2000, "min_cycles": 2}
RANDOM = {"name": "random", "excitation": "random", "amplitudes_m": [0.008], "voltages_v": [0.0, 1.0, 2.25, 3.0, 5.0],
          "sample_rate_hz": 1000.0, "duration_s": 3.0, "samples": 1000, "band_hz": [0.5, 4.0]}
EFFECTS = ("mount_hysteresis", "thermal", "friction", "gas_spring", "valve_lag", "bump_stop")


def _with_order(ds, how: str, seed: int):
    """The rig's stated order (sorted by frequency), a shuffled stated one, or none stated."""
    if how == "rig":
        return ds
    if how == "none":
        return ds.subset([t.copy(meta={k: v for k, v in t.meta.items() if k != "run_order"}) for t in ds.tests])
    order = np.random.default_rng([seed, 7]).permutation(len(ds.tests))
    return ds.subset([ds.tests[j].copy(meta={**ds.tests[j].meta, "run_order": k + 1}) for k, j in enumerate(order)])


def ramps_and_rests(seed: int):
    """Sine tests between rests: 1 s still, a 0.5 s ramp in, 2.5 cycles, a 0.5 s ramp out, 1 s still;
    the rig's truth damper and sensor noise."""
    from dampnet.data import Dataset, DynoTest
    from dampnet.rig import truth_force
    from dampnet.rig.sensors import SensorNoise, measure

    fs, amp, noise = 1000.0, 0.02, SensorNoise()
    tests = []
    k = 0
    for f in (0.5, 1.25, 2.0):
        for u in (0.0, 2.25, 5.0):
            k += 1
            rng = np.random.default_rng([seed, k])
            dur = 2.5 / f
            t = np.arange(int((3.0 + dur) * fs)) / fs
            env = np.clip((t - 1.0) / 0.5, 0, 1) * np.clip((2.0 + dur - t) / 0.5, 0, 1)
            s = np.where((t >= 1.0) & (t <= 2.0 + dur), np.sin(2 * np.pi * f * (t - 1.0)), 0.0)
            x = amp * env * s
            v = np.gradient(x, 1 / fs)
            uu = np.full_like(t, u)
            force = truth_force(x, v, uu, dt=1 / fs)
            ch = {"displacement": measure("displacement", x, noise, rng), "velocity": measure("velocity", v, noise, rng),
                  "force": measure("force", force, noise, rng), "voltage": measure("voltage", uu, noise, rng)}
            tests.append(DynoTest(f"RR{k:02d}", t, ch, frequency_hz=f, amplitude_m=amp, control_nominal=u,
                                  meta={"run_order": int(rng.integers(1_000_000))}))
    return Dataset(tests=tests, source=f"ramps and rests, seed {seed}",
                   meta={"generator": "dampnet.data.rig", "noise": noise.to_dict()})


def panel(seeds: int, quick: bool, real: bool):
    """[(name, kind, build)]: build() -> Dataset."""
    from dampnet.rig import generate

    out = []
    for s in range(seeds):
        for order in ("rig", "shuffled", "none"):
            out.append((f"2.5/3.5 cycles, order {order}, seed {s}", "shape",
                        lambda s=s, o=order: _with_order(generate(PARTIAL, seed=s), o, s)))
        out.append((f"whole cycles, order shuffled, seed {s}", "shape",
                    lambda s=s: _with_order(generate(WHOLE, seed=s), "shuffled", s)))
        for rate in (500.0, 2000.0):
            out.append((f"{rate:g} Hz, order shuffled, seed {s}", "shape",
                        lambda s=s, r=rate: _with_order(generate({**PARTIAL, "sample_rate_hz": r,
                                                                  "samples": int(2 * r)}, seed=s), "shuffled", s)))
        out.append((f"random content, order shuffled, seed {s}", "shape",
                    lambda s=s: _with_order(generate(RANDOM, seed=s), "shuffled", s)))
        out.append((f"ramps and rests, seed {s}", "shape", lambda s=s: ramps_and_rests(s)))
        if not quick:
            for e in EFFECTS:
                for order in ("shuffled", "none"):
                    out.append((f"{e} alone, order {order}, seed {s}", "effect",
                                lambda s=s, e=e, o=order: _with_order(generate(PARTIAL, effects=[e], seed=s), o, s)))
    if real:
        from dampnet.data.real import LABCONTROL, UTFSM, load_labcontrol, load_utfsm, shared_data_dir

        root = shared_data_dir()
        if (root / UTFSM).is_dir():
            out.append(("real: UTFSM MTS (30 tests, no run order)", "real", load_utfsm))
        if (root / LABCONTROL).is_dir():
            out.append(("real: labcontrol (no run order)", "real", load_labcontrol))
    return out


def run_one(ds, epochs: int, n_sur: int) -> dict:
    from dampnet.diagnosis import score as S
    from dampnet.diagnosis.artefacts import find_artefacts
    from dampnet.diagnosis.context import build_context
    from dampnet.diagnosis.leftover import history_columns, noise_floor
    from dampnet.training.pipeline import train_dataset

    m, _, _ = train_dataset(ds, decimate=8, max_epochs=epochs, holdout_voltage=None, algorithm="lm", seed=0)
    ctx = build_context(m, ds)
    ctx.notes["included"] = []
    history_columns(ctx)
    found = find_artefacts(ctx, S.folds_of(ctx), n_sur, 0, noise_floor(ctx)["rms_n"])
    row = {}
    for a in found:
        r = {"testable": bool(a.get("testable", True)), "detected": bool(a.get("detected")),
             "note": a.get("note", ""), "sentence": a.get("sentence", "") if a.get("detected") else ""}
        if a["artefact"] == "time_offset" and "offset_s" in a:
            r["stat"] = abs(a["offset_s"]) / max(a["uncertainty_s"], 1e-12)
            r["offset_ms"] = 1000 * a["offset_s"]
            r["uncertainty_ms"] = 1000 * a["uncertainty_s"]
            r["fall"] = a["static_fit_rms_n"]["fall"]
            r["constant"] = (a.get("constant_over_frequency") or {}).get("constant")
            r["all_but_constancy"] = bool(abs(a["offset_s"]) >= 0.001 and r["stat"] >= 4.0 and r["fall"] >= 0.03)
        if a["artefact"] == "run_order_drift" and "z" in a:
            r["stat"] = float(a["z"])
        if a["artefact"] == "sensor_offset":
            r["stat"] = _zero_z(ds)
            r["tests"] = [h["test_id"] for h in a.get("tests", [])]
        row[a["artefact"]] = r
    return row


def _zero_z(ds) -> float | None:
    """The displacement zeros' largest robust z over the tests (the statistic OFFSET_Z thresholds), with
    the detector's own definition of a zero; None where it has none (an older dampnet)."""
    try:
        from dampnet.diagnosis.artefacts import displacement_zero
    except ImportError:
        return None
    zs = [displacement_zero(t)["zero"] for t in ds.tests if "displacement" in t.channels]
    zs = np.asarray([z for z in zs if z is not None])
    if len(zs) < 3:
        return None
    amp = np.median([np.std(t.channels["displacement"]) for t in ds.tests])
    med = float(np.median(zs))
    spread = max(1.4826 * float(np.median(np.abs(zs - med))), 0.02 * amp)
    return float(np.max(np.abs(zs - med)) / spread)


def summarise(rows: list[dict]) -> dict:
    out = {}
    for det in DETECTORS:
        got = [r["result"].get(det) for r in rows if r["result"].get(det) is not None]
        tested = [g for g in got if g["testable"]]
        fp = [r["name"] for r in rows if r["result"].get(det, {}).get("detected")]
        stats = [g["stat"] for g in tested if g.get("stat") is not None and np.isfinite(g["stat"])]
        out[det] = {"datasets": len(got), "testable": len(tested), "false_positives": len(fp),
                    "rate": len(fp) / len(got) if got else None, "which": fp,
                    "stat_p95": float(np.percentile(stats, 95)) if stats else None,
                    "stat_max": float(np.max(stats)) if stats else None}
        if det == "time_offset":   # the other gates: |offset| >= 1 ms, the static fit's fall >= 3 %
            offs = [abs(g["offset_ms"]) for g in tested if "offset_ms" in g]
            falls = [g["fall"] for g in tested if "fall" in g]
            out[det].update(offset_ms_p95=float(np.percentile(offs, 95)) if offs else None,
                            fall_p95=float(np.percentile(falls, 95)) if falls else None,
                            all_but_constancy=[r["name"] for r in rows
                                               if r["result"].get(det, {}).get("all_but_constancy")])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--epochs", type=int, default=20)
    ap.add_argument("--surrogates", type=int, default=19)
    ap.add_argument("--quick", action="store_true", help="the shapes only (no effect-alone datasets)")
    ap.add_argument("--no-real", action="store_true", help="leave out the real datasets of ../shared/data")
    ap.add_argument("--json", default=None, help="write every number here")
    a = ap.parse_args(argv)
    rows = []
    t0 = time.perf_counter()
    for name, kind, build in panel(a.seeds, a.quick, not a.no_real):
        t = time.perf_counter()
        ds = build()
        res = run_one(ds, a.epochs, a.surrogates)
        rows.append({"name": name, "kind": kind, "tests": len(ds.tests), "result": res,
                     "seconds": round(time.perf_counter() - t, 2)})
        claims = [k for k, v in res.items() if v["detected"]]
        print(f"{name:55s} {len(ds.tests):3d} tests  {time.perf_counter() - t:5.1f} s  "
              f"claims: {', '.join(claims) or '-'}", flush=True)
    summ = summarise(rows)
    import dampnet

    print(f"\n{len(rows)} clean datasets, {time.perf_counter() - t0:.0f} s; dampnet at {Path(dampnet.__file__).parent}")
    print(f"{'detector':18s} {'datasets':>8s} {'testable':>8s} {'claims':>6s} {'rate':>6s}  95th pct of its statistic (max)")
    for det, s in summ.items():
        rate = "-" if s["rate"] is None else f"{100 * s['rate']:.0f} %"
        p95 = "-" if s["stat_p95"] is None else f"{s['stat_p95']:.2f} ({s['stat_max']:.2f})"
        print(f"{det:18s} {s['datasets']:8d} {s['testable']:8d} {s['false_positives']:6d} {rate:>6s}  {p95}")
        if det == "time_offset" and s.get("offset_ms_p95") is not None:
            print(f"{'':18s} |offset| 95th pct {s['offset_ms_p95']:.2f} ms, static fit's fall 95th pct "
                  f"{100 * s['fall_p95']:.1f} %; past every gate but the constancy over frequency: "
                  f"{len(s['all_but_constancy'])} ({', '.join(s['all_but_constancy'][:4])})")
    if a.json:
        Path(a.json).write_text(json.dumps({"rows": rows, "summary": summ, "args": vars(a)}, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
