"""Dataset in, trained model out: the pipeline that `dampnet train`, the demo and the diagnosis share.

  train_dataset(ds, features=..., algorithm=..., ...) -> (model, info, split)
  predict_force(model, test_or_features, displacement=None) -> force [N]
  save_model_dir(model, metrics, out_dir, force=False) -> out_dir
  model_metrics(model, info, split) -> the metrics.json dict

What train_dataset does, in order (the thesis's chapter 4 data handling):
 1. Acceleration, if a feature needs it and the data lack it: derived at the full
    sampling rate (`dampnet.data.add_acceleration`, default 20 ms window), before
    any decimation.
 2. Hold-out: every test at `holdout_voltage` (default 2.25 V, as the thesis) and
    the tests named in `holdout_tests` are set aside for independent evaluation.
    None/None holds nothing out.
 3. Decimation of the training tests (every `decimate`-th sample; None = to about
    DECIMATE_TARGET_HZ = 200 Hz, i.e. 25 at the dyno's 5 kHz). The highest test
    frequency is 3 Hz, so 200 Hz keeps 67 samples per cycle, far more than the
    force waveform needs; the derived acceleration is already smoothed over
    20 ms (100 samples) so decimating it loses nothing. Measured on the full
    thesis plan (bench/bench_train_thesis.py, RESULTS.md): factor 25 trains LM in
    ~6 s to a hold-out NRMSE of 0.0037; factor 50 gives 0.0042 (fewer samples per
    weight make early stopping stop sooner); factor 1 would be 25x the work.
    Features are computed at the full rate and then decimated: derived features
    with a state (velocity_lag, voltage_lag, friction_state) are only the
    quantities the runtime's loop computes when sampled finely.
 4. Physics terms (hybrid model), if any: their parameters are fitted first
    (fit_terms) and the network learns the residual force minus the terms.
 5. `dampnet.train.fit`: mapminmax scaling, random 70/15/15 split with early
    stopping, zero-force points, saturation limits from the training range.

Features and terms are data: a feature is a name in the registry
(`dampnet.train.features.FEATURES`), a term a dict {"kind": ..., "params": [...]}
(`dampnet.terms`); nothing here branches on their names.
"""

from __future__ import annotations

import inspect
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from dampnet.data import DataError, Dataset, DynoTest, add_acceleration, decimate as _decimate
from dampnet.data import holdout_split
from dampnet.data.preprocess import DEFAULT_WINDOW_S, acceleration_of
from dampnet.model import MlpModel, ModelError, atomic_write_text
from dampnet.schema import show

#: Default input features (the thesis's); the control is swapped for "current" on current data.
DEFAULT_FEATURES = ("velocity", "acceleration", "voltage")
#: Decimated sample rate aimed for when decimate=None [Hz] (see the module docstring).
DECIMATE_TARGET_HZ = 200.0
DEFAULT_HOLDOUT_VOLTAGE = 2.25
HEADER_NAME = "model.h"
#: Settings train_dataset uses unless `settings` overrides them. Adam's own defaults
#: (full batch, lr 1e-3: one small step per epoch) need thousands of epochs on dyno data;
#: mini-batches of 128 with lr 1e-2 decaying 2 %/epoch reach about 0.012 NRMSE in ~50
#: epochs on tests/python/test_train_cli.py's small plan (full batch: 0.066 after 150).
ALGORITHM_SETTINGS = {"adam": {"batch_size": 128, "lr": 1e-2, "lr_decay": 0.98}}
HEADER_PREFIX = "dn_model"


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


# -- features -------------------------------------------------------------------

def default_features(ds: Dataset) -> list[str]:
    """velocity, acceleration and the data's control channel (voltage or current)."""
    control = ds.tests[0].control_name if ds.tests else "voltage"
    return ["velocity", "acceleration", control]


def _feature_column(test: DynoTest, name: str, feature_params: dict[str, float]) -> np.ndarray:
    from dampnet.train.features import feature

    get = feature(name).get
    try:
        n_params = len(inspect.signature(get).parameters)
    except (TypeError, ValueError):
        n_params = 1
    return np.asarray(get(test, feature_params) if n_params >= 2 else get(test), dtype=np.float64).ravel()


def feature_matrix(tests: Sequence[DynoTest], features: Sequence[str],
                   feature_params: dict[str, float] | None = None,
                   acceleration_window: float | int | None = None) -> np.ndarray:
    """X [samples, len(features)] of `tests`, via the feature registry.

    Derives acceleration (on a copy of the test's channels) if a test lacks it.
    Raises DataError naming the feature, the test and the channels it has when a
    test cannot provide a feature (e.g. a model trained with temperature, data without).
    """
    from dampnet.train.features import FEATURES

    unknown = [f for f in features if f not in FEATURES]
    if unknown:
        raise DataError(f"unknown feature(s) {unknown}; known: {', '.join(sorted(FEATURES))}")
    params = dict(feature_params or {})
    blocks = []
    for t in tests:
        cols = []
        for f in features:
            if f == "acceleration" and "acceleration" not in t.channels:
                try:
                    cols.append(acceleration_of(t, acceleration_window))
                except DataError:
                    raise DataError(f"test {t.test_id}: feature 'acceleration' needs a velocity or "
                                    "displacement channel") from None
                continue
            try:
                cols.append(_feature_column(t, f, params))
            except KeyError as e:
                have = ", ".join(sorted(t.channels))
                raise DataError(f"test {t.test_id}: feature {f!r} needs channel {e.args[0]!r}, which "
                                f"the data do not have (channels: {have})") from None
        if len({len(c) for c in cols}) > 1 or (cols and len(cols[0]) != len(t)):
            raise DataError(f"test {t.test_id}: features {list(features)} have lengths "
                            f"{[len(c) for c in cols]}, expected {len(t)}")
        blocks.append(np.stack(cols, axis=1) if cols else np.empty((len(t), 0)))
    return np.concatenate(blocks) if blocks else np.empty((0, len(features)))


# -- physics terms ---------------------------------------------------------------

def _terms_module():
    import importlib

    try:
        mod = importlib.import_module("dampnet.terms")  # numpy versions of the runtime's term formulas
    except ModuleNotFoundError as e:
        if e.name != "dampnet.terms":
            raise
        return None
    return mod if hasattr(mod, "terms_force") else None


def _term_force_fallback(term: dict[str, Any], x: np.ndarray) -> np.ndarray:
    """The term formulas of the C++ runtime (used only if dampnet.terms is absent).

    position_poly [p0, p1, p2, p3]:  p0 + p1 x + p2 x^2 + p3 x^3      (x displacement [m], N)
    bump_stop [x_free, k, n]:        sign(x) k (|x| - x_free)^n beyond |x| > x_free, else 0
    """
    p = [float(v) for v in term.get("params", [])]
    kind = term["kind"]
    if kind == "position_poly":
        p = (p + [0.0] * 4)[:4]
        return p[0] + x * (p[1] + x * (p[2] + x * p[3]))
    if kind == "bump_stop":
        x_free, k, n = (p + [0.0, 0.0, 1.0])[:3]
        over = np.maximum(np.abs(x) - x_free, 0.0)
        return np.sign(x) * k * over ** n
    raise ModelError(f"unknown physics term kind {kind!r} (known: position_poly, bump_stop)")


def terms_force(terms: Sequence[dict[str, Any]], displacement: np.ndarray) -> np.ndarray:
    """Sum of the physics terms [N] at displacement [m] (0 for no terms)."""
    x = np.asarray(displacement, dtype=np.float64)
    if not terms:
        return np.zeros_like(x)
    mod = _terms_module()
    if mod is not None:
        try:
            return np.asarray(mod.terms_force(list(terms), x), dtype=np.float64)
        except ValueError as e:
            raise ModelError(f"physics terms: {e}") from None
    return sum(_term_force_fallback(t, x) for t in terms)


def _velocity_basis(v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """A simple damper model, linear in its coefficients, fitted jointly with the terms so that
    velocity-dependent force is not attributed to position: c1 v + c2 v u + c3 tanh(v/v0) + c4 tanh(v/v0) u."""
    v0 = 0.05 * max(float(np.max(np.abs(v))), 1e-9)
    s = np.tanh(v / v0)
    return np.stack([v, v * u, s, s * u], axis=1)


def _term_columns(kind: str, x: np.ndarray, shape: tuple[float, ...]) -> np.ndarray:
    if kind == "position_poly":
        return np.stack([np.ones_like(x), x, x * x, x ** 3], axis=1)
    if kind == "bump_stop":
        x_free, n = shape
        return (np.sign(x) * np.maximum(np.abs(x) - x_free, 0.0) ** n)[:, None]
    raise ModelError(f"cannot fit physics term kind {kind!r} (fittable: position_poly, bump_stop)")


def _shape_candidates(kind: str, x: np.ndarray) -> list[tuple[float, ...]]:
    if kind == "bump_stop":
        xmax = float(np.max(np.abs(x)))
        return [(f * xmax, n) for f in (0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95) for n in (1.0, 1.5, 2.0, 3.0)]
    return [()]


def fit_terms(terms: Sequence[dict[str, Any]], x: np.ndarray, v: np.ndarray, u: np.ndarray,
              y: np.ndarray) -> list[dict[str, Any]]:
    """Terms with parameters: those given keep theirs; the others are fitted by least squares.

    Fitted jointly (one linear least-squares problem) on the training samples:
    y - sum(fixed terms) ~ sum(fitted terms) + the simple velocity model of
    _velocity_basis, whose coefficients are then dropped (the MLP learns the
    velocity dependence). position_poly is linear in its 4 parameters;
    bump_stop's x_free and exponent n are chosen on a grid (x_free 50-95 % of
    the largest |x|, n in 1, 1.5, 2, 3) by least residual, k by least squares.
    """
    terms = [dict(t) for t in terms]
    for t in terms:
        if "kind" not in t:
            raise ModelError(f"physics term {t}: expected a 'kind'")
    fixed = [t for t in terms if t.get("params") is not None]
    free = [i for i, t in enumerate(terms) if t.get("params") is None]
    if not free:
        return terms
    target = y - terms_force(fixed, x)
    base = _velocity_basis(v, u)
    import itertools

    best = None
    for shapes in itertools.product(*[_shape_candidates(terms[i]["kind"], x) for i in free]):
        cols = [_term_columns(terms[i]["kind"], x, s) for i, s in zip(free, shapes)]
        A = np.hstack(cols + [base])
        coef, *_ = np.linalg.lstsq(A, target, rcond=None)
        resid = float(np.sum((A @ coef - target) ** 2))
        if best is None or resid < best[0]:
            best = (resid, shapes, coef, [c.shape[1] for c in cols])
    _, shapes, coef, widths = best
    pos = 0
    for i, s, w in zip(free, shapes, widths):
        c = coef[pos:pos + w]
        pos += w
        kind = terms[i]["kind"]
        if kind == "bump_stop":
            # k < 0 would pull towards the stop: not a bump stop, so the term is switched off
            terms[i]["params"] = [float(s[0]), max(float(c[0]), 0.0), float(s[1])]
        else:
            terms[i]["params"] = [float(a) for a in c]
        terms[i]["fitted"] = "least squares with a velocity model (dampnet.workflow.fit_terms)"
    return terms


# -- prediction --------------------------------------------------------------------

def predict_force(model: MlpModel, test_or_features, displacement: np.ndarray | None = None) -> np.ndarray:
    """Force [N] of a (hybrid) model: MLP(features) + sum of the model's physics terms.

    `test_or_features`: a DynoTest (features built via the registry; a missing
    feature raises DataError) or a feature matrix [n, n_inputs] in the model's
    feature order, in which case a hybrid model also needs `displacement` [m].
    """
    if isinstance(test_or_features, DynoTest):
        test = test_or_features
        X = feature_matrix([test], model.features, model.feature_params,
                           model.meta.get("data", {}).get("acceleration_window_s"))
        if model.terms:
            if "displacement" not in test.channels:
                raise DataError(f"test {test.test_id}: the model's physics terms need a displacement "
                                "channel, which the data do not have")
            displacement = test.channels["displacement"]
    else:
        X = np.atleast_2d(np.asarray(test_or_features, dtype=np.float64))
    y = model.predict(X)
    if model.terms:
        if displacement is None:
            raise ModelError("this model has physics terms: pass displacement [m] with the features")
        y = y + terms_force(model.terms, np.asarray(displacement, dtype=np.float64).ravel())
    return y


def check_features(model: MlpModel, ds: Dataset) -> None:
    """Raise DataError if a test of `ds` cannot provide one of the model's features."""
    for t in ds.tests:
        for f in model.features:
            if f == "acceleration" and ("velocity" in t.channels or "displacement" in t.channels):
                continue
            from dampnet.train.features import FEATURES

            getter = FEATURES.get(f)
            channel = getattr(getattr(getter, "get", None), "channel", None)
            if getter is None:
                raise DataError(f"the model needs feature {show(f)}, which this dampnet does not know")
            if channel is not None and channel not in t.channels:
                raise DataError(f"test {t.test_id}: the model was trained on features "
                                f"{show(', '.join(model.features))}, but the data have no {channel!r} channel "
                                f"(channels: {', '.join(sorted(t.channels))})")


# -- training -----------------------------------------------------------------------

def _auto_decimate(ds: Dataset) -> int:
    if not ds.tests:
        return 1
    fs = 1.0 / ds.tests[0].dt
    return max(1, int(round(fs / DECIMATE_TARGET_HZ)))


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
    rig = ds.meta
    if rig.get("generator") == "dampnet.data.rig":
        d["rig"] = {"plan": rig.get("plan", {}).get("name"), "effects": sorted(rig.get("effects", {})),
                    "seed": rig.get("seed")}
    return d


def train_dataset(ds: Dataset, features: Sequence[str] | None = None, algorithm: str = "lm", *,
                  hidden: Sequence[int] = (30,), activation: str = "tanh",
                  holdout_voltage: float | None = DEFAULT_HOLDOUT_VOLTAGE,
                  holdout_tests: Sequence[str] | None = None, decimate: int | None = None,
                  terms: Sequence[dict[str, Any]] | None = None,
                  feature_params: dict[str, float] | None = None, seed: int = 0,
                  progress: Callable[[dict], Any] | None = None, zero_points: bool = True,
                  max_epochs: int = 1000, max_fail: int = 6, settings: dict[str, Any] | None = None,
                  threads: int | None = None,
                  acceleration_window: float | None = None) -> tuple[MlpModel, Any, Split]:
    """Train a (hybrid) MLP damper model on a dataset; see the module docstring for the steps.

    Returns (model, info, split): `info` is dampnet.train.TrainInfo (its subset indices
    refer to the decimated training samples, split.train_used), `split` says which
    tests trained and which were held out. Raises DataError for unusable data
    (nothing to hold out, missing feature, no training tests) and ModelError for bad terms.
    """
    from dampnet.train import fit

    if not ds.tests:
        raise DataError(f"{ds.source}: no tests")
    features = list(features) if features else default_features(ds)
    if len(set(features)) != len(features):
        raise DataError(f"features: each feature once, got {features}")
    window = DEFAULT_WINDOW_S if acceleration_window is None else acceleration_window
    if "acceleration" in features:
        for t in ds.tests:
            if "acceleration" not in t.channels:
                add_acceleration(t, window)
    if holdout_voltage is None and not holdout_tests:
        train, hold = ds, None
    else:
        try:
            train, hold = holdout_split(ds, holdout_voltage, list(holdout_tests or []))
        except ValueError as e:
            raise DataError(f"{e} (choose another --holdout-voltage, name --holdout-tests, or "
                            "--holdout-voltage none)") from None
    if not train.tests:
        raise DataError("every test is held out: nothing left to train on")
    factor = _auto_decimate(train) if decimate is None else int(decimate)
    used = _decimate(train, factor) if factor > 1 else train
    # Features at the full sample rate, then decimated: a derived feature with a state (a lag of a
    # few ms, the friction state) computed on decimated samples would be a different quantity.
    X = np.concatenate([feature_matrix([t], features, feature_params, window)[::factor]
                        for t in train.tests])
    y = np.concatenate([t.channels["force"] for t in used.tests])
    terms = list(terms or [])
    if terms:
        for t in used.tests:
            if "displacement" not in t.channels:
                raise DataError(f"test {t.test_id}: physics terms need a displacement channel")
        xd = np.concatenate([t.channels["displacement"] for t in used.tests])
        v = np.concatenate([t.channels["velocity"] for t in used.tests])
        u = np.concatenate([t.control for t in used.tests])
        terms = fit_terms(terms, xd, v, u, y)
        y = y - terms_force(terms, xd)
    _check_magnitudes(X, y, features)
    split = Split(train=train, holdout=hold, holdout_voltage=holdout_voltage,
                  holdout_tests=list(holdout_tests or []), decimate=factor, train_used=used)
    try:
        model, info = fit(X, y, features=features, hidden=hidden, activation=activation,
                          algorithm=algorithm, seed=seed, max_epochs=max_epochs, max_fail=max_fail,
                          zero_points=zero_points,
                          settings={**ALGORITHM_SETTINGS.get(algorithm, {}), **(settings or {})},
                          progress=progress,
                          threads=threads, data=_data_provenance(ds, split, features, window))
    except ValueError as e:
        raise DataError(str(e)) from None
    model.terms = terms
    model.feature_params = dict(feature_params or {})
    model.meta["zero_points"] = bool(zero_points)
    if terms:
        # fit() measured NRMSE on the residual force; report the hybrid model's.
        y_all = y + terms_force(terms, xd)
        pred = predict_force(model, X, xd)
        from dampnet.train import nrmse

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
    return model, info, split


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


# -- metrics and files ----------------------------------------------------------------

def model_metrics(model: MlpModel, info, split: Split, lookup: bool = True) -> dict[str, Any]:
    """metrics.json: training summary, hold-out tables of the model and of the lookup-table baseline.

    Keys: model_id, training {algorithm, time_s, epochs, best_epoch, stop_reason, nrmse {train,
    val, test, all}, samples, history}, holdout_tests, holdout and holdout_lookup (tables of
    dampnet.evaluate.metrics), lookup_table (the baseline fitted on the training tests,
    LookupTable.to_dict), noise_floor {nrmse_range, nrmse_std, rmse_n} for rig data.
    """
    from dampnet.evaluate.metrics import evaluate_model

    out: dict[str, Any] = {
        "model_id": model.model_id(),
        "training": {
            "algorithm": info.algorithm, "time_s": info.time_s, "epochs": info.epochs,
            "best_epoch": info.best_epoch, "stop_reason": info.stop_reason,
            "nrmse": dict(info.metrics),
            "samples": {"train": info.n_train, "val": info.n_val, "test": info.n_test,
                        "zero_points": info.n_zero_points},
            "history": info.history,
        },
        "holdout_tests": split.holdout_ids,
    }
    if split.holdout is not None:
        out["holdout"] = evaluate_model(lambda t: predict_force(model, t), split.holdout.tests)
        if lookup:
            try:
                from dampnet.evaluate.lookup import fit_lookup

                table = fit_lookup(split.train)
                out["lookup_table"] = table.to_dict()
                out["holdout_lookup"] = evaluate_model(table.predict_test, split.holdout.tests)
            except (DataError, ValueError) as e:
                out["holdout_lookup"] = {"error": str(e)}
    nf = noise_floors(split.holdout or split.train)
    if nf:
        out["noise_floor"] = nf
    return out


def noise_floors(ds: Dataset) -> dict[str, float] | None:
    """The rig's noise floor on `ds` in both definitions (None for data not from the rig)."""
    if ds.meta.get("generator") != "dampnet.data.rig":
        return None
    from dampnet.data.rig import noise_floor_nrmse

    sigma = float(ds.meta["noise"]["force_n"])
    res = float(ds.meta.get("resolution", {}).get("force", 0.0))
    f = ds.concat("force")
    rms = float(np.sqrt(sigma ** 2 + res ** 2 / 12.0))
    return {"nrmse_range": rms / float(np.ptp(f)), "nrmse_std": noise_floor_nrmse(ds), "rmse_n": rms}


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if np.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def write_json(path: str | os.PathLike, obj: Any, overwrite: bool = False) -> Path:
    """JSON (NaN/Inf written as null) atomically."""
    return atomic_write_text(path, json.dumps(_jsonable(obj), indent=1, allow_nan=False) + "\n", overwrite)


def save_model_dir(model: MlpModel, metrics: dict[str, Any] | None, out_dir: str | os.PathLike,
                   force: bool = False, prefix: str = HEADER_PREFIX,
                   inputs: Sequence[str | os.PathLike] = ()) -> Path:
    """Write MODEL_DIR/{model.json, metrics.json, model.h} as one atomic step.

    The files go to a staging directory next to out_dir that is then swapped into
    place (`dampnet.outputs`): a reader never sees a half-written model directory,
    and a kill at any point leaves the old or the new one. An existing out_dir is
    refused (OutputError, a FileExistsError) unless `force`, and even then unless it
    is a model directory (model.json) that is not one of `inputs`, `.` or a parent.
    """
    from dampnet.export import write_header
    from dampnet.outputs import check_output_dir, staged_dir

    out = check_output_dir(out_dir, "model", inputs, force)
    with staged_dir(out) as tmp:
        model.save(tmp / "model.json", overwrite=True)
        write_json(tmp / "metrics.json", metrics or {}, overwrite=True)
        write_header(model, tmp / HEADER_NAME, prefix=prefix, overwrite=True)
    return out
