"""Every training setting in one table: its type, range, meaning (with unit) and default.

Two kinds of settings:
  ALGORITHM_TABLES[algorithm]: the `settings` dict of one algorithm (lm, br, scg, adam),
      e.g. {"mu_max": 1e8} or {"lr": 0.01, "batch_size": 1024};
  OPTIONS: every training option (max_epochs, hidden, restarts, seed, ...), one `Option` row
      each: its kind, range, default, unit, meaning, `dampnet train` option and sweep key, the
      one place each default is stated. The request (dampnet.training.request.TrainingRequest),
      the command line's options (dampnet.commands.training_options), the sweep's [training]
      keys (dampnet.sweep.spec.training_params) are made from it; `register` adds a row.
      `hidden` is checked against the runtime's layer limit (dampnet._core.MAX_HIDDEN), the
      feature count against dampnet._core.MAX_INPUTS, the activation against its registry
      (dampnet._core.ACTIVATIONS).

`check_settings(algorithm, settings)` and the rows' checks (`option`, `check_request`, and
`TrainingRequest.check` with the relations between options) are the one place a training's
inputs are validated; every front end passes through them before any training starts
(`dampnet.training.fit`, `dampnet.training.pipeline.train_dataset` = `dampnet.train`, the
algorithms' constructors, `dampnet train` before it loads its data, the sweep's train cells).
An invalid value is a ValueError of one line naming the setting, its meaning and its range.
The error messages, the defaults of the algorithms and `settings_help()` (the --settings help)
all come from these tables.

Why every value is bounded: an unbounded count builds lists forever (--restarts 1e20), and
LM's damping loop only ends when mu grows (mu > 0, mu_inc > 1); its loop is bounded as well
(MAX_MU_INCREASES per epoch), so that no setting can hang it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from dampnet.data.preprocess import AUTO_DECIMATE_RULE
from dampnet.model import ACTIVATIONS
from dampnet.schema import show
from dampnet.training.rest_points import REST_TARGETS
from dampnet.training.valve_choice import VALVE_CHOICES

#: the largest epoch count (max_epochs, max_fail, Adam's cosine_epochs)
MAX_EPOCHS = 1_000_000
#: the largest number of restarts (each is a full training)
MAX_RESTARTS = 1_000
#: the largest number of worker processes or torch threads
MAX_PROCESSES = 1_024
#: the largest seed (numpy and torch take 64-bit seeds)
MAX_SEED = 2**63 - 1
#: LM and BR raise mu at most this many times in one epoch, then stop training with that reason
#: (the defaults, mu_inc 10 from the floor 1e-20 to mu_max 1e10, need 30)
MAX_MU_INCREASES = 200
#: the largest batch size, restart period and decimation factor (samples or iterations)
MAX_COUNT = 10**9

#: restarts `dampnet train` runs unless --restarts says otherwise (bench/RESULTS.md "Restarts")
DEFAULT_RESTARTS = 6
#: the automatic restarts' budget: training rows (after decimation) times restarts, for LM (BR trains
#: once, BR_MAX_ROWS: the plans of up to 30,000 rows). The thesis plan's 45,780 rows (at 100 Hz,
#: dampnet.data.preprocess.DECIMATE_LARGE_HZ) get 2, in parallel on 2 cores: one in three of its single
#: trainings settles in a worse minimum, which the combined score tells apart (issue 33, bench/RESULTS.md
#: "Two restarts on the thesis plan"); LM asked for on the 5 x 8 plan (25,221 rows) gets 3,
#: DEFAULT_RESTARTS up to 16,666 rows.
RESTART_ROWS_BUDGET = 100_000
#: the automatic algorithm (`dampnet train`'s default, `--algorithm auto`): Bayesian regularisation up
#: to this many training rows, Levenberg-Marquardt beyond. Why (issue 33, bench/LOG.md "Few dyno
#: tests"): on the 5 x 8 and 6 x 8 plans (25,221 and 28,021 rows) one BR training per seed, with the
#: control prior, was held out at 0.50x and 0.53x the lookup table's error with seeds agreeing to
#: 1.32x and 1.17x (rest points at 0 N; 0.41x with the estimated force at rest, the default since), where LM
#: needed 6 restarts for 0.56x and 1.84x on 5 x 8; on the thesis plan (91,518
#: rows) BR was no better (seed 0: 3.08x the noise floor against LM's 2.88x) and several times slower.
BR_MAX_ROWS = 30_000
#: the restart scores (dampnet.training.restarts says what each measures)
SCORES = ("combined", "interpolation", "lolo")
#: how restarts are ranked unless restart_score says otherwise (dampnet.training.restarts says why)
DEFAULT_SCORE = "combined"


@dataclass(frozen=True)
class Setting:
    """One setting: `kind` "real" (a finite number), "whole" (an integer), "pair" (two reals) or
    "choice" (one of the words `choices`; low and high unused); its range [low, high] (an end
    excluded when `open_low` / `open_high`); None allowed when `none` says what None means."""

    name: str
    kind: str
    low: float
    high: float
    default: Any
    meaning: str
    open_low: bool = False
    open_high: bool = False
    none: str | None = None
    cli: str | None = None  # the command-line option, for a request option that has one
    choices: tuple[str, ...] = ()  # kind "choice": the words allowed

    def range_text(self) -> str:
        """The range in interval notation, e.g. (0, 1] or [1, 1000000]; a choice's words."""
        if self.kind == "choice":
            return ", ".join(self.choices)
        lo, hi = (f"{v:g}" if self.kind != "whole" else str(int(v)) for v in (self.low, self.high))
        return f"{'(' if self.open_low else '['}{lo}, {hi}{')' if self.open_high else ']'}"

    def expected(self) -> str:
        if self.kind == "choice":
            return f"one of {self.range_text()}"
        what = {"real": "a number", "whole": "a whole number", "pair": "two numbers, each"}[self.kind]
        return f"{what} in {self.range_text()}" + (f" or null ({self.none})" if self.none else "")

    def _in_range(self, v: float) -> bool:
        above = v > self.low if self.open_low else v >= self.low
        below = v < self.high if self.open_high else v <= self.high
        return above and below

    def _scalar(self, v: Any) -> float | int | None:
        """v as a number of this kind in range, or None when it is not."""
        if isinstance(v, (bool, np.bool_)):
            return None
        if self.kind == "whole":
            if not isinstance(v, (int, np.integer)):
                return None
            v = int(v)
        else:
            if not isinstance(v, (int, float, np.integer, np.floating)):
                return None
            try:
                v = float(v)
            except OverflowError:  # an int beyond any float, e.g. JSON's 1 followed by 400 zeros
                return None
            if not math.isfinite(v):
                return None
        return v if self._in_range(v) else None

    def check(self, value: Any, where: str) -> Any:
        """The value (ints as int, reals as float, a pair as a tuple); ValueError naming
        `where` (the setting and its meaning) and the range otherwise."""
        if value is None and self.none:
            return None
        if self.kind == "choice":
            if isinstance(value, str) and value in self.choices:
                return value
            raise ValueError(f"{where}: expected {self.expected()}, got {show_value(value)}")
        if self.kind == "pair":
            ok = isinstance(value, (list, tuple)) and len(value) == 2
            out = tuple(self._scalar(v) if ok else None for v in (value if ok else ()))
            ok = ok and None not in out
        else:
            out = self._scalar(value)
            ok = out is not None
        if not ok:
            raise ValueError(f"{where}: expected {self.expected()}, got {show_value(value)}")
        return out


def show_value(value: Any) -> str:
    """A value for an error message: a short list is shown whole (betas [0.9, 2])."""
    if isinstance(value, (list, tuple)) and len(value) <= 4:
        return "[" + ", ".join(show(v) for v in value) + "]"
    return show(value)


def _table(*settings: Setting) -> dict[str, Setting]:
    return {s.name: s for s in settings}


# -- the algorithms' settings (MATLAB's trainlm / trainbr / trainscg defaults; Adam's) ---------------

_MU = dict(low=1e-20, high=1e30)
_LM_LIKE = (
    Setting("mu_dec", "real", 0, 1, 0.1, "the factor mu shrinks by after an accepted step",
            open_low=True, open_high=True),
    Setting("mu_inc", "real", 1, 1e10, 10.0, "the factor mu grows by after a rejected step", open_low=True),
    Setting("mu_max", "real", **_MU, default=1e10, meaning="the damping at which training stops"),
    Setting("min_grad", "real", 0, 1, 1e-7, "the gradient norm (scaled MSE per weight) at which training stops"),
)

#: each algorithm's name in words (help texts, the demo's report, "auto"'s note)
ALGORITHM_NAMES = {"lm": "Levenberg-Marquardt", "br": "Bayesian regularisation", "scg": "scaled conjugate gradient",
                   "adam": "Adam"}

ALGORITHM_TABLES: dict[str, dict[str, Setting]] = {
    "lm": _table(Setting("mu", "real", **_MU, default=1e-3, meaning="the initial damping added to JᵀJ's diagonal"),
                 *_LM_LIKE),
    "br": _table(Setting("mu", "real", **_MU, default=5e-3, meaning="the initial damping added to JᵀJ's diagonal"),
                 *_LM_LIKE),
    "scg": _table(
        Setting("sigma", "real", 0, 1, 5e-5, "the weight change for the second-derivative estimate",
                open_low=True),
        Setting("lambda", "real", 0, 1e6, 5e-7, "the initial scale of the Hessian model", open_low=True),
        Setting("min_grad", "real", 0, 1, 1e-6, "the gradient norm (scaled MSE per weight) at which training stops"),
        Setting("restart", "whole", 1, MAX_COUNT, None, "restart with steepest descent every this many iterations",
                none="the number of weights"),
    ),
    "adam": _table(
        Setting("lr", "real", 0, 1, 1e-3, "the learning rate, in scaled weight units per step", open_low=True),
        Setting("betas", "pair", 0, 1, (0.9, 0.999), "the decay rates of the gradient's mean and square",
                open_high=True),
        Setting("eps", "real", 0, 1, 1e-8, "the term added to the root mean square of the gradient", open_low=True),
        Setting("batch_size", "whole", 1, MAX_COUNT, None, "training samples per step",
                none="the whole training set"),
        Setting("lr_decay", "real", 0, 1, 1.0, "the factor the learning rate is multiplied by each epoch",
                open_low=True),
        Setting("cosine_epochs", "whole", 1, MAX_EPOCHS, None, "epochs of a half-cosine decay from lr to lr_min",
                none="no cosine schedule"),
        Setting("lr_min", "real", 0, 1, 0.0, "the learning rate the cosine schedule ends at"),
    ),
}

#: relations between one algorithm's settings: (what must hold, the settings it involves, the test)
RELATIONS: dict[str, list[tuple[str, tuple[str, ...], Callable[[Mapping[str, Any]], bool]]]] = {
    "lm": [("mu <= mu_max", ("mu", "mu_max"), lambda s: s["mu"] <= s["mu_max"])],
    "br": [("mu <= mu_max", ("mu", "mu_max"), lambda s: s["mu"] <= s["mu_max"])],
    "scg": [],
    "adam": [("lr_min <= lr", ("lr_min", "lr"), lambda s: s["lr_min"] <= s["lr"]),
             ("lr_decay 1 with cosine_epochs (one schedule at a time)", ("cosine_epochs", "lr_decay"),
              lambda s: s["cosine_epochs"] is None or s["lr_decay"] == 1.0)],
}


#: Settings train_dataset (dampnet train, the demo, the sweep) uses unless `settings` overrides
#: them. Adam's own defaults (full batch, lr 1e-3: one small step per epoch) need thousands of
#: epochs on dyno data; mini-batches of 128 with lr 1e-2 decaying 2 %/epoch reach about 0.012
#: NRMSE in ~50 epochs on tests/python/test_train_cli.py's small plan (full batch: 0.066 after 150).
TRAIN_DEFAULTS = {"adam": {"batch_size": 128, "lr": 1e-2, "lr_decay": 0.98}}


def train_settings(algorithm: Any, settings: Any) -> Any:
    """The settings train_dataset gives fit(): TRAIN_DEFAULTS's for `algorithm`, overridden by
    `settings` (anything but a mapping is passed on as it is, for check_settings to name)."""
    if settings is not None and not isinstance(settings, Mapping):
        return settings
    base = TRAIN_DEFAULTS.get(algorithm, {}) if isinstance(algorithm, str) else {}
    return {**base, **(settings or {})}


def defaults(algorithm: str) -> dict[str, Any]:
    """The algorithm's default settings."""
    return {name: s.default for name, s in ALGORITHM_TABLES[algorithm].items()}


def check_algorithm(algorithm: Any) -> str:
    if not isinstance(algorithm, str) or algorithm not in ALGORITHM_TABLES:
        raise ValueError(f"algorithm (--algorithm): expected one of {', '.join(ALGORITHM_TABLES)}, "
                         f"got {show(algorithm)}")
    return algorithm


def check_settings(algorithm: str, settings: Mapping[str, Any] | None) -> dict[str, Any]:
    """The algorithm's full settings (defaults, overridden by `settings`), each checked against its
    table entry; ValueError of one line naming the first bad setting, an unknown key or a broken
    relation."""
    table = ALGORITHM_TABLES[check_algorithm(algorithm)]
    settings = {} if settings is None else settings
    if not isinstance(settings, Mapping):
        raise ValueError(f"settings ({algorithm}): expected an object of setting names and values, "
                         f"got {show(settings)}")
    unknown = [str(k) for k in settings if k not in table]
    if unknown:
        raise ValueError(f"{algorithm}: unknown settings {', '.join(map(repr, unknown))}; the {algorithm} "
                         f"settings are {', '.join(table)}")
    out = defaults(algorithm)
    for name, value in settings.items():
        out[name] = table[name].check(value, f"{algorithm} setting {name} ({table[name].meaning})")
    for what, keys, holds in RELATIONS[algorithm]:
        if not holds(out):
            given = ", ".join(f"{k} {show(out[k])}" for k in keys)
            raise ValueError(f"settings ({algorithm}): {what} expected, got {given}")
    return out


def check_hidden(hidden: Any) -> tuple[int, ...]:
    """One or two hidden layer sizes: layer 1 in 1..the runtime's DN_MAX_HIDDEN, or both in
    1..DN_MAX_HIDDEN2 when there are two; ValueError otherwise."""
    from dampnet import _core

    caps = (int(_core.MAX_HIDDEN), int(_core.MAX_HIDDEN2))
    try:
        sizes = tuple(hidden) if not isinstance(hidden, (str, bytes)) else None
    except TypeError:
        sizes = (hidden,)
    ok = sizes is not None and len(sizes) in (1, 2) and all(
        isinstance(h, (int, np.integer)) and not isinstance(h, (bool, np.bool_)) and 1 <= h <= cap
        for h, cap in zip(sizes, caps)) and (len(sizes) == 1 or sizes[0] <= caps[1])
    if not ok:
        raise ValueError(f"hidden (--hidden): expected one or two layer sizes, whole numbers: layer 1 in "
                         f"[1, {caps[0]}], layer 2 in [1, {caps[1]}], both in [1, {caps[1]}] when there are two "
                         f"(the runtime's limits, DN_MAX_HIDDEN and DN_MAX_HIDDEN2), got {show_value(hidden)}")
    return tuple(int(h) for h in sizes)


def check_inputs(features: Sequence[str]) -> None:
    """ValueError when there are more features than the runtime's DN_MAX_INPUTS."""
    from dampnet import _core

    cap = int(_core.MAX_INPUTS)
    if len(features) > cap:
        raise ValueError(f"features (--features): {len(features)} given ({', '.join(features)}); the runtime's "
                         f"models take at most {cap} inputs (DN_MAX_INPUTS)")


# -- the options of a training request: one table ------------------------------------------------

#: restarts and algorithm: the word for "as the data allow" (dampnet.training.restarts: auto_restarts,
#: auto_algorithm)
AUTO = "auto"


@dataclass(frozen=True)
class Option(Setting):
    """One training option, its one row: a Setting (kind, range, default, `meaning`: the error
    messages' words) with `unit` and `doc` (the help's words, default the meaning). `check_value`
    (value -> value, ValueError) checks a value when given (kind "other": else the request does,
    e.g. settings with their algorithm).
    How it is spelled: `cli` the `dampnet train` option (`compare-algorithms`' too unless
    `train_only`), `cli_help` the command line's own words, `cli_default` the command line's
    default when it is not the table's (AUTO), `metavar`, `parse` its text to a value (default: by
    kind, dampnet.commands.training_options); `sweep` the [training] key (None: not in the sweep),
    `axis` a main axis. `request` False: not a TrainingRequest field (how the work runs: workers,
    threads; fit()'s own: rest_fraction); `compare` False: not part of the request's identity."""

    unit: str = ""
    doc: str = ""
    check_value: Callable[[Any], Any] | None = None
    cli_help: str = ""
    cli_default: Any = None
    metavar: str | None = None
    train_only: bool = False
    sweep: str | None = None
    axis: bool = False
    request: bool = True
    compare: bool = True

    def help(self) -> str:
        """What the option means, with its unit (the CLI's and the sweep's help start with it)."""
        return (self.doc or self.meaning) + (f" [{self.unit}]" if self.unit else "")

    def check(self, value: Any, where: str) -> Any:
        if self.check_value is not None:
            return self.check_value(value)
        return value if self.kind == "other" else super().check(value, where)


def _check_activation(value: Any) -> str:
    if not isinstance(value, str) or value not in ACTIVATIONS:
        raise ValueError(f"activation (--activation): expected one of {', '.join(ACTIVATIONS)}, got {show(value)}")
    return value


def _check_features(value: Any) -> tuple[str, ...] | None:
    if value is not None:
        check_inputs(list(value))
    return value


def _check_algorithm(value: Any) -> str:
    """An algorithm of ALGORITHM_TABLES or AUTO (a request's; fit() takes no AUTO: check_algorithm)."""
    if not isinstance(value, str) or (value != AUTO and value not in ALGORITHM_TABLES):
        raise ValueError(f"algorithm (--algorithm): expected {AUTO} or one of {', '.join(ALGORITHM_TABLES)}, "
                         f"got {value!r}")
    return value


_O = Option
#: every training option, one row each: its default, range and unit here and nowhere else; the
#: `dampnet train` options, the sweep's [training] keys (in this order: the cells' order),
#: TrainingRequest's fields and the checks are made from it (docs/recipes.md, "Training requests")
OPTIONS: dict[str, Option] = {}


def register(row: Option) -> Option:
    """Add a training option (a row of OPTIONS; its name new); returns it."""
    if row.name in OPTIONS:
        raise ValueError(f"training option {row.name!r} is registered already")
    OPTIONS[row.name] = row
    return row


for _row in (
    _O("algorithm", "other", 0, 0, "lm", "the training algorithm", check_value=_check_algorithm,
       doc=f"the training algorithm ('auto': br up to {BR_MAX_ROWS:,} training rows, lm beyond)",
       cli="--algorithm", cli_default=AUTO, choices=(AUTO, *ALGORITHM_TABLES), cli_help="auto (the default; "
       "bench/RESULTS.md 'Few dyno tests'), " + ", ".join(f"{k} {v}" for k, v in ALGORITHM_NAMES.items()),
       sweep="algorithms", axis=True),
    _O("add", "other", 0, 0, (), "effects whose features and terms are added (dampnet.effects)", cli="--add",
       metavar="EFFECT", sweep="add", axis=True),
    _O("features", "other", 0, 0, None, "the input features, in order", none="velocity, acceleration and the data's "
       "control", doc="the input features, in order (default: velocity, acceleration and the data's control)",
       check_value=_check_features, cli="--features", cli_help="comma-separated, e.g. "
       "velocity,acceleration,voltage,temperature", sweep="features", axis=True),
    _O("seed", "whole", 0, MAX_SEED, 0, "the random seed of the split, the rest points and the weights",
       doc="the seed of the split, rest points and weights (restarts: the first)", cli="--seed", sweep="seeds",
       axis=True),
    _O("hidden", "other", 0, 0, (30,), "hidden layer sizes", check_value=check_hidden,
       cli="--hidden", cli_help="e.g. 30 or 20,10", sweep="hidden", axis=True),
    _O("decimate", "whole", 1, MAX_COUNT, None, "keep every N-th training sample", none=AUTO_DECIMATE_RULE,
       doc=f"every N-th training sample is kept (default: {AUTO_DECIMATE_RULE})", cli="--decimate",
       cli_help="N, or 'auto' (the default; 25 at 5 kHz, 50 on large data)", sweep="decimate"),
    _O("max_epochs", "whole", 1, MAX_EPOCHS, 1000, "the epoch limit", cli="--max-epochs", sweep="max_epochs"),
    _O("max_fail", "whole", 1, MAX_EPOCHS, 6, "epochs of rising validation error that stop training",
       sweep="max_fail"),
    _O("holdout_voltage", "real", -1e15, 1e15, 2.25, "the control level held out", unit="V or A",
       none="hold nothing out by level", doc="the control level whose tests are held out",
       cli="--holdout-voltage", cli_help="every test at this nominal control value; 'none' for none",
       sweep="holdout_voltage"),
    _O("activation", "choice", 0, 0, "tanh", "the hidden layers' activation", choices=ACTIVATIONS,
       check_value=_check_activation,
       cli="--activation", cli_help="tanh is MATLAB's tansig", sweep="activation"),
    _O("restarts", "whole", 1, MAX_RESTARTS, 1, "trainings from different seeds, the best kept",
       doc="trainings from different seeds, the best kept ('auto': 1 with br, or --average's count; otherwise "
       f"{DEFAULT_RESTARTS} with two control levels or more, fewer beyond "
       f"{RESTART_ROWS_BUDGET // DEFAULT_RESTARTS:,} training rows, else 1)", cli="--restarts", cli_default=AUTO,
       metavar="N", cli_help="N (--seed first), never looking at the hold-out; 1: train once. model.json records "
       "every restart (meta.restarts)", train_only=True, sweep="restarts"),
    _O("average", "whole", 1, MAX_RESTARTS, 1, "the best restarts averaged into one network", cli="--average",
       metavar="K", cli_help="K, into one network K times as wide (their mean output, exactly; the width must fit "
       "the runtime's DN_MAX_HIDDEN, 384 here, e.g. 6 x 30 hidden): lower held-out error than one seed or one wide "
       "network (bench/RESULTS.md 'Inside the envelope'); 1: the best restart alone", train_only=True,
       sweep="average"),
    _O("restart_score", "choice", 0, 0, DEFAULT_SCORE, "how restarts are ranked", choices=SCORES,
       doc=f"how restarts are ranked: {', '.join(SCORES)} (default {DEFAULT_SCORE})", cli="--restart-score",
       train_only=True, sweep="restart_score"),
    _O("control_prior", "real", 0, 1e6, 1.0, "the weight of the prior that the force between the tested control "
       "levels follows the smooth curve through theirs (dampnet.training.control_prior); 0: off",
       doc="the weight of the prior that the force between the tested control levels follows the natural cubic "
       "spline through theirs at the same motion (a straight line between two, as a lookup table interpolates); "
       "against the data's squared error, per row; 0: off", cli="--control-prior", metavar="W",
       cli_help="dampnet.training.control_prior; bench/RESULTS.md 'Few dyno tests'", sweep="control_prior"),
    _O("monotone_prior", "real", 0, 1e6, 0.0, "the weight of the prior that the force rises with velocity between "
       "and at the tested control levels (dampnet.training.monotone_prior); 0: off",
       doc="the weight of the prior that the force rises with velocity, at the training rows and at their motion "
       "with the control anywhere between the lowest and highest tested level (only where it falls does it act); "
       "its mean square against the data's; 0: off (100 when wanted)", cli="--monotone-prior", metavar="W",
       cli_help="dampnet.training.monotone_prior", sweep="monotone_prior"),
    _O("rest_target", "choice", 0, 0, "estimated", "the rest points' force: estimated (the damper's own force at "
       "rest, dampnet.training.rest_points), zero (0 N, the thesis's), or none (no rest points)",
       choices=REST_TARGETS, doc="the rest points' force: estimated (the damper's own force at rest, fitted to the "
       "training samples near v = 0), zero (0 N, the thesis's) or none (no rest points: "
       "dampnet.training.rest_points)", cli="--rest-target", sweep="rest_target"),
    _O("holdout_tests", "other", 0, 0, (), "test ids held out as well", cli="--holdout-tests",
       cli_help="comma-separated"),
    _O("settings", "other", 0, 0, None, "the algorithm's settings (dampnet.training.settings)", cli="--settings"),
    _O("terms", "other", 0, 0, (), "physics terms (dampnet.terms)", cli="--terms", cli_help='JSON, e.g. '
       '\'[{"kind": "position_poly"}]\'; terms without "params" are fitted by least squares, the MLP learns the rest'),
    _O("valve", "choice", 0, 0, "off", "whether a free valve term (bleed and blow-off per direction, dampnet.terms) "
       "goes under the network", choices=VALVE_CHOICES,
       doc="whether a free valve term (bleed and blow-off per direction, fitted first; the network learns what it "
       "leaves) goes under the network: on, off, or auto (trained both ways, the hybrid kept when its validation "
       "error is 5 percent lower at least, on training tests at 3 control levels or more: dampnet.training.valve_choice)", cli="--valve", cli_default=AUTO, train_only=True,
       cli_help="auto costs a second training; model.json records both errors (meta.valve)", sweep="valve"),
    _O("diagnosis", "other", 0, 0, None, "a diagnosis whose estimated parameters the added effects take (default: "
       "estimated from the data)", cli="--diagnosis", metavar="FILE", cli_help="the JSON of `dampnet diagnose "
       "--json FILE` (the same additions as the demo's improve stage)", compare=False),
    _O("diagnosis_source", "other", 0, 0, None, "the diagnosis's file (for messages)"),
    _O("feature_params", "other", 0, 0, None, "feature parameters (a lag's time constant [s], ...)"),
    _O("acceleration_window", "real", 0, 10, None, "a moving-average window for the derived acceleration, as the "
       "thesis did (0.02)", unit="s", open_low=True,
       none="the zero-phase derivative, within 0.5 % to 20 Hz (dampnet.data.derivative)"),
    _O("workers", "whole", 1, MAX_PROCESSES, None, "processes the restarts run in", none="the local cores",
       cli="--workers", metavar="N", cli_help="one torch thread each", train_only=True, request=False),
    _O("threads", "whole", 1, MAX_PROCESSES, None, "torch's and numpy's BLAS threads during training",
       none="1 for small problems, else the idle cores", request=False),
    _O("rest_fraction", "real", 0, 1, 0.01, "rest points added, as a fraction of the training samples",
       request=False),
):
    register(_row)


def option(name: str, value: Any) -> Any:
    """`value` of request option `name` checked against OPTIONS (the message names --name too)."""
    s = OPTIONS[name]
    return s.check(value, f"{name} ({s.cli + ', ' if s.cli else ''}{s.meaning})")


def options_markdown() -> str:
    """The options table as Markdown (docs/training.md's "Training options", checked against it by
    tests/python/test_training_options.py): one line per row."""
    def value_text(row: Option) -> str:
        if row.choices:
            return ", ".join(row.choices)
        if row.kind in ("whole", "real", "pair"):
            return row.range_text() + (" or none" if row.none else "") + (f" or {AUTO}" if row.cli_default == AUTO else "")
        return "see the meaning"

    def default_text(row: Option) -> str:
        d = row.default
        if d is None or d == ():
            text = row.none or "none"
        else:
            text = ",".join(map(str, d)) if isinstance(d, tuple) else f"{d:g}" if isinstance(d, float) else str(d)
        return text + (f" (`dampnet train`: {row.cli_default})" if row.cli_default is not None else "")

    lines = ["| option | `dampnet train` | sweep key | values | default | unit | meaning |",
             "|---|---|---|---|---|---|---|"]
    for row in OPTIONS.values():
        cells = [row.name, f"`{row.cli}`" if row.cli else "", row.sweep or "", value_text(row), default_text(row),
                 row.unit, (row.doc or row.meaning).replace("|", "/")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def command_defaults() -> dict[str, Any]:
    """What `dampnet train` trains with where it differs from the Python defaults (the rows'
    cli_default: algorithm, restarts and valve "auto"): the demo and the loop train the same way."""
    return {name: row.cli_default for name, row in OPTIONS.items() if row.cli_default is not None and row.request}


def option_defaults() -> dict[str, Any]:
    """Every option's default by name (OPTIONS')."""
    return {name: row.default for name, row in OPTIONS.items()}


_UNSET = object()

#: the options fit() takes (dampnet.training.fitting.fit), besides the data and how it runs
FIT_OPTIONS = ("algorithm", "hidden", "activation", "seed", "max_epochs", "max_fail", "rest_fraction", "settings",
               "control_prior", "monotone_prior", "rest_target", "threads")


def check_request(*, settings: Any = _UNSET, **options: Any) -> dict[str, Any]:
    """Check the given options of OPTIONS by name (only those passed; `algorithm` one that trains,
    not "auto"; `settings` with its algorithm). Returns the checked values by name (settings: the
    algorithm's full settings). ValueError of one line naming the first bad one; TypeError for an
    unknown name. Cheap: call it before any work."""
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise TypeError(f"check_request: unknown options {unknown}")
    out = {name: check_algorithm(value) if name == "algorithm" else option(name, value)
           for name, value in options.items()}
    if settings is not _UNSET:
        if "algorithm" not in options:
            raise TypeError("check_request: settings need their algorithm")
        out["settings"] = check_settings(options["algorithm"], settings)
    return out


def fit_options(**given: Any) -> dict[str, Any]:
    """fit()'s options (FIT_OPTIONS): the given ones checked, the others the table's defaults;
    `settings` stays the overrides given (the algorithm fills in its defaults)."""
    unknown = sorted(set(given) - set(FIT_OPTIONS))
    if unknown:
        raise TypeError(f"fit: unknown option(s) {', '.join(map(repr, unknown))}; fit's options are "
                        + ", ".join(FIT_OPTIONS))
    out = {name: OPTIONS[name].default for name in FIT_OPTIONS}
    out.update(given)
    checked = check_request(**{k: v for k, v in out.items() if k != "settings"}, settings=out["settings"])
    return {**out, **{k: v for k, v in checked.items() if k != "settings"}}


def settings_help(overrides: Mapping[str, Mapping[str, Any]] | None = None) -> str:
    """Every algorithm's settings with their ranges and defaults (the --settings help, docs/training.md);
    `overrides` {algorithm: {name: value}}: defaults a front end uses instead (train_dataset's)."""
    parts = []
    for algo, table in ALGORITHM_TABLES.items():
        mine = (overrides or {}).get(algo, {})
        items = [f"{s.name} {s.range_text()}{' or null' if s.none else ''} "
                 f"(default {_default_text(s, mine.get(s.name, s.default))})" for s in table.values()]
        parts.append(f"{algo}: " + ", ".join(items))
    return "; ".join(parts)


def _default_text(s: Setting, value: Any) -> str:
    if value is None:
        return f"null, {s.none}"
    if isinstance(value, str):  # a choice
        return value
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    return f"{value:g}"
