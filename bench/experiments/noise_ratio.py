"""The model's residual against the force channel's noise where the leftover test finds nothing
(dampnet.diagnosis.verdict.NOISE_LIKE_MAX): test_diagnose_hidden's plan and training (rig seed 1),
the run order shuffled and not stated, no temperature channel; clean data, a hidden thermal effect
and hidden mount hysteresis. Prints per case the verdict's kind, the ratio and the sentence.

    python bench/experiments/noise_ratio.py     # about 2 min on 2 cores

Measured 2026-12-02: clean 5.7x (nothing_left), thermal 20.3x (nothing_left: was called noise
before NOISE_LIKE_MAX), mount hysteresis 10.6x (unknown_structure).
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "python"))

from test_diagnose_hidden import N_SUR, PLAN, TRAIN  # noqa: E402

from dampnet.diagnosis.run import diagnose  # noqa: E402
from dampnet.rig import generate  # noqa: E402
from dampnet.training.pipeline import train_dataset  # noqa: E402

for effects in ([], ["thermal"], ["mount_hysteresis"]):
    ds = generate(PLAN, effects=effects, seed=1)
    for t in ds.tests:
        t.channels.pop("temperature", None)
        t.meta.pop("run_order", None)
    order = np.random.default_rng(0).permutation(len(ds.tests))
    ds.tests[:] = [ds.tests[i] for i in order]
    model, _, _ = train_dataset(ds, **TRAIN)
    d = diagnose(model, ds, n_surrogates=N_SUR)
    left = d["leftover"]["before_effects"]
    print(f"{effects or 'clean'}: {d['finding']['kind']}, residual {left.get('model_residual_vs_noise'):.1f}x the "
          f"force channel's noise; {d['finding']['sentence'][:240]}", flush=True)
