"""Beyond the trained velocities (issue 54 item 4): does a hybrid model with the valve term follow
the valve law where a network-only model follows tanh?

The rig (its truth damper as it is, shim stacks with their blow-off knees) runs two plans of 1-inch
sines at the thesis's 15 control levels: TRAIN at 0.25-1.75 Hz (peak speed up to 0.28 m/s) and
BEYOND at 3.25, 4 and 5 Hz (0.52, 0.64 and 0.80 m/s). Each model is trained on TRAIN only
(`dampnet.train`, algorithm 'auto', restarts 1, one seed each) and scored on BEYOND against the
rig's noise-free force (truth_channels): RMSE [N] over the samples faster than anything trained on
(|v| above TRAIN's largest speed), and over all of BEYOND, for

  network     the default features, no term
  hybrid      the same with a free valve term (terms=[{"kind": "valve"}]: bleed + blow-off, fitted
              first by nonlinear least squares, the network trained on what it leaves)

    python bench/experiments/valve_extrapolation.py                 # seeds 0-2, ~10 min on 2 cores
    python bench/experiments/valve_extrapolation.py --seeds 0 --json out.json --plot beyond.png

One line per (seed, model) on stdout, then the medians; --json writes every row (atomically);
--plot draws the first seed's models against the noise-free force at 5 Hz, 0, 2.25 and 5 V.
"""

from __future__ import annotations

import argparse
import io
import json
import statistics
import sys
import time

import numpy as np

from dampnet.rig.plans import Plan
from dampnet.rig.truth import TABLE2_VOLTAGE_V, INCH

TRAIN_HZ = [0.25 * k for k in range(1, 8)]       # 0.25 .. 1.75 Hz: |v| <= 0.28 m/s
BEYOND_HZ = [3.25, 4.0, 5.0]                      # 0.52, 0.64, 0.80 m/s
MODELS = {"network": [], "hybrid": [{"kind": "valve"}]}


def plans() -> tuple[Plan, Plan]:
    volts = [float(v) for v in TABLE2_VOLTAGE_V]
    common = dict(amplitudes_m=[INCH], voltages_v=volts, samples=5000, min_cycles=2.0)
    return Plan("valve-train", frequencies_hz=TRAIN_HZ, **common), Plan("valve-beyond", frequencies_hz=BEYOND_HZ, **common)


def beyond_errors(model, tests, v_max: float) -> dict:
    """RMSE [N] against the noise-free force over |v| > v_max, and over every sample; the worst test's."""
    from dampnet.predict import predict_force

    e_out, e_all, per_test = [], [], {}
    for t in tests:
        e = predict_force(model, t) - t.channels["true_force"]
        fast = np.abs(t.channels["velocity"]) > v_max
        e_out.append(e[fast])
        e_all.append(e)
        per_test[t.test_id] = float(np.sqrt(np.mean(e[fast] ** 2))) if fast.any() else None
    rms = lambda parts: float(np.sqrt(np.mean(np.concatenate(parts) ** 2)))  # noqa: E731
    return {"rmse_beyond_n": rms(e_out), "rmse_all_n": rms(e_all),
            "share_beyond": float(sum(p.size for p in e_out) / sum(p.size for p in e_all)),
            "worst_test_rmse_beyond_n": max(v for v in per_test.values() if v is not None)}


def plot(models: dict, tests, v_max: float, path: str) -> None:
    """Force against velocity at 5 Hz and 0, 2.25 and 5 V: the noise-free force and each model."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dampnet.outputs import atomic_write_bytes
    from dampnet.predict import predict_force

    volts = (0.0, 2.25, 5.0)
    fig, axes = plt.subplots(1, len(volts), figsize=(13, 4.2), sharey=True)
    for ax, u in zip(axes, volts):
        t = min((t for t in tests if t.frequency_hz == max(BEYOND_HZ)),
                key=lambda t: abs(float(t.control_nominal) - u))
        v = t.channels["velocity"]
        ax.axvspan(-v_max, v_max, color="0.92", label="trained speeds")
        ax.plot(v, t.channels["true_force"] / 1000, "k", lw=2.5, label="rig (noise-free)")
        for (name, model), style in zip(models.items(), ("C3--", "C0-")):
            ax.plot(v, predict_force(model, t) / 1000, style, lw=1.2, label=name)
        ax.set_title(f"{t.frequency_hz:g} Hz, {float(t.control_nominal):g} V")
        ax.set_xlabel("velocity [m/s]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("force [kN]")
    axes[0].legend(fontsize=8, loc="upper left")
    fig.suptitle(f"Beyond the trained speeds (|v| <= {v_max:.2f} m/s): the network alone against the hybrid with the valve term")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    ap.add_argument("--json", help="write every row here")
    ap.add_argument("--plot", help="write the force-velocity figure here (PNG)")
    args = ap.parse_args(argv)
    import dampnet
    from dampnet.rig import generate

    train_plan, beyond_plan = plans()
    train_ds = generate(train_plan, seed=0)
    beyond = generate(beyond_plan, seed=1, truth_channels=True).tests
    v_max = max(float(np.max(np.abs(t.channels["velocity"]))) for t in train_ds.tests)
    v_top = max(float(np.max(np.abs(t.channels["velocity"]))) for t in beyond)
    print(f"trained up to |v| = {v_max:.3f} m/s ({len(train_ds.tests)} tests); scored to {v_top:.3f} m/s "
          f"({len(beyond)} tests)", flush=True)
    rows, first = [], {}
    for seed in args.seeds:
        for name in args.models:
            t0 = time.perf_counter()
            trained = dampnet.train(train_ds, seed=seed, holdout_voltage=None, algorithm="auto", restarts=1,
                                    terms=MODELS[name])
            row = {"model": name, "seed": seed, "train_s": round(time.perf_counter() - t0, 1),
                   "terms": trained.model.terms, **beyond_errors(trained.model, beyond, v_max)}
            rows.append(row)
            if seed == args.seeds[0]:
                first[name] = trained.model
            print(f"seed {seed} {name:8s}: beyond the envelope RMSE {row['rmse_beyond_n']:7.1f} N "
                  f"(worst test {row['worst_test_rmse_beyond_n']:.1f} N, {100 * row['share_beyond']:.0f} % of the "
                  f"samples), all of BEYOND {row['rmse_all_n']:.1f} N ({row['train_s']:.0f} s)", flush=True)
    for name in args.models:
        mine = [r for r in rows if r["model"] == name]
        print(f"median {name:8s}: beyond {statistics.median(r['rmse_beyond_n'] for r in mine):.1f} N, "
              f"all {statistics.median(r['rmse_all_n'] for r in mine):.1f} N")
    if args.plot:
        plot(first, beyond, v_max, args.plot)
    if args.json:
        from dampnet.outputs import atomic_write_text
        atomic_write_text(args.json, json.dumps({"v_train_max_m_s": v_max, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
