"""One training cell, on a worker: a dataset in, a trained model and its metrics out.

The same training as `dampnet train DATA --add EFFECT ...` and `dampnet.train`: the cell's
parameters are a dampnet.recipes.training.TrainingRequest (each added effect with its parameters
estimated from the data; restarts, average, restart_score), trained by its `plan(...).run`, which
returns the model with its envelope: the cell's model directory holds what `dampnet train`'s does.
Torch runs one thread and the restarts run one after another in the cell's process
(torch.set_num_threads(1), threads=1, workers=1): N workers use N cores, and a cell's result does
not depend on the machine's core count.
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
    """{"metrics": the row's metrics, "model": model.json's dict, "metrics_json": metrics.json's,
    "envelope": the model's training envelope (the model directory's envelope.npz / .json)}."""
    import torch

    from dampnet.recipes.training import plan

    torch.set_num_threads(1)
    ds = dataset(params, inputs["dataset"])
    trained = plan(ds, request(params)).run(threads=1, workers=1)
    metrics = trained.metrics
    return {"metrics": row_metrics(trained.model, trained.info, metrics), "model": trained.model.to_dict(),
            "metrics_json": metrics, "envelope": trained.envelope}


def request(params: dict[str, Any]):
    """The cell's dampnet.recipes.training.TrainingRequest: its value of every option with a sweep
    key (dampnet.training.settings.OPTIONS; features 'default' is None)."""
    from dampnet.recipes.training import TrainingRequest
    from dampnet.training.settings import OPTIONS

    given = {row.name: params[row.name] for row in OPTIONS.values() if row.sweep and row.request}
    given["features"] = given["features"] or None
    given["restart_score"] = given["restart_score"] or OPTIONS["restart_score"].default
    return TrainingRequest.of(**given)


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
        "algorithm_used": model.meta.get("algorithm", info.algorithm),
        "train_time_s": info.time_s,
        "n_inputs": model.n_inputs,
        "features_used": ",".join(model.features),
        "model_id": model.model_id(),
    }
