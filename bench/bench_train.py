"""Time the training algorithms on a thesis-sized synthetic damper problem.

Default: LM on 180 tests x 500 samples (90k samples, 3 inputs, a 3-30-1
tanh MLP, 151 weights), 1 % force noise. Prints per-phase timing, the time
to reach the final accuracy (first epoch within 1 % of the final validation
MSE), and test-set NRMSE (thesis Table 3 definition; the noise floor is
~0.01 here). Usage:

  python bench/bench_train.py [--algorithm lm] [--tests 180] [--samples 500]
                              [--threads N] [--max-epochs 1000] [--seed 0]

Measured (2-core shared VM, torch 2.13.0 CPU, --threads 1 --max-epochs 400):
99 ms/epoch; validation MSE within 1 % of its final value at epoch 249,
25.5 s; test NRMSE 0.0101 (noise floor 0.0100). With 2 threads on the same
busy machine an epoch took ~600 ms (thread contention), hence fit()'s
idle-core thread choice.
"""

from __future__ import annotations

import argparse
import time

import torch

from dampnet.training import fit
from dampnet.training.synthetic import synthetic_dyno


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--algorithm", default="lm")
    ap.add_argument("--tests", type=int, default=180)
    ap.add_argument("--samples", type=int, default=500)
    ap.add_argument("--hidden", type=int, nargs="+", default=[30])
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--max-epochs", type=int, default=1000)
    ap.add_argument("--max-fail", type=int, default=6)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--noise", type=float, default=0.01)
    a = ap.parse_args()

    X, y = synthetic_dyno(a.tests, a.samples, noise=a.noise, seed=a.seed)
    t0 = time.perf_counter()
    last = [t0]

    def progress(rec):
        now = time.perf_counter()
        if rec["epoch"] % 25 == 0:
            print(f"  epoch {rec['epoch']:4d}  train {rec['train']:.3e}  val {rec['val']:.3e}  "
                  f"{now - last[0]:.2f} s/25 epochs", flush=True)
            last[0] = now

    model, info = fit(X, y, features=["velocity", "acceleration", "voltage"], hidden=a.hidden,
                      algorithm=a.algorithm, seed=a.seed, max_epochs=a.max_epochs,
                      max_fail=a.max_fail, threads=a.threads, progress=progress)
    total = time.perf_counter() - t0
    hist = info.history
    final_val = hist[info.best_epoch]["val"]
    reach = next(h for h in hist if h["val"] is not None and h["val"] <= 1.01 * final_val)
    print(f"algorithm {a.algorithm}: {len(X)} samples x {X.shape[1]} inputs, hidden {a.hidden}, "
          f"{sum(p.size for p in (model.w1, model.b1, model.w_out)) + 1 + (0 if model.w2 is None else model.w2.size + model.b2.size)} weights, "
          f"torch {torch.__version__}, {model.meta['threads']} threads")
    print(f"epochs {info.epochs} (best {info.best_epoch}), stop: {info.stop_reason}")
    print(f"training loop {info.time_s:.1f} s ({info.time_s / max(info.epochs, 1) * 1e3:.0f} ms/epoch), "
          f"fit total {total:.1f} s; final accuracy (val MSE within 1 %) reached at epoch "
          f"{reach['epoch']}, {reach['time_s']:.1f} s")
    print("NRMSE " + ", ".join(f"{k} {v:.4f}" for k, v in info.metrics.items()))
    if info.stats:
        print("stats", info.stats)


if __name__ == "__main__":
    main()
