#!/usr/bin/env python3
"""The quarter car and the full car with a stateful neural damper, before/after (issue 30, "Must
not move": the loop references, where the demo does not reach: the demo's models use no damper
state).

Usage: python bench/compare_loop_states.py --before /work/wt-before --after /work/main [--json OUT]

Runs the same script in each tree's .venv (python/env.sh has built it): a random MLP
(seed 11, 8 tanh neurons) on velocity, velocity_lag, friction_state, voltage_lag, voltage
(velocity_lag_tau_s 4 ms, friction_presliding_m 0.5 mm, control_lag_tau_s 8 ms), on a two-tone road (3 s at 0.2 ms) with on-off skyhook,
through the quarter car (_core loop: per_stage and per_step damper evaluation) and the full car
(_core.FullCar, per_step and per_stage; each corner its own road phase). Every output array is
compared by name, the state matrices column by column by their state names (the column order may
differ between the trees). Prints per column: bit-identical or the max relative difference
(|a-b| / max|a|,|b| over the samples, floor 1e-300) and max ulps, and the first differing step.
Exit 0 always (2 when a tree fails to run).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

_RUN = r"""
import sys
import numpy as np
from dampnet import _core
from dampnet.model import MlpModel
from dampnet.sim.quarter_car.loop import QuarterCar, STATE_NAMES, damper_from_model

FEATURES = ["velocity", "velocity_lag", "friction_state", "voltage_lag", "voltage"]
RANGES = {"velocity": (-2.0, 2.0), "velocity_lag": (-2.0, 2.0), "friction_state": (-1.0, 1.0),
          "voltage_lag": (0.0, 5.0), "voltage": (0.0, 5.0)}
UNITS = {"velocity": "m/s", "velocity_lag": "m/s", "friction_state": "1", "voltage_lag": "V", "voltage": "V"}
PARAMS = {"velocity_lag_tau_s": 0.004, "friction_presliding_m": 5e-4, "control_lag_tau_s": 0.008}
DT = 2e-4
rng = np.random.default_rng(11)
n, h, fr = len(FEATURES), 8, 800.0
lo = np.array([RANGES[f][0] for f in FEATURES]); hi = np.array([RANGES[f][1] for f in FEATURES])
model = MlpModel(w1=rng.normal(0, 1.0, (h, n)), b1=rng.normal(0, 0.5, h), w_out=rng.normal(0, 1.0, h) / np.sqrt(h),
                 b_out=0.05, in_offset=lo, in_gain=2.0 / (hi - lo), out_offset=-fr / 2, out_gain=2.0 / fr,
                 sat_lo=lo, sat_hi=hi, features=FEATURES, units=[UNITS[f] for f in FEATURES], activation="tanh",
                 terms=[], feature_params=PARAMS)
N = 15000
t = np.arange(N) * DT
z = 0.02 * np.sin(2 * np.pi * 1.3 * t) + 0.004 * np.sin(2 * np.pi * 11.0 * t)
v = 0.02 * 2 * np.pi * 1.3 * np.cos(2 * np.pi * 1.3 * t) + 0.004 * 2 * np.pi * 11.0 * np.cos(2 * np.pi * 11.0 * t)
ctrl = {"kind": "skyhook_onoff"}
out = {}
for ev in ("per_stage", "per_step"):
    car = QuarterCar(damper_from_model(model), vehicle={"dt": DT, "damper_eval": ev}, controller=ctrl)
    res = car.simulate(z, v)
    for k, a in res.items():
        a = np.asarray(a)
        if k == "state" and a.ndim == 2:
            for j, name in enumerate(STATE_NAMES):
                out[f"quarter_{ev}.state.{name}"] = a[:, j]
        elif a.dtype.kind in "fiu" and a.size:
            out[f"quarter_{ev}.{k}"] = a
names = list(_core.FULLCAR_STATE_NAMES)
ph = [0.0, 0.9, 1.8, 2.7]
zr = np.stack([0.02 * np.sin(2 * np.pi * 1.3 * t + p) + 0.004 * np.sin(2 * np.pi * 11.0 * t + 2 * p) for p in ph], 1)
vr = np.stack([0.02 * 2 * np.pi * 1.3 * np.cos(2 * np.pi * 1.3 * t + p)
               + 0.004 * 2 * np.pi * 11.0 * np.cos(2 * np.pi * 11.0 * t + 2 * p) for p in ph], 1)
steer = 0.03 * np.sin(2 * np.pi * 0.5 * t)
for ev in ("per_step", "per_stage"):
    params = {"damper_eval": ev, "accel_feature": "linear", "dt": DT}
    dampers = [damper_from_model(model) for _ in range(4)]
    car = _core.FullCar(_core.FullCarModel(dampers, params, ctrl))
    res = car.simulate(zr, vr, steer=steer)
    for k, a in res.items():
        a = np.asarray(a)
        if k == "state" and a.ndim == 2 and a.shape[1] == len(names):
            for j, name in enumerate(names):
                out[f"fullcar_{ev}.state.{name}"] = a[:, j]
        elif a.dtype.kind in "fiu" and a.size:
            out[f"fullcar_{ev}.{k}"] = a
np.savez(sys.argv[1], **out)
"""


def run_tree(tree: Path, out: Path) -> dict:
    py = tree / ".venv" / "bin" / "python"
    proc = subprocess.run([str(py), "-c", _RUN, str(out)], capture_output=True, text=True, cwd=tree)
    if proc.returncode != 0:
        raise RuntimeError(f"{tree}: {proc.stderr[-3000:]}")
    with np.load(out) as z:
        return {k: z[k] for k in z.files}


def _ulps(a: np.ndarray, b: np.ndarray) -> int:
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    ia, ib = a.view(np.int64), b.view(np.int64)
    ia = np.where(ia < 0, -(ia & 0x7FFFFFFFFFFFFFFF), ia)
    ib = np.where(ib < 0, -(ib & 0x7FFFFFFFFFFFFFFF), ib)
    ok = np.isfinite(a) & np.isfinite(b)
    return int(np.max(np.abs(ia[ok] - ib[ok]), initial=0))


def compare(b: dict, a: dict) -> list[dict]:
    rows = []
    for k in sorted(set(b) | set(a)):
        if k not in b or k not in a:
            rows.append({"name": k, "only": "after" if k in a else "before"})
            continue
        x, y = np.asarray(b[k]), np.asarray(a[k])
        if x.shape != y.shape:
            rows.append({"name": k, "shape": [list(x.shape), list(y.shape)]})
            continue
        same = np.array_equal(x, y, equal_nan=x.dtype.kind == "f")
        row = {"name": k, "identical": bool(same)}
        if not same:
            xf, yf = x.astype(np.float64).ravel(), y.astype(np.float64).ravel()
            den = np.maximum(np.maximum(np.abs(xf), np.abs(yf)), 1e-300)
            rel = np.abs(xf - yf) / den
            diff = np.flatnonzero(xf != yf)
            row.update(max_rel=float(np.nanmax(rel)), max_abs=float(np.nanmax(np.abs(xf - yf))),
                       ulps=_ulps(xf, yf), n_diff=int(diff.size), first_diff=int(diff[0]) if diff.size else None,
                       n=int(xf.size))
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--after", type=Path, required=True)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            b = run_tree(args.before.resolve(), Path(tmp) / "before.npz")
            a = run_tree(args.after.resolve(), Path(tmp) / "after.npz")
        except RuntimeError as e:
            print(f"compare_loop_states: {e}", file=sys.stderr)
            return 2
    rows = compare(b, a)
    same = [r for r in rows if r.get("identical")]
    moved = [r for r in rows if r.get("identical") is False]
    other = [r for r in rows if "identical" not in r]
    print(f"arrays compared: {len(same) + len(moved)}; bit-identical: {len(same)}; moved: {len(moved)}; "
          f"unmatched: {len(other)}")
    if moved:
        print(f"\n{'array':60s} {'max rel':>10s} {'max abs':>10s} {'ulps':>12s} {'n diff':>8s} {'first':>6s}")
        for r in moved:
            print(f"{r['name']:60s} {r['max_rel']:10.3e} {r['max_abs']:10.3e} {r['ulps']:12d} "
                  f"{r['n_diff']:8d} {r['first_diff']!s:>6s}")
    for r in other:
        print(f"unmatched: {r}")
    print("\nbit-identical: " + ", ".join(r["name"] for r in same))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
