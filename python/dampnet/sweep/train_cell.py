"""One training cell, on a worker: a dataset in, a trained model and its metrics out.

The same steps as `dampnet train DATA --add EFFECT ...`: each added effect goes through
`dampnet.training.pipeline.apply_additions` with its parameters estimated from the data
(dampnet.diagnosis.estimate), then `train_dataset` and `model_metrics`. Torch runs one thread
(torch.set_num_threads(1) and threads=1): N workers use N cores, and a cell's result does not
depend on the machine's core count.
"""

from __future__ import annotations

import copy
from typing import Any


def dataset(params: dict[str, Any], value: Any):
    """The cell's dataset: generated on the rig (rig:PLAN, with data_seed and rig_effects), or a
    private copy of the loaded / shipped one (training adds channels to it)."""
    from dampnet.sweep.inputs import InputRef

    if isinstance(value, InputRef):          # generated: rig:PLAN
        from dampnet.rig import generate

        plan = value.payload if value.payload is not None else value.text[4:]
        return generate(plan, effects=params["rig_effects"] or (), seed=params["data_seed"])
    return copy.deepcopy(value)


def run(params: dict[str, Any], inputs: dict[str, Any]) -> dict[str, Any]:
    """{"metrics": the row's metrics, "model": model.json's dict, "metrics_json": metrics.json's}."""
    import torch

    from dampnet.diagnosis.estimate import estimate_parameters
    from dampnet.training.pipeline import apply_additions, model_metrics, train_dataset

    torch.set_num_threads(1)
    ds = dataset(params, inputs["dataset"])
    kw: dict[str, Any] = {}
    if params["features"]:
        kw["features"] = list(params["features"])
    for effect in params["add"]:
        kw, _ = apply_additions(kw, ds, effect, params=estimate_parameters(effect, ds))
    model, info, split = train_dataset(
        ds, algorithm=params["algorithm"], hidden=tuple(params["hidden"]), activation=params["activation"],
        holdout_voltage=params["holdout_voltage"], decimate=params["decimate"], seed=params["seed"],
        max_epochs=params["max_epochs"], max_fail=params["max_fail"], threads=1, **kw)
    metrics = model_metrics(model, info, split)
    return {"metrics": row_metrics(model, info, metrics), "model": model.to_dict(), "metrics_json": metrics}


def row_metrics(model, info, metrics: dict[str, Any]) -> dict[str, Any]:
    """The table's columns of a trained model (NRMSE: RMSE / the force range; errors in N; s)."""
    hold = metrics.get("holdout", {}).get("overall", {})
    lookup = metrics.get("holdout_lookup", {}).get("overall", {})
    return {
        "holdout_nrmse": hold.get("nrmse"),
        "holdout_rmse_n": hold.get("rmse_n"),
        "holdout_max_abs_error_n": hold.get("max_abs_error_n"),
        "lookup_holdout_nrmse": lookup.get("nrmse"),
        "train_nrmse": info.metrics.get("train"),
        "val_nrmse": info.metrics.get("val"),
        "test_nrmse": info.metrics.get("test"),
        "noise_floor_nrmse": metrics.get("noise_floor", {}).get("nrmse_range"),
        "epochs": info.epochs,
        "stop_reason": info.stop_reason,
        "train_time_s": info.time_s,
        "n_inputs": model.n_inputs,
        "features_used": ",".join(model.features),
        "model_id": model.model_id(),
    }
