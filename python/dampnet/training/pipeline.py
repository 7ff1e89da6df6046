"""Dataset in, trained model out: the pipeline that `dampnet train`, the demo and the diagnosis share.

  train_dataset(ds, features=..., algorithm=..., ...) -> (model, info, split)
  model_metrics(model, info, split) -> the metrics.json dict
  apply_additions(settings, ds, effect, diagnosis=...) -> (settings, additions): the
      diagnose -> add effect -> retrain step, used by `dampnet train --add` and the demo

What train_dataset does, in order (the thesis's chapter 4 data handling):
 1. Acceleration, if a feature needs it and the data lack it: derived at the full
    sampling rate (`dampnet.data.add_acceleration`: by default the zero-phase derivative), before
    any decimation.
 2. Hold-out: every test at `holdout_voltage` (default 2.25 V, as the thesis) and
    the tests named in `holdout_tests` are set aside for independent evaluation.
    None/None holds nothing out.
 3. Decimation of the training tests (every `decimate`-th sample; None = to about
    dampnet.data.preprocess.DECIMATE_TARGET_HZ = 200 Hz, i.e. 25 at the dyno's 5 kHz, or to
    about DECIMATE_LARGE_HZ = 100 Hz when 200 Hz would leave more than DECIMATE_MAX_ROWS = 50,000
    training rows, as on the thesis plan). The highest test frequency is 3 Hz, so 100 Hz keeps 33
    samples per cycle and 200 Hz 67, more than the force waveform needs; the derived acceleration
    is already smoothed over 20 ms (100 samples) so decimating it loses nothing. Measured on the
    full thesis plan (bench/LOG.md "The thesis plan at 100 Hz"): with the estimated force at
    rest LM runs up to its 1,000 epochs either way, and at 100 Hz takes half the time to a held-out
    error no worse (rest points at 0 N it stopped early, and 200 Hz was the better: 0.0037 against
    0.0042); factor 1 would be 25x the work.
    Features are computed at the full rate and then decimated: derived features
    with a state (velocity_lag, voltage_lag, friction_state) are only the
    quantities the runtime's loop computes when sampled finely.
 4. Physics terms (hybrid model), if any: their parameters are fitted first
    (fit_terms) and the network learns the residual force minus the terms.
 5. `dampnet.training.fit`: mapminmax scaling, random 70/15/15 split with early
    stopping, rest points (at the estimated force at rest), saturation limits from the training range.
 6. With restarts=N > 1, steps 4-5 run N times from different seeds in worker processes
    and the model that fits the training control levels best and strays least between them is
    kept (`dampnet.training.restarts`; `dampnet train` runs up to 6 by default).
 7. With valve "auto" (`dampnet train`'s default), steps 4-6 run twice, without and with a free
    valve term (bleed and blow-off per direction) under the network, and the hybrid is kept when
    its validation error is lower by valve_choice.MIN_GAIN (`dampnet.training.valve_choice`; "on"
    and "off" train one way).

Steps 1-3 are `prepare_training` (a `Prepared`), steps 4-5 `fit_prepared`.

Features and terms are data: a feature is a name in the registry
(`dampnet.features.FEATURES`), a term a dict {"kind": ..., "params": [...]}
(`dampnet.terms`); nothing here branches on their names.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from dampnet.data import DataError, Dataset, add_acceleration, decimate as _decimate
from dampnet.data import holdout_split
from dampnet.data.preprocess import HOLDOUT_HINT, acceleration_key, acceleration_record, auto_decimate
from dampnet.data.types import RIG_GENERATOR
from dampnet.effects import additions as effect_additions, effect as catalogue_effect
from dampnet.evaluation.lookup import fit_lookup
from dampnet.evaluation.metrics import evaluate_model
from dampnet.evaluation.structure import structure
from dampnet.features import default_features, feature_matrix
from dampnet.model import MlpModel, ModelError
from dampnet.predict import predict_force
from dampnet.rig import noise_floor_nrmse, noise_floor_rmse_n
from dampnet.terms import fit_terms, terms_force
from dampnet.training.fitting import fit_checked
from dampnet.training.metrics import nrmse
from dampnet.training.request import TrainingRequest
from dampnet.training.valve_choice import (keep_hybrid, record as valve_record, validation_nrmse,
                                            too_few_levels, why_not_auto, with_valve)
from dampnet.training.settings import FIT_OPTIONS, OPTIONS, check_algorithm, option, train_settings

# every option's default and range: the options table, dampnet.training.settings.OPTIONS; the
# algorithm settings train_dataset uses unless `settings` overrides them: its TRAIN_DEFAULTS


@dataclass
class Split:
    """Which data trained the model and which were held out (full-rate tests, acceleration added)."""

    train: Dataset
    holdout: Dataset | None
    holdout_voltage: float | None
    holdout_tests: list[str]
    decimate: int
    train_used: Dataset | None = None  # the decimated training tests fit() saw
    notes: dict[str, Any] = field(default_factory=dict)

    @property
    def holdout_ids(self) -> list[str]:
        return [] if self.holdout is None else self.holdout.test_ids



# -- training -----------------------------------------------------------------------

def _data_provenance(ds: Dataset, split: Split, features, window) -> dict[str, Any]:
    d: dict[str, Any] = {
        "source": ds.source,
        "n_tests": len(ds.tests),
        "train_tests": split.train.test_ids,
        "holdout_tests": split.holdout_ids,
        "holdout_voltage": split.holdout_voltage,
        "decimate": split.decimate,
        "acceleration_window_s": window if "acceleration" in features else None,
    }
    if "acceleration" in features and any(t.meta.get("acceleration_derived") for t in ds.tests):
        d["acceleration"] = acceleration_record(ds, window)     # derived here: how, and its bandwidth
    if "velocity_derived" in ds.meta:   # lab files without a velocity channel (dampnet.data.lab.assemble)
        d["velocity_derived"] = ds.meta["velocity_derived"]
    rig = ds.meta
    if rig.get("generator") == RIG_GENERATOR:
        d["rig"] = {"plan": rig.get("plan", {}).get("name"), "effects": sorted(rig.get("effects", {})),
                    "seed": rig.get("seed")}
    return d


def train_dataset(ds: Dataset, features: Sequence[str] | None = None, algorithm: str | None = None, *,
                  request: TrainingRequest | None = None, progress: Callable[[dict], Any] | None = None,
                  threads: int | None = None, init: MlpModel | None = None, workers: int | None = None,
                  **options: Any) -> tuple[MlpModel, Any, Split]:
    """Train a (hybrid) MLP damper model on a dataset; see the module docstring for the steps.

    The training is `request` (a dampnet.training.request.TrainingRequest), or one made of
    `features`, `algorithm` and the keyword `options` (hidden, activation, holdout_voltage,
    holdout_tests, decimate, terms, feature_params, seed, max_epochs, max_fail, settings,
    acceleration_window, restarts, restart_score, average, control_prior, monotone_prior,
    rest_target: the options table's names, dampnet.training.settings.OPTIONS, each its
    default unless given); its algorithm and restarts named (no "auto": dampnet.recipes.training.plan
    resolves those with the data). How the work runs is not part of it: `progress`, `threads`,
    `workers`, `init` (a warm start, one training).

    Returns (model, info, split): `info` is dampnet.train.TrainInfo (its subset indices
    refer to the decimated training samples, split.train_used), `split` says which
    tests trained and which were held out. Raises DataError for unusable data
    (nothing to hold out, missing feature, no training tests) and ModelError for bad terms.

    `restarts` > 1 trains that many times from different seeds (`seed` first) and keeps the
    model scored best on the training control levels by `restart_score` (dampnet.training.restarts.SCORES:
    "combined", "interpolation" or "lolo"), in `workers` processes (None: the local
    cores) with one torch thread each; model.meta["restarts"] records every restart. See
    dampnet.training.restarts for the scores and why the default is what it is; `progress`
    then receives one record per finished fit instead of one per epoch. restarts=1 (the
    default) is exactly the single training it always was. `average` > 1 keeps the best `average`
    restarts instead and averages them into one network (dampnet.training.restarts, step 4).
    `control_prior` weighs the prior that the force between the training control levels follows
    the natural cubic spline through theirs, a straight line for two (dampnet.training.control_prior;
    0: off); `monotone_prior` the prior that the force rises with velocity
    (dampnet.training.monotone_prior; 0: off); `rest_target` the rest points' force, "estimated"
    (the default), "zero" (the thesis's 0 N) or "none" (no rest points; dampnet.training.rest_points).
    model.meta["request"] records the request (TrainingRequest.recorded).
    """
    from dampnet.training.restarts import FULL_FIT_SCORES, check_average, check_restarts, train_restarts

    req = _request(request, features, algorithm, options)
    # every option and setting before any work (one-line errors naming it and its range), unless
    # the request is checked already (dampnet.recipes.training.plan) and was not changed since
    check_algorithm(req.algorithm)
    req = req if req.checked else req.check()
    restarts = check_restarts(req.restarts, workers, req.restart_score)
    option("threads", threads)
    check_average(req.average, restarts, req.hidden, req.restart_score)
    if restarts > 1 and init is not None:
        raise ValueError("init: a warm start is one training; use restarts=1 with init")
    def fit(prep: Prepared):
        if restarts == 1:
            return fit_prepared(prep, req.seed, progress=progress, threads=threads, init=init)
        if req.restart_score in FULL_FIT_SCORES and any(t.get("params") is None for t in prep.terms):
            # every full fit fits the free terms on the same rows, to the same parameters: once here
            # (a valve's fit takes seconds), not in each restart
            prep = replace(prep, terms=_fitted_terms(prep.terms, prep.xd, prep.v, prep.u, prep.force))
        # data errors (a feature or force beyond MAX_TRAINING_MAGNITUDE) before any worker starts
        _check_magnitudes(prep.X, prep.force if not prep.terms else np.zeros(0), prep.features)
        return train_restarts(prep, fit_prepared, restarts, req.seed, workers=workers, score=req.restart_score,
                              progress=progress, average=req.average)

    if req.valve == "on":
        prep = prepare_training(ds, request=req.replace(terms=with_valve(req.terms)).check())
        model, info = fit(prep)
    elif req.valve == "auto":
        model, info, prep = _fit_valve_auto(ds, req, fit, init is not None)
    else:
        prep = prepare_training(ds, request=req)
        model, info = fit(prep)
    model.meta["request"] = req.recorded()
    return model, info, prep.split


def _fit_valve_auto(ds: Dataset, req: TrainingRequest, fit: Callable, warm_start: bool):
    """valve "auto" (dampnet.training.valve_choice): the request trained without and with a free
    valve term, same seed, split and restarts; the hybrid kept by valve_choice.keep_hybrid, the
    choice in model.meta["valve"]. (model, info, the kept variant's Prepared)."""
    import time

    # every test, the held-out ones too: a hybrid's evaluation reads their displacement as well
    why = why_not_auto(req.terms, ds.tests, warm_start)
    if why is not None:
        prep = prepare_training(ds, request=req)
        model, info = fit(prep)
        model.meta["valve"] = valve_record(None, None, False, why=why)
        return model, info, prep
    prep_h = prepare_training(ds, request=req.replace(terms=with_valve(req.terms)).check())
    # the network alone on the same rows: its samples without what only terms need
    prep_n = replace(prep_h, terms=[dict(t) for t in req.terms], request=req,
                     **({} if req.terms else {"xd": None, "v": None, "u": None}))
    few = too_few_levels(prep_h.split.train.tests)
    if few is not None:   # the control gain would be fitted with no level between the others
        model, info = fit(prep_n)
        model.meta["valve"] = valve_record(None, None, False, why=few)
        return model, info, prep_n
    t0 = time.perf_counter()
    model_n, info_n = fit(prep_n)
    t1 = time.perf_counter()
    try:
        model_h, info_h = fit(prep_h)
    except ModelError as e:  # e.g. the valve's fit needs samples in both directions
        model_n.meta["valve"] = valve_record(validation_nrmse(model_n, info_n), None, False, failed=str(e))
        return model_n, info_n, prep_n
    t2 = time.perf_counter()
    without, with_ = validation_nrmse(model_n, info_n), validation_nrmse(model_h, info_h)
    used = keep_hybrid(without, with_)
    model, info, prep = (model_h, info_h, prep_h) if used else (model_n, info_n, prep_n)
    model.meta["valve"] = valve_record(without, with_, used, times={"without": t1 - t0, "with": t2 - t1})
    return model, info, prep


def _request(request: TrainingRequest | None, features, algorithm, options: dict[str, Any]) -> TrainingRequest:
    """`request`, or the request of the keyword options (not both)."""
    if request is None:
        given = {**({} if features is None else {"features": features}),
                 **({} if algorithm is None else {"algorithm": algorithm}), **options}
        return TrainingRequest(**given)
    if options or features is not None or algorithm is not None:
        raise TypeError("give the options either as a request or as keywords, not both")
    return request


@dataclass
class Prepared:
    """The training samples train_dataset fits, one row per decimated sample, before any fit.

    `level` is each row's test's nominal control (NaN for a test without one): the control
    levels the restarts' scores interpolate between (dampnet.training.restarts). `terms` are
    the terms as requested (their free parameters are fitted with each fit, on its rows).
    """

    X: np.ndarray
    force: np.ndarray  # measured force [N]
    level: np.ndarray
    features: list[str]
    control_name: str
    terms: list[dict[str, Any]]
    xd: np.ndarray | None  # displacement [m], velocity [m/s], control: what the terms need
    v: np.ndarray | None
    u: np.ndarray | None
    feature_params: dict[str, float]
    request: TrainingRequest  # checked: fit()'s options (hidden, activation, algorithm, ...) are its
    provenance: dict[str, Any]
    split: Split | None = None  # not shipped to restart workers (it holds the full-rate tests)

    def lean(self) -> "Prepared":
        """A copy without the split: what a restart worker needs."""
        return Prepared(**{**self.__dict__, "split": None})


def prepare_training(ds: Dataset, features: Sequence[str] | None = None, algorithm: str | None = None, *,
                     request: TrainingRequest | None = None, **options: Any) -> Prepared:
    """Steps 1-3 of the module docstring: acceleration, hold-out, decimation, the feature matrix;
    of `request` (checked), or of the keyword options as train_dataset takes them (checked here)."""
    req = _request(request, features, algorithm, options)
    if not req.checked:
        req = req.check()
    features, holdout_voltage, holdout_tests = req.features, req.holdout_voltage, req.holdout_tests
    decimate, terms, feature_params, acceleration_window = req.decimate, req.terms, req.feature_params, \
        req.acceleration_window
    if not ds.tests:
        raise DataError(f"{ds.source}: no tests")
    features = list(features) if features else default_features(ds)
    if len(set(features)) != len(features):
        raise DataError(f"features: each feature once, got {features}")
    window = acceleration_window         # None: the zero-phase derivative (dampnet.data.derivative)
    if "acceleration" in features:
        for t in ds.tests:
            # derive it when missing, and again when an earlier training derived it (in place, as
            # add_acceleration does) another way; a measured channel has no such mark
            derived = t.meta.get("acceleration_derived")
            if "acceleration" not in t.channels or (derived is not None and derived != acceleration_key(t, window)):
                add_acceleration(t, window)
    if holdout_voltage is None and not holdout_tests:
        train, hold = ds, None
    else:
        try:
            train, hold = holdout_split(ds, holdout_voltage, list(holdout_tests or []))
        except ValueError as e:
            raise DataError(f"{e} ({HOLDOUT_HINT})") from None
    if not train.tests:
        raise DataError("every test is held out: nothing left to train on")
    factor = auto_decimate(train) if decimate is None else int(decimate)
    used = _decimate(train, factor) if factor > 1 else train
    # Features at the full sample rate, then decimated: a derived feature with a state (a lag of a
    # few ms, the friction state) computed on decimated samples would be a different quantity.
    X = np.concatenate([feature_matrix([t], features, feature_params, window)[::factor]
                        for t in train.tests])
    y = np.concatenate([t.channels["force"] for t in used.tests])
    level = np.concatenate([np.full(len(t), np.nan if t.control_nominal is None else float(t.control_nominal))
                            for t in used.tests])
    terms = [dict(t) for t in terms or ()]
    xd = v = u = None
    if terms:
        for t in used.tests:
            if "displacement" not in t.channels:
                raise DataError(f"test {t.test_id}: physics terms need a displacement channel")
        xd = np.concatenate([t.channels["displacement"] for t in used.tests])
        v = np.concatenate([t.channels["velocity"] for t in used.tests])
        u = np.concatenate([t.control for t in used.tests])
    split = Split(train=train, holdout=hold, holdout_voltage=holdout_voltage,
                  holdout_tests=list(holdout_tests or []), decimate=factor, train_used=used)
    return Prepared(X=X, force=y, level=level, features=features,
                    control_name=train.tests[0].control_name, terms=terms, xd=xd, v=v, u=u,
                    feature_params=dict(feature_params or {}),
                    request=req,
                    provenance=_data_provenance(ds, split, features, window), split=split)


def fit_prepared(prep: Prepared, seed: int, *, rows: np.ndarray | None = None,
                 progress: Callable[[dict], Any] | None = None, threads: int | None = None,
                 init: MlpModel | None = None) -> tuple[MlpModel, Any]:
    """Steps 4-5 of the module docstring on the prepared samples (all, or the boolean mask
    `rows`: a restart's leave-one-level-out fit): (model, info)."""
    X, y = prep.X, prep.force
    xd, v, u = prep.xd, prep.v, prep.u
    if rows is not None:
        X, y = X[rows], y[rows]
        if xd is not None:
            xd, v, u = xd[rows], v[rows], u[rows]
    terms = list(prep.terms)
    rest_from = None
    if terms:
        terms = _fitted_terms(terms, xd, v, u, y)
        # the force at rest is the damper's, less what the terms give at rest (v = 0: a valve nothing)
        rest_from = y - terms_force(terms, xd, np.zeros_like(v), u=u)
        y = y - terms_force(terms, xd, v, u=u)
    _check_magnitudes(X, y, prep.features)
    r = prep.request
    o = {name: getattr(r, name, None) for name in FIT_OPTIONS}
    o.update(seed=seed, threads=threads, rest_fraction=OPTIONS["rest_fraction"].default,
             settings=train_settings(r.algorithm, r.settings))
    try:
        model, info = fit_checked(X, y, prep.features, o, progress=progress, data=prep.provenance, init=init,
                                  rest_from=rest_from)
    except ValueError as e:
        raise DataError(str(e)) from None
    model.terms = terms
    model.feature_params = dict(prep.feature_params)
    if terms:
        # fit() measured NRMSE on the residual force; report the hybrid model's.
        y_all = y + terms_force(terms, xd, v, u=u)
        pred = predict_force(model, X, xd, v=v, u=u)
        for name, idx in (("train", info.train_idx), ("val", info.val_idx), ("test", info.test_idx)):
            if len(idx):
                info.metrics[name] = nrmse(pred[idx], y_all[idx])
        info.metrics["all"] = nrmse(pred, y_all)
        model.meta["metrics"] = {k: round(v, 6) for k, v in info.metrics.items()}
    bad = {k: v for k, v in info.metrics.items() if v is None or not np.isfinite(v)}
    if bad:  # never a model with null metrics and exit 0
        raise ModelError(f"training gave non-finite NRMSE ({', '.join(sorted(bad))}): the fit diverged; "
                         "check the data's scale and units, or try another --algorithm or --seed")
    model.validate()  # feature_params (time constants > 0) and the rest, as model.json is checked
    return model, info


def _fitted_terms(terms, xd, v, u, y) -> list[dict[str, Any]]:
    """`terms` with their free parameters fitted to the force y [N] (dampnet.terms.fit_terms);
    ModelError for terms that cannot be fitted."""
    try:
        return fit_terms(terms, xd, v, u, y)
    except ValueError as e:
        raise ModelError(str(e)) from None


#: largest |value| accepted in a training feature or force, in its SI unit. The runtime runs in
#: single precision (largest float 3.4e38): the model's offsets and gains must stay well inside it,
#: and squared errors must stay finite in double. Real dyno data are below 1e6 in SI units.
MAX_TRAINING_MAGNITUDE = 1e15


def _check_magnitudes(X: np.ndarray, y: np.ndarray, features: Sequence[str]) -> None:
    """DataError naming the first feature (or the force) whose values are beyond MAX_TRAINING_MAGNITUDE."""
    for name, col in [*zip(features, np.asarray(X).T), ("force", y)]:
        peak = float(np.max(np.abs(col))) if np.size(col) else 0.0
        if not peak <= MAX_TRAINING_MAGNITUDE:
            raise DataError(f"training data: {name} reaches {peak:.3g} in its SI unit: expected values below "
                            f"{MAX_TRAINING_MAGNITUDE:.0e} (are the units right? the runtime computes in single "
                            "precision)")


# -- the diagnose -> add effect -> retrain step --------------------------------------------

def diagnosed_parameters(diagnosis: Mapping[str, Any], effect_id: str) -> dict[str, Any]:
    """The parameters the diagnosis estimated for `effect_id` (its catalogue entry's
    `diagnosed_by` candidate, e.g. gas_spring for bump_stop), from the dict `dampnet.diagnose`
    returns or its JSON (`dampnet diagnose --json`). ValueError naming the field when the
    diagnosis has no such candidate or could not test it (its parameters are unknown)."""
    cid = catalogue_effect(effect_id).diagnosed_by
    if cid is None:
        raise ValueError(f"effect {effect_id!r} is not diagnosed (the catalogue names no candidate for it)")
    cands = diagnosis.get("candidates") if isinstance(diagnosis, Mapping) else None
    if not isinstance(cands, list):
        raise ValueError("diagnosis: no 'candidates' list (expected the JSON of dampnet diagnose --json)")
    entry = next((c for c in cands if isinstance(c, Mapping) and c.get("effect") == cid), None)
    if entry is None:
        raise ValueError(f"diagnosis: candidates has no entry for effect {cid!r}; it has "
                         f"{', '.join(str(c.get('effect')) for c in cands if isinstance(c, Mapping)) or 'none'}")
    params = entry.get("parameters")
    if not entry.get("testable", True) or not params:
        raise ValueError(f"diagnosis: effect {cid!r} was not testable, so it has no estimated parameters "
                         f"({entry.get('note') or 'no parameters'}); estimate them from the data instead")
    if not isinstance(params, Mapping):
        raise ValueError(f"diagnosis: candidates[{cid}].parameters: expected an object, got {params!r}")
    return dict(params)


def apply_additions(settings: Mapping[str, Any], ds: Dataset, effect_id: str, *,
                    diagnosis: Mapping[str, Any] | None = None,
                    params: Mapping[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """`settings` (train_dataset keyword arguments) with what captures `effect_id` merged in.

    The effect's additions are the catalogue's (dampnet.effects): its features join
    settings["features"] (None: the data's default features) unless already there, its
    terms join settings["terms"], its feature parameters update settings["feature_params"].
    Their parameters (a lag's time constant, a pre-sliding length) are taken, in order,
    from `diagnosis` (the dict dampnet.diagnose returns, or its JSON) when it is given;
    else from `params` (`dampnet train --add` estimates them from the data with
    dampnet.diagnosis.estimate.estimate_parameters); else the catalogue's defaults.

    Returns (new settings, the additions: {"features", "terms", "feature_params", "how",
    "why", "parameters", "parameters_from"}). ValueError for an unknown effect, an effect
    without a recipe, a diagnosis without the effect, or both diagnosis and params.
    """
    if diagnosis is not None and params is not None:
        raise ValueError("apply_additions: give the diagnosis or params, not both")
    catalogue_effect(effect_id)  # ValueError listing the known ids
    if diagnosis is not None:
        used, source = diagnosed_parameters(diagnosis, effect_id), "diagnosis"
    elif params:
        used, source = dict(params), "estimated from the data"
    else:
        used, source = {}, "catalogue defaults"
    control = ds.tests[0].control_name if ds.tests else "voltage"
    add = effect_additions(effect_id, used, control)
    out = dict(settings)
    features = list(out.get("features") or default_features(ds))
    features += [f for f in add["features"] if f not in features]
    terms = list(out.get("terms") or [])
    terms += [t for t in add["terms"] if t not in terms]
    feature_params = {**(out.get("feature_params") or {}), **add["feature_params"]}
    out.update(features=features, terms=terms, feature_params=feature_params)
    return out, {**add, "parameters": used, "parameters_from": source}


# -- metrics and files ----------------------------------------------------------------

def model_metrics(model: MlpModel, info, split: Split, lookup: bool = True) -> dict[str, Any]:
    """metrics.json: training summary, hold-out tables of the model and of the lookup-table baseline.

    Keys: model_id, training {algorithm, time_s, epochs, best_epoch, stop_reason, nrmse {train,
    val, test, all}, samples, history}, holdout_tests, holdout and holdout_lookup (tables of
    dampnet.evaluate.metrics), lookup_table (the baseline fitted on the training tests,
    LookupTable.to_dict), noise_floor {nrmse_range, nrmse_std, rmse_n} for rig data, structure (is
    the force rising with velocity, and straight between the training control levels:
    dampnet.evaluation.structure).
    """
    out: dict[str, Any] = {
        "model_id": model.model_id(),
        "training": {
            "algorithm": info.algorithm, "time_s": info.time_s, "epochs": info.epochs,
            "best_epoch": info.best_epoch, "stop_reason": info.stop_reason,
            "nrmse": dict(info.metrics),
            "samples": {"train": info.n_train, "val": info.n_val, "test": info.n_test,
                        "rest_points": info.n_rest_points},
            **({"rest_force": model.meta["rest_force"]} if "rest_force" in model.meta else {}),
            "history": info.history,
            **({"restarts": model.meta["restarts"]} if "restarts" in model.meta else {}),
            **({"valve": model.meta["valve"]} if "valve" in model.meta else {}),
        },
        "holdout_tests": split.holdout_ids,
    }
    if split.holdout is not None:
        out["holdout"] = evaluate_model(lambda t: predict_force(model, t), split.holdout.tests)
        if "restarts" in model.meta and getattr(info, "restart_models", None):
            out["training"]["restarts"] = restarts_holdout(model.meta["restarts"], info.restart_models,
                                                           split.holdout.tests)
        if lookup:
            try:
                table = fit_lookup(split.train)
                out["lookup_table"] = table.to_dict()
                out["holdout_lookup"] = evaluate_model(table.predict_test, split.holdout.tests)
            except (DataError, ValueError) as e:
                out["holdout_lookup"] = {"error": str(e)}
    out["structure"] = structure(model, split.train.tests)
    nf = noise_floors(split.holdout or split.train)
    if nf:
        out["noise_floor"] = nf
        if "holdout" in out:
            out["noise_floor"]["holdout_vs_floor"] = holdout_vs_noise_floor(out["holdout"], nf["rmse_n"])
    return out


def holdout_vs_noise_floor(holdout: dict[str, Any], noise_rmse_n: float) -> dict[str, Any]:
    """The hold-out error against the rig's noise floor, overall and per frequency: the ratio of the
    model's RMSE to the sensor noise's RMS [N] (the same ratio as NRMSE over the floor's NRMSE on the
    same tests; 1 is a model as good as the data can show, since the measured force carries the noise)."""
    o = holdout["overall"]
    # a per-frequency row's NRMSE is its RMSE over its own force range: the floor's NRMSE on it is
    # the noise's RMS over that range
    rows = [{"frequency_hz": r["frequency_hz"], "nrmse": r["nrmse"],
             "floor_nrmse": noise_rmse_n * r["nrmse"] / r["rmse_n"] if r["rmse_n"] > 0 else float("nan"),
             "ratio": r["rmse_n"] / noise_rmse_n} for r in holdout.get("per_frequency", [])]
    return {"ratio": o["rmse_n"] / noise_rmse_n, "floor_nrmse": noise_rmse_n / o["force_range_n"],
            "per_frequency": rows}


def restarts_holdout(record: dict[str, Any], models: list[MlpModel], tests) -> dict[str, Any]:
    """The restart record with every restart's hold-out NRMSE added (run["holdout_nrmse"]) and its
    spread: shown to the user after the fact, never used to choose (the selection saw only the
    training levels)."""
    out = {**record, "runs": [dict(r) for r in record["runs"]]}
    for run, m in zip(out["runs"], models):
        run["holdout_nrmse"] = round(evaluate_model(lambda t: predict_force(m, t), tests)["overall"]["nrmse"], 7)
    h = [r["holdout_nrmse"] for r in out["runs"]]
    out.update(holdout_nrmse_min=min(h), holdout_nrmse_max=max(h),
               holdout_note="each restart's hold-out NRMSE, for information: the selection never saw the hold-out")
    return out


def noise_floors(ds: Dataset) -> dict[str, float] | None:
    """The rig's noise floor on `ds` in both definitions (None for data not from the rig)."""
    if ds.meta.get("generator") != RIG_GENERATOR:
        return None
    f = ds.concat("force")
    rms = noise_floor_rmse_n(ds)
    return {"nrmse_range": rms / float(np.ptp(f)), "nrmse_std": noise_floor_nrmse(ds), "rmse_n": rms}
