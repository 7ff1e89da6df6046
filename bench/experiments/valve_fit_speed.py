"""The valve term's nonlinear fit (dampnet.terms._fit_valve) on the rig's quick plan, every sample
(160,011), with and without a gas spring's columns projected out: its time and its parameters
(to compare two trees' fits: equal parameters, bit for bit, and the time).

    python bench/experiments/valve_fit_speed.py [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main(argv=None) -> int:
    from dampnet import terms
    from dampnet.rig import generate

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", help="write {case: parameters} here")
    a = ap.parse_args(argv)
    out = {}
    for effects in (["gas_spring"], []):
        ds = generate("quick", effects=effects, seed=0, progress=False)
        v, u, f, x = (np.concatenate([t.channels[c] if c != "u" else t.control for t in ds.tests])
                      for c in ("velocity", "u", "force", "displacement"))
        for with_poly in (False, True):
            A = np.stack([np.ones_like(x), x, x * x, x ** 3], 1) if with_poly else None
            t0 = time.perf_counter()
            p = terms._fit_valve(v, u, f, A)
            key = f"quick-{'+'.join(effects) or 'none'}-{'poly' if with_poly else 'alone'}"
            out[key] = p
            print(f"{key}: {time.perf_counter() - t0:.1f} s, {v.size} samples, parameters {p}", flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
