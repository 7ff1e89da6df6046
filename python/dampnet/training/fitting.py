"""fit(): from a feature matrix and forces to a trained MlpModel, reproducibly.

What fit does, in order (MATLAB's fitting-app defaults unless stated):
 1. Random split of the samples into train/validation/test (default 70/15/15),
    seeded (numpy default_rng(seed)).
 2. Rest points (thesis §5, after Burnett et al.; dampnet.training.rest_points):
    ceil(rest_fraction * n_train) extra training samples (default 1 %) at which
    the damper is at rest, at any valid control, with target the damper's own
    force at rest (rest_target "estimated", the default), 0 N ("zero", the
    thesis's) or no rest points ("none"). They join the training set only.
 3. mapminmax scaling of inputs and force to [-1, 1] over all data given to
    fit (plus rest points), as MATLAB's process functions do before division;
    the same range gives the saturation limits (sat_lo/sat_hi).
 4. Nguyen-Widrow initialisation from torch.Generator().manual_seed(seed).
 5. Training with the chosen algorithm; validation early stopping after
    max_fail (6) consecutive rises, returning the best-validation weights.
    'br' does not stop on validation (as MATLAB's trainbr): its evidence
    framework is the guard against overfitting; validation is still recorded.

The default hidden activation is tanh: it is MATLAB's default 'tansig' which
the thesis's toolbox network used (the thesis calls it "sigmoidal", tansig
being a sigmoid-shaped function), and it is zero-centred, which suits inputs
and targets scaled to [-1, 1]. 'sigmoid' (logsig) is available.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import math
import os
import platform
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np
import torch

from dampnet.model import MlpModel, mapminmax_settings
from dampnet.outputs import jsonable
from dampnet.training.adam import Adam
from dampnet.training.br import BayesianRegularization
from dampnet.training.control_prior import prior_rows
from dampnet.training.monotone_prior import monotone_rows
from dampnet.features import control_columns, control_levels, units_of, velocity_column
from dampnet.training.lm import LevenbergMarquardt
from dampnet.training.loop import run
from dampnet.training.metrics import nrmse
from dampnet.training.net import DTYPE, Layout
from dampnet.training.problem import MlpProblem
from dampnet.training.rest_points import RestForce, rest_force, rest_points
from dampnet.training.torch_reference import torch_forward
from dampnet.training.scg import ScaledConjugateGradient
from dampnet.training.settings import check_request, fit_options, show_value

ALGORITHMS = {
    "lm": LevenbergMarquardt,
    "br": BayesianRegularization,
    "scg": ScaledConjugateGradient,
    "adam": Adam,
}
# Below this many Jacobian entries (samples x parameters) one thread is much faster:
# torch's thread start-up and spinning dominate small ops, worse on a busy machine.
_SMALL_PROBLEM = 2_000_000


@dataclass
class TrainInfo:
    """What happened in a fit. Errors in `history` are MSE of the scaled force ([-1, 1] units)."""

    algorithm: str
    settings: dict[str, Any]
    history: list[dict[str, Any]]
    epochs: int
    best_epoch: int
    stop_reason: str
    time_s: float
    n_train: int
    n_val: int
    n_test: int
    n_rest_points: int  # the rest rows added to the training rows (dampnet.training.rest_points)
    metrics: dict[str, float]  # NRMSE (thesis Table 3 definition) per subset, in force units
    stats: dict[str, Any] = field(default_factory=dict)  # e.g. BR's gamma
    train_idx: np.ndarray | None = None  # indices into X of each subset
    val_idx: np.ndarray | None = None
    test_idx: np.ndarray | None = None
    #: with restarts (dampnet.training.restarts): every restart's full-fit model, in restart
    #: order (the kept one among them), so that the spread can be shown; not serialised
    restart_models: list | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (without the per-sample subset indices and restart models)."""
        return {k: v for k, v in self.__dict__.items() if not k.endswith("_idx") and k != "restart_models"}


@contextlib.contextmanager
def _training_threads(n: int | None):
    """torch's threads set to `n` (None: as they are) and numpy's BLAS, which computes LM's JᵀJ
    (dampnet.training.lm.gram), limited to the same number: by default it would start one thread
    per core beside torch's, and restart workers run one thread each."""
    from threadpoolctl import threadpool_limits

    old = torch.get_num_threads()
    if n is not None and n != old:
        torch.set_num_threads(n)
    try:
        with threadpool_limits(limits=torch.get_num_threads(), user_api="blas"):
            yield torch.get_num_threads()
    finally:
        if torch.get_num_threads() != old:
            torch.set_num_threads(old)


def _auto_threads(jacobian_entries: int) -> int:
    """1 thread for small problems; else the cores not already busy (1-min load average).

    On a shared machine extra torch threads contend with other processes and
    run several times slower than one thread (measured: bench/bench_train.py).
    """
    if jacobian_entries < _SMALL_PROBLEM:
        return 1
    try:
        free = (os.cpu_count() or 1) - os.getloadavg()[0]
    except OSError:
        free = 1
    return max(1, min(torch.get_num_threads(), int(free + 0.5)))


def split_indices(n: int, split: Sequence[float], rng: np.random.Generator):
    """Random disjoint train/val/test index arrays with fractions `split` (summing to 1)."""
    given = split
    try:
        split = [float(f) for f in split]
    except (TypeError, ValueError):
        split = None
    if split is None or len(split) != 3 or not min(split) >= 0 or not math.isclose(sum(split), 1.0, abs_tol=1e-9):
        raise ValueError(f"split: three non-negative fractions summing to 1 expected, got {show_value(given)}")
    perm = rng.permutation(n)
    n_tr = int(round(split[0] * n))
    n_va = int(round(split[1] * n))
    n_tr = max(1, min(n_tr, n))
    n_va = min(n_va, n - n_tr)
    return np.sort(perm[:n_tr]), np.sort(perm[n_tr:n_tr + n_va]), np.sort(perm[n_tr + n_va:])


def warm_start_weights(model: MlpModel, layout: Layout, features: Sequence[str], in_off, in_gain,
                       out_off: float, out_gain: float) -> torch.Tensor:
    """`model`'s weights as a flat vector of `layout` in another mapminmax scaling, same function.

    The scaled input of the model, s = (x - off) g - 1, is an affine map of the new one,
    s = A s' + c; so is the output. Folding both into the first layer and the output layer
    gives a network of the new scaling that computes the same force (to rounding).
    """
    if list(model.features) != list(features) or tuple(model.hidden) != tuple(layout.hidden) \
            or model.activation != layout.activation:
        raise ValueError(f"init: the model's features {model.features}, hidden {list(model.hidden)} and "
                         f"activation {model.activation!r} must be this fit's ({list(features)}, "
                         f"{list(layout.hidden)}, {layout.activation!r})")
    ymin = model.in_ymin
    a = model.in_gain / in_gain
    c = (1.0 / in_gain + in_off - model.in_offset) * model.in_gain + ymin
    w1 = model.w1 * a[None, :]
    b1 = model.b1 + model.w1 @ c
    # force = (y - ymin_out) / g_old + off_old; new scaled output = (force - off) g - 1
    r = out_gain / model.out_gain
    d = (-model.out_ymin / model.out_gain + model.out_offset - out_off) * out_gain - 1.0
    p = {"w1": w1, "b1": b1, "w_out": model.w_out * r, "b_out": np.array([model.b_out * r + d])}
    if model.w2 is not None:
        p.update(w2=model.w2, b2=model.b2)
    return layout.pack({k: torch.as_tensor(v, dtype=DTYPE) for k, v in p.items()})


def _scaled(a: np.ndarray, offset: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """Values in the network's scaled units (mapminmax: [-1, 1] over the training range)."""
    return (a - offset) * gain - 1.0


def _control_prior(X_train: np.ndarray, features: Sequence[str], weight: float, in_off: np.ndarray,
                   in_gain: np.ndarray, rng: np.random.Generator):
    """(the prior's rows or None, what model.meta["control_prior"] records)."""
    meta: dict[str, Any] = {"weight": weight}
    columns = control_columns(features)
    if weight <= 0:
        return None, meta
    if not columns:
        meta["off"] = "no control input"
        return None, meta
    values = control_levels(X_train, columns)
    meta["levels"] = [round(float(v), 6) for v in values[:, 0]]
    if len(values) < 2:
        meta["off"] = "fewer than two control levels"
        return None, meta
    xs = torch.as_tensor(_scaled(X_train, in_off, in_gain), dtype=DTYPE)
    rows = prior_rows(xs, columns, _scaled(values, in_off[columns], in_gain[columns]), weight, rng)
    meta["points"] = len(rows) if rows is not None else 0
    return rows, meta


def _monotone_prior(X_train: np.ndarray, features: Sequence[str], weight: float, in_off: np.ndarray,
                    in_gain: np.ndarray, rng: np.random.Generator):
    """(the velocity-monotone prior's rows or None, what model.meta["monotone_prior"] records)."""
    meta: dict[str, Any] = {"weight": weight}
    j = velocity_column(features)
    if weight <= 0:
        return None, meta
    if j is None:
        meta["off"] = "no velocity input"
        return None, meta
    columns = control_columns(features)
    values = control_levels(X_train, columns)
    span = None
    if len(values) >= 2:  # between the lowest and highest level; else each row keeps its control
        ends = _scaled(values[[0, -1]], in_off[columns], in_gain[columns])
        span = (ends[0], ends[1])
    xs = torch.as_tensor(_scaled(X_train, in_off, in_gain), dtype=DTYPE)
    rows = monotone_rows(xs, j, columns, span, weight, rng)
    meta["points"] = len(rows) if rows is not None else 0
    return rows, meta


def fit(X: np.ndarray, y: np.ndarray, *, features: Sequence[str], units: Sequence[str] | None = None,
        split: Sequence[float] = (0.7, 0.15, 0.15), progress: Callable[[dict], Any] | None = None,
        data: Any = None, init: MlpModel | None = None, control_prior: float = 0.0,
        **options: Any) -> tuple[MlpModel, TrainInfo]:
    """Train an MLP force model on X [n, k] (feature units) and y [n] (force [N]).

    `options`: the training options fit() takes by name (dampnet.training.settings.FIT_OPTIONS:
    algorithm, hidden, activation, seed, max_epochs, max_fail, rest_fraction, settings,
    control_prior, monotone_prior, rest_target, threads), each the options table's default
    (dampnet.training.settings.OPTIONS) unless given, but `control_prior`: off (0) for a bare
    fit, which knows no control levels of a campaign (the pipeline passes the request's).
    `settings` overrides the algorithm's defaults (e.g. {"mu_max": 1e8} for lm,
    {"lr": 1e-2, "batch_size": 1024} for adam). `progress(record)` is called
    after every epoch with the history record; returning True stops training.
    `threads`: torch threads during training (None: 1 for small problems, else
    the idle cores, see _auto_threads). `data` is stored in model.meta as provenance.
    `init`: start from this model's weights (same features, hidden sizes and activation; its
    function carried over exactly into this fit's scaling) instead of Nguyen-Widrow; the seed
    still draws the split and the rest points (a warm start: dampnet.training.restarts).
    `control_prior`: the weight of the control-interpolation prior (dampnet.training.control_prior;
    0: off) between the control levels of the training rows; it is off without two levels or a
    control input (model.meta["control_prior"] says).
    `rest_target`: the rest points' force: "estimated" (the default: the damper's own force at rest
    from the training rows near v = 0, dampnet.training.rest_points), "zero" (the thesis's 0 N) or
    "none" (no rest points); model.meta["rest_force"] records the estimate whenever there are rest
    points.
    `monotone_prior`: the weight of the prior that the force rises with velocity
    (dampnet.training.monotone_prior; 0: off), between the lowest and highest control level of
    the training rows; off without a velocity input (model.meta["monotone_prior"] says).
    The same inputs and seed give bit-identical weights on the same machine.
    Every option and setting is checked first (dampnet.training.settings.fit_options: a
    one-line ValueError naming it and its range); a training that stops before its first epoch
    (e.g. min_grad above the initial gradient) is a ValueError too, not an untrained model.
    """
    check_request(features=list(features))
    return fit_checked(X, y, features, fit_options(control_prior=control_prior, **options), units=units,
                       split=split, progress=progress, data=data, init=init)


def fit_checked(X: np.ndarray, y: np.ndarray, features: Sequence[str], o: dict[str, Any], *,
                units: Sequence[str] | None = None, split: Sequence[float] = (0.7, 0.15, 0.15),
                progress: Callable[[dict], Any] | None = None, data: Any = None,
                init: MlpModel | None = None, rest_from: np.ndarray | None = None) -> tuple[MlpModel, TrainInfo]:
    """fit() with its options `o` checked already (dampnet.training.settings.fit_options, or a
    checked TrainingRequest's: dampnet.training.pipeline.fit_prepared). `rest_from` [n]: the force
    the estimated force at rest is read from near v = 0 (default y; a hybrid's: the measured force
    less its terms at rest, not the residual the network learns, which a valve's steep bleed near
    v = 0 bends)."""
    algorithm, activation, seed, threads = o["algorithm"], o["activation"], o["seed"], o["threads"]
    max_epochs, max_fail, settings, rest_target = o["max_epochs"], o["max_fail"], o["settings"], o["rest_target"]
    X = np.asarray(X, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64).ravel()
    if X.ndim == 1:
        X = X[:, None]
    features = list(features)
    if X.shape[1] != len(features):
        raise ValueError(f"X has {X.shape[1]} columns but features names {len(features)}: {features}")
    if len(y) != len(X):
        raise ValueError(f"X has {len(X)} rows but y has {len(y)} values")
    if len(X) < 3:
        raise ValueError(f"need at least 3 samples, got {len(X)}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
        raise ValueError("X and y must be finite (found NaN or Inf); clean the data first")
    units = units_of(features) if units is None else list(units)
    layout = Layout(len(features), o["hidden"], activation)

    rng = np.random.default_rng(seed)
    tr, va, te = split_indices(len(X), split, rng)
    Z = rest_points(X[tr], features, o["rest_fraction"], rng) if rest_target != "none" else np.empty((0, X.shape[1]))
    y_rest = y if rest_from is None else np.asarray(rest_from, dtype=np.float64).ravel()
    at_rest = rest_force(X[tr], y_rest[tr], features, Z) if len(Z) else RestForce(0.0, "no rest points")
    y_Z = at_rest.targets(Z) if rest_target == "estimated" else np.zeros(len(Z))
    X_all = np.vstack([X, Z])
    y_all = np.concatenate([y, y_Z])
    in_off, in_gain = mapminmax_settings(X_all)
    (out_off,), (out_gain,) = mapminmax_settings(y_all)

    def scale_x(a):
        return torch.as_tensor(_scaled(a, in_off, in_gain), dtype=DTYPE)

    def scale_y(a):
        return torch.as_tensor((a - out_off) * out_gain - 1.0, dtype=DTYPE)

    prior, prior_meta = _control_prior(X[tr], features, o["control_prior"], in_off, in_gain, rng)
    mono, mono_meta = _monotone_prior(X[tr], features, o["monotone_prior"], in_off, in_gain, rng)
    problem = MlpProblem(layout, scale_x(np.vstack([X[tr], Z])), scale_y(np.concatenate([y[tr], y_Z])),
                         scale_x(X[va]), scale_y(y[va]), prior=[prior, mono])
    gen = torch.Generator().manual_seed(seed)
    x0 = layout.init(gen)
    if init is not None:
        x0 = warm_start_weights(init, layout, features, in_off, in_gain, float(out_off), float(out_gain))
    cls = ALGORITHMS[algorithm]
    kwargs = {"generator": gen} if cls is Adam else {}
    if threads is None:
        threads = _auto_threads(problem.n_train * layout.n_params)
    with _training_threads(threads) as n_threads:
        algo = cls(problem, x0, **kwargs, **(settings or {}))
        res = run(algo, problem, max_epochs=max_epochs,
                  max_fail=None if algorithm == "br" else max_fail, progress=progress)
    if res.epochs == 0 and init is None:  # the initial random network is no model
        raise ValueError(f"training stopped before its first epoch ({res.stop_reason}): check the {algorithm} "
                         "settings")
    stats = algo.stats() if hasattr(algo, "stats") else {}

    p = {k: v.numpy().copy() for k, v in layout.unpack(res.x).items()}
    model = MlpModel(w1=p["w1"], b1=p["b1"], w2=p.get("w2"), b2=p.get("b2"), w_out=p["w_out"],
                     b_out=float(p["b_out"][0]), in_offset=in_off, in_gain=in_gain,
                     out_offset=float(out_off), out_gain=float(out_gain),
                     sat_lo=X_all.min(axis=0), sat_hi=X_all.max(axis=0), features=features,
                     units=units, activation=activation)
    metrics = {name: nrmse(torch_forward(model, X[idx]), y[idx])
               for name, idx in (("train", tr), ("val", va), ("test", te)) if len(idx)}
    metrics["all"] = nrmse(torch_forward(model, X), y)
    info = TrainInfo(algorithm=algorithm, settings=dict(algo.settings), history=res.history,
                     epochs=res.epochs, best_epoch=res.best_epoch, stop_reason=res.stop_reason,
                     time_s=res.time_s, n_train=len(tr), n_val=len(va), n_test=len(te),
                     n_rest_points=len(Z), metrics=metrics, stats=stats,
                     train_idx=tr, val_idx=va, test_idx=te)
    model.meta = {
        "algorithm": algorithm,
        "settings": jsonable(algo.settings),
        "training_time_s": round(res.time_s, 3),
        "trained_at": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "torch_version": torch.__version__,
        "threads": n_threads,
        "python": platform.python_version(),
        "seed": seed,
        "hidden": list(layout.hidden),
        "split": list(split),
        "max_epochs": max_epochs,
        "max_fail": None if algorithm == "br" else max_fail,
        "epochs": res.epochs,
        "best_epoch": res.best_epoch,
        "stop_reason": res.stop_reason,
        "samples": {"train": len(tr), "val": len(va), "test": len(te), "rest_points": len(Z)},
        "rest_force": {**at_rest.meta(), "target": rest_target, "target_N": round(float(np.mean(y_Z)), 3)
                       if len(Z) else 0.0},
        "control_prior": prior_meta,
        "monotone_prior": mono_meta,
        "metrics": {k: round(v, 6) for k, v in metrics.items()},
        **({"stats": jsonable(stats)} if stats else {}),
        **({"data": data} if data is not None else {}),
    }
    return model, info
