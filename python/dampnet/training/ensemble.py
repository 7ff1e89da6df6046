"""Averaging networks: K one-hidden-layer models of the same data as one model.

Why: networks trained from different seeds on the same samples scatter around the data (the
held-out error of BR fits of the demo's data spans 2.2-2.8x the noise floor over seeds), and
their mean scatters less (bench/RESULTS.md "Inside the envelope"). The mean of K networks that
share their input and output scaling is itself one network:

  y = ((1/K) sum_k (w_out_k . h_k(x) + b_out_k) - out_ymin) / out_gain + out_offset

is a network whose hidden layer is the K hidden layers side by side (w1, b1 stacked), with output
weights w_out_k / K and output bias mean(b_out_k). So the ensemble runs wherever one network runs
(the C++ runtime, the generated header, the FMU, ONNX) as long as its width fits the runtime's
DN_MAX_HIDDEN: 384 in the Python module's build (twelve networks of 32); a C or C++ build wider
than its default 64 is built with -DDN_MAX_HIDDEN=N, which the exported FMU and firmware folder
do themselves (export.header.build_defines).

Training the same data makes the scalings equal bit for bit (mapminmax of the same samples; the
physics terms fitted by the same least squares); `average_networks` refuses models that differ
in any of them, naming the field.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from dampnet.model import MlpModel, ModelError

#: fields every member must share exactly (their scalings, inputs and physics)
SHARED = ("features", "units", "activation", "in_offset", "in_gain", "in_ymin", "out_offset", "out_gain",
          "out_ymin", "sat_lo", "sat_hi", "output", "output_unit", "terms", "feature_params")


def check_width(hidden_each: Sequence[int]) -> int:
    """The averaged layer's width; ModelError when it exceeds the runtime's DN_MAX_HIDDEN."""
    from dampnet import _core

    width, cap = int(sum(hidden_each)), int(_core.MAX_HIDDEN)
    if width > cap:
        raise ModelError(f"average: {len(hidden_each)} networks of {', '.join(map(str, hidden_each))} hidden "
                         f"neurons make a layer of {width}; dampnet's models hold at most {cap} "
                         "(average fewer or narrower networks)")
    return width


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b))
    return a == b


def average_networks(models: Sequence[MlpModel]) -> MlpModel:
    """One model computing the mean of `models`' outputs (see the module docstring); ModelError
    when a member has two hidden layers or differs from the first in a shared field."""
    models = list(models)
    if not models:
        raise ModelError("average_networks: no models")
    first = models[0]
    for k, m in enumerate(models):
        if m.w2 is not None:
            raise ModelError(f"average_networks: model {k} has two hidden layers; only one-hidden-layer "
                             "networks add up to one network")
        for name in SHARED:
            if not _same(getattr(m, name), getattr(first, name)):
                raise ModelError(f"average_networks: model {k}'s {name} differs from model 0's: members must be "
                                 "trained on the same data with the same features (their scalings equal)")
    k = len(models)
    width = check_width([int(m.w1.shape[0]) for m in models])
    # the training record of the first member, less what describes one member's own fit
    meta = {key: v for key, v in first.meta.items()
            if key not in ("seed", "split", "epochs", "best_epoch", "stop_reason", "samples", "metrics", "stats")}
    meta["hidden"] = [width]
    meta["seeds"] = [m.meta.get("seed") for m in models]
    meta["ensemble"] = {"members": k, "hidden_each": [int(m.w1.shape[0]) for m in models],
                        "member_ids": [m.model_id() for m in models],
                        "what": "the mean of the members' outputs as one network (dampnet.training.ensemble)"}
    return MlpModel(w1=np.vstack([m.w1 for m in models]), b1=np.concatenate([m.b1 for m in models]),
                    w_out=np.concatenate([m.w_out for m in models]) / k,
                    b_out=float(np.mean([m.b_out for m in models])),
                    in_offset=first.in_offset.copy(), in_gain=first.in_gain.copy(), out_offset=first.out_offset,
                    out_gain=first.out_gain, sat_lo=first.sat_lo.copy(), sat_hi=first.sat_hi.copy(),
                    features=list(first.features), units=list(first.units), activation=first.activation,
                    in_ymin=first.in_ymin, out_ymin=first.out_ymin, output=first.output,
                    output_unit=first.output_unit, terms=[dict(t) for t in first.terms],
                    feature_params=dict(first.feature_params), meta=meta)
