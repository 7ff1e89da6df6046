"""Every training setting in one table: its type, range, meaning (with unit) and default.

Two kinds of settings:
  ALGORITHM_TABLES[algorithm]: the `settings` dict of one algorithm (lm, br, scg, adam),
      e.g. {"mu_max": 1e8} or {"lr": 0.01, "batch_size": 1024};
  OPTIONS: the options of a training request (max_epochs, restarts, seed, ...), the same
      for every algorithm; `hidden` is checked against the runtime's layer limit
      (dampnet._core.MAX_HIDDEN) and the feature count against dampnet._core.MAX_INPUTS.

`check_settings(algorithm, settings)` and `check_request(...)` are the one place a training's
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
from dampnet.schema import show
from dampnet.training.rest_points import REST_TARGETS

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


# -- the options of a training request ------------------------------------------------------------

OPTIONS = _table(
    Setting("max_epochs", "whole", 1, MAX_EPOCHS, 1000, "the epoch limit", cli="--max-epochs"),
    Setting("max_fail", "whole", 1, MAX_EPOCHS, 6, "epochs of rising validation error that stop training"),
    Setting("seed", "whole", 0, MAX_SEED, 0, "the random seed of the split, the rest points and the weights",
            cli="--seed"),
    Setting("restarts", "whole", 1, MAX_RESTARTS, 1, "trainings from different seeds, the best kept",
            cli="--restarts"),
    Setting("average", "whole", 1, MAX_RESTARTS, 1, "the best restarts averaged into one network", cli="--average"),
    Setting("workers", "whole", 1, MAX_PROCESSES, None, "processes the restarts run in", none="the local cores",
            cli="--workers"),
    Setting("threads", "whole", 1, MAX_PROCESSES, None, "torch's and numpy's BLAS threads during training",
            none="1 for small problems, else the idle cores"),
    Setting("decimate", "whole", 1, MAX_COUNT, None, "keep every N-th training sample", none=AUTO_DECIMATE_RULE,
            cli="--decimate"),
    Setting("rest_fraction", "real", 0, 1, 0.01, "rest points added, as a fraction of the training samples"),
    Setting("rest_target", "choice", 0, 0, "estimated", "the rest points' force: estimated (the damper's own "
            "force at rest, dampnet.training.rest_points), zero (0 N, the thesis's), or none (no rest points)",
            cli="--rest-target", choices=REST_TARGETS),
    Setting("holdout_voltage", "real", -1e15, 1e15, 2.25, "the control level held out [V or A]",
            none="hold nothing out by level", cli="--holdout-voltage"),
    Setting("control_prior", "real", 0, 1e6, 1.0, "the weight of the prior that the force between the tested "
            "control levels follows the smooth curve through theirs (dampnet.training.control_prior); 0: off",
            cli="--control-prior"),
    Setting("monotone_prior", "real", 0, 1e6, 0.0, "the weight of the prior that the force rises with velocity "
            "between and at the tested control levels (dampnet.training.monotone_prior); 0: off",
            cli="--monotone-prior"),
    Setting("acceleration_window", "real", 0, 10, None, "the smoothing window of the derived acceleration [s]",
            open_low=True, none="20 ms"),
)


def option(name: str, value: Any) -> Any:
    """`value` of request option `name` checked against OPTIONS (the message names --name too)."""
    s = OPTIONS[name]
    return s.check(value, f"{name} ({s.cli + ', ' if s.cli else ''}{s.meaning})")


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


_UNSET = object()


def check_request(*, algorithm: Any = _UNSET, settings: Any = _UNSET, hidden: Any = _UNSET,
                  activation: Any = _UNSET, features: Any = _UNSET, **options: Any) -> dict[str, Any]:
    """Check the given parts of a training request (only those passed): the algorithm and its
    settings, the hidden sizes and activation, the feature count and any OPTIONS by name (max_epochs=...,
    restarts=...). Returns the checked values by name (settings: the algorithm's full settings).
    ValueError of one line naming the first bad one. Cheap: call it before any work."""
    out: dict[str, Any] = {}
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise TypeError(f"check_request: unknown options {unknown}")
    if algorithm is not _UNSET:
        out["algorithm"] = check_algorithm(algorithm)
    if hidden is not _UNSET:
        out["hidden"] = check_hidden(hidden)
    if activation is not _UNSET:
        from dampnet.model import ACTIVATIONS

        if not isinstance(activation, str) or activation not in ACTIVATIONS:
            raise ValueError(f"activation (--activation): expected one of {', '.join(ACTIVATIONS)}, "
                             f"got {show(activation)}")
        out["activation"] = activation
    if features is not _UNSET and features is not None:
        check_inputs(list(features))
    for name, value in options.items():
        out[name] = option(name, value)
    if settings is not _UNSET:
        if algorithm is _UNSET:
            raise TypeError("check_request: settings need their algorithm")
        out["settings"] = check_settings(algorithm, settings)
    return out


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
