"""A training request, and the one way to train it: `dampnet train`, the sweep's [training]
cells and the Python `dampnet.train` all build a `TrainingRequest` and call `train`, which
returns the model WITH its training envelope, so every way of training saves the same model
directory (model.json, metrics.json, model.h, envelope.npz, envelope.json).

    req = TrainingRequest(algorithm="lm", restarts=6, average=2, add=("valve_lag",))
    trained = train(dataset, req)              # or train(dataset, algorithm="lm", restarts=6)
    model, info, split = trained               # as dampnet.train always returned
    trained.envelope, trained.metrics          # the envelope (dampnet.envelope), metrics.json's dict
    trained.save("model_dir")                  # = dampnet train's MODEL_DIR

The request's fields (`FIELDS`: each with its unit, meaning, `dampnet train` option and sweep
key) are checked by dampnet.training.settings, the one place training values are validated,
before any data are loaded (`TrainingRequest.check`). `plan(dataset, request)` does what needs
the data (each added effect's features and terms, dampnet.training.pipeline.apply_additions,
with the diagnosis's parameters or ones estimated from the data; restarts "auto" resolved,
dampnet.training.restarts.auto_restarts), `Plan.run` trains. How the work runs (progress,
threads, restart workers) is not part of the request: it does not change the model.

Adding a training option: a field of TrainingRequest with its FIELDS entry, its check in
dampnet.training.settings, and its use in `Plan.run` (docs/recipes.md, "Training requests").
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Callable, Mapping, Sequence

from dampnet.data.preprocess import AUTO_DECIMATE_RULE
from dampnet.training.restarts import BR_MAX_ROWS, DEFAULT_RESTARTS, DEFAULT_SCORE, RESTART_ROWS_BUDGET, SCORES

#: restarts and algorithm: the word for "as the data allow" (dampnet.training.restarts: auto_restarts,
#: auto_algorithm)
AUTO = "auto"


@dataclass(frozen=True)
class RequestField:
    """How one request field is spelled and what it means: `cli` the `dampnet train` option,
    `sweep` the [training] key (None: not in the sweep), `unit` ("" for none), `doc`."""

    name: str
    cli: str | None
    sweep: str | None
    unit: str
    doc: str

    def help(self) -> str:
        return self.doc + (f" [{self.unit}]" if self.unit else "")


FIELDS: dict[str, RequestField] = {f.name: f for f in (
    RequestField("features", "--features", "features", "", "the input features, in order (default: "
                 "velocity, acceleration and the data's control)"),
    RequestField("algorithm", "--algorithm", "algorithms", "", f"the training algorithm ('auto': br up to "
                 f"{BR_MAX_ROWS:,} training rows, lm beyond)"),
    RequestField("hidden", "--hidden", "hidden", "", "hidden layer sizes"),
    RequestField("activation", "--activation", "activation", "", "the hidden layers' activation"),
    RequestField("holdout_voltage", "--holdout-voltage", "holdout_voltage", "V or A",
                 "the control level whose tests are held out"),
    RequestField("holdout_tests", "--holdout-tests", None, "", "test ids held out as well"),
    RequestField("decimate", "--decimate", "decimate", "", "every N-th training sample is kept (default: "
                 f"{AUTO_DECIMATE_RULE})"),
    RequestField("rest_target", "--rest-target", "rest_target", "", "the rest points' force: estimated (the "
                 "damper's own force at rest, fitted to the training samples near v = 0), zero (0 N, the "
                 "thesis's) or none (no rest points: dampnet.training.rest_points)"),
    RequestField("max_epochs", "--max-epochs", "max_epochs", "", "the epoch limit"),
    RequestField("max_fail", None, "max_fail", "", "epochs of rising validation error that stop training"),
    RequestField("seed", "--seed", "seeds", "", "the seed of the split, rest points and weights (restarts: the first)"),
    RequestField("settings", "--settings", None, "", "the algorithm's settings (dampnet.training.settings)"),
    RequestField("terms", "--terms", None, "", "physics terms (dampnet.terms)"),
    RequestField("add", "--add", "add", "", "effects whose features and terms are added (dampnet.effects)"),
    RequestField("diagnosis", "--diagnosis", None, "", "a diagnosis whose estimated parameters the "
                 "added effects take (default: estimated from the data)"),
    RequestField("restarts", "--restarts", "restarts", "", "trainings from different seeds, the best kept "
                 f"('auto': 1 with br, or --average's count; otherwise {DEFAULT_RESTARTS} with two control levels or "
                 f"more, fewer beyond {RESTART_ROWS_BUDGET // DEFAULT_RESTARTS:,} training rows, else 1)"),
    RequestField("restart_score", "--restart-score", "restart_score", "", "how restarts are ranked: "
                 f"{', '.join(SCORES)} (default {DEFAULT_SCORE})"),
    RequestField("average", "--average", "average", "", "the best restarts averaged into one network"),
    RequestField("control_prior", "--control-prior", "control_prior", "", "the weight of the prior that the "
                 "force between the tested control levels follows the natural cubic spline through theirs at "
                 "the same motion (a straight line between two, as a lookup table interpolates); against the "
                 "data's squared error, per row; 0: off"),
    RequestField("monotone_prior", "--monotone-prior", "monotone_prior", "", "the weight of the prior that the "
                 "force rises with velocity, at the training rows and at their motion with the control anywhere "
                 "between the lowest and highest tested level (only where it falls does it act); its mean square "
                 "against the data's; 0: off (the default; 100 when wanted)"),
    RequestField("feature_params", None, None, "", "feature parameters (a lag's time constant [s], ...)"),
    RequestField("acceleration_window", None, None, "s", "the derived acceleration's smoothing window"),
)}


def _option_default(name: str) -> Any:
    """A request option's default, from its one home (dampnet.training.settings.OPTIONS)."""
    from dampnet.training.settings import OPTIONS

    return OPTIONS[name].default


@dataclass(frozen=True)
class TrainingRequest:
    """Everything that decides a trained model (FIELDS says what each field means). `restarts`
    AUTO ("auto") and `algorithm` AUTO let the data decide (dampnet.training.restarts: auto_restarts,
    auto_algorithm); `diagnosis` is the parsed JSON of `dampnet diagnose --json`
    and `diagnosis_source` its file (for messages)."""

    features: tuple[str, ...] | None = None
    algorithm: str = "lm"
    hidden: tuple[int, ...] = (30,)
    activation: str = "tanh"
    holdout_voltage: float | None = 2.25
    holdout_tests: tuple[str, ...] = ()
    decimate: int | None = None
    rest_target: str = _option_default("rest_target")
    max_epochs: int = 1000
    max_fail: int = 6
    seed: int = 0
    settings: Mapping[str, Any] | None = None
    terms: tuple[Mapping[str, Any], ...] = ()
    add: tuple[str, ...] = ()
    diagnosis: Mapping[str, Any] | None = field(default=None, compare=False)
    diagnosis_source: str | None = None
    restarts: int | str = 1
    restart_score: str = DEFAULT_SCORE
    average: int = 1
    control_prior: float = _option_default("control_prior")
    monotone_prior: float = _option_default("monotone_prior")
    feature_params: Mapping[str, float] | None = None
    acceleration_window: float | None = None

    @classmethod
    def of(cls, **options: Any) -> "TrainingRequest":
        """A request from keyword options (dampnet.train's and train_dataset's names; lists as
        tuples); TypeError naming an unknown option."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(options) - names)
        if unknown:
            raise TypeError(f"unknown training option(s) {', '.join(map(repr, unknown))}; the options are "
                            + ", ".join(sorted(names)))
        for k in ("features", "hidden", "holdout_tests", "terms", "add"):
            if options.get(k) is not None and not isinstance(options[k], (str, bytes)):
                options[k] = tuple(options[k])
        return cls(**options)

    def check(self) -> None:
        """Every value against dampnet.training.settings (and the restart and average rules),
        before any data: ValueError of one line naming the option and its range."""
        from dampnet.training.restarts import check_average, check_restarts
        from dampnet.training.settings import ALGORITHM_TABLES, check_request, train_settings

        algo = {}
        if self.algorithm == AUTO:
            if self.settings:
                raise ValueError("settings (--settings): the settings are one algorithm's; name it with --algorithm "
                                 "('auto' chooses br or lm by the size of the data)")
        else:
            if not isinstance(self.algorithm, str) or self.algorithm not in ALGORITHM_TABLES:  # 'auto' too
                raise ValueError(f"algorithm (--algorithm): expected {AUTO} or one of {', '.join(ALGORITHM_TABLES)}, "
                                 f"got {self.algorithm!r}")
            algo = dict(algorithm=self.algorithm, settings=train_settings(self.algorithm, self.settings))
        check_request(**algo, hidden=self.hidden, activation=self.activation, features=self.features,
                      max_epochs=self.max_epochs, max_fail=self.max_fail, seed=self.seed,
                      decimate=self.decimate, holdout_voltage=self.holdout_voltage,
                      acceleration_window=self.acceleration_window, control_prior=self.control_prior,
                      monotone_prior=self.monotone_prior, rest_target=self.rest_target)
        for t in self.terms:
            if not isinstance(t, Mapping) or "kind" not in t:
                raise ValueError(f"terms (--terms): each term must be an object with a 'kind', got {t!r}")
        if self.diagnosis is not None and not self.add:
            raise ValueError("--diagnosis: name the effect(s) to add with --add EFFECT (e.g. the diagnosis's verdict)")
        auto = self.restarts == AUTO
        n = check_restarts(1 if auto else self.restarts, None, self.restart_score)
        # with restarts "auto" the count is known with the data: its relation to average is checked then
        check_average(self.average, self.average if auto else n, self.hidden, self.restart_score)

    def kwargs(self) -> dict[str, Any]:
        """dampnet.training.pipeline.train_dataset's keyword arguments, before any added effect."""
        return dict(features=list(self.features) if self.features else None, hidden=tuple(self.hidden),
                    activation=self.activation, holdout_voltage=self.holdout_voltage,
                    holdout_tests=list(self.holdout_tests), decimate=self.decimate,
                    terms=[dict(t) for t in self.terms], feature_params=dict(self.feature_params or {}) or None,
                    seed=self.seed, max_epochs=self.max_epochs,
                    max_fail=self.max_fail, settings=dict(self.settings) if self.settings is not None else None,
                    acceleration_window=self.acceleration_window, control_prior=self.control_prior,
                    monotone_prior=self.monotone_prior, rest_target=self.rest_target)


@dataclass
class Plan:
    """A request with what needs the data resolved: `kw` train_dataset's arguments (the added
    effects' features and terms in), `added` what each effect added, `restarts` the count,
    `note` why "auto" ran fewer than the default restarts (None otherwise), `algorithm` the one
    trained with and `algorithm_note` why, when the request said "auto" (None otherwise)."""

    dataset: Any
    request: TrainingRequest
    kw: dict[str, Any]
    added: list[dict[str, Any]]
    restarts: int
    note: str | None
    algorithm: str = "lm"
    algorithm_note: str | None = None

    def run(self, progress: Callable[[dict], Any] | None = None, threads: int | None = None,
            workers: int | None = None, init=None) -> "Trained":
        """Train (dampnet.training.pipeline.train_dataset) and build the model's envelope.
        progress: per-epoch records (one training) or one per finished fit (restarts); threads:
        torch's; workers: the processes restarts run in (None: the local cores)."""
        from dampnet.envelope import envelope_of
        from dampnet.training.pipeline import train_dataset

        r = self.request
        model, info, split = train_dataset(self.dataset, algorithm=self.algorithm, progress=progress, threads=threads,
                                           init=init, restarts=self.restarts, workers=workers,
                                           restart_score=r.restart_score, average=r.average, **self.kw)
        return Trained(model, info, split, envelope_of(model, split), self.added, self.note, self.restarts,
                       self.algorithm_note)


def plan(dataset, request: TrainingRequest, check: bool = True) -> Plan:
    """The request checked (unless `check` is False: `compare-algorithms` checks each algorithm's
    settings as it trains it), its effects added to the training (with the diagnosis's parameters
    or ones estimated from `dataset`) and restarts "auto" resolved; ValueError of one line otherwise."""
    if check:
        request.check()
    elif request.diagnosis is not None and not request.add:
        raise ValueError("--diagnosis: name the effect(s) to add with --add EFFECT (e.g. the diagnosis's verdict)")
    kw = request.kwargs()
    added = []
    if request.add:
        from dampnet.diagnosis.estimate import estimate_parameters
        from dampnet.effects import effect
        from dampnet.training.pipeline import apply_additions

        for name in request.add:
            try:
                effect(name)
                params = None if request.diagnosis is not None else estimate_parameters(name, dataset)
                kw, add = apply_additions(kw, dataset, name, diagnosis=request.diagnosis, params=params)
            except ValueError as e:
                where = f" (from {request.diagnosis_source or 'the diagnosis'})" if request.diagnosis is not None else ""
                raise ValueError(f"--add {name}{where}: {e}") from None
            added.append({"effect": name, **add})
    note = algorithm_note = rows = None
    algorithm = request.algorithm
    if algorithm == AUTO:
        from dampnet.training.restarts import auto_algorithm, training_rows

        rows = training_rows(dataset, kw["holdout_voltage"], kw["holdout_tests"], kw.get("decimate"))
        algorithm, algorithm_note = auto_algorithm(rows)
    if request.restarts == AUTO:
        from dampnet.training.restarts import auto_restarts, check_average

        restarts, note = auto_restarts(dataset, kw["holdout_voltage"], kw["holdout_tests"], kw["features"],
                                       request.restart_score, decimate=kw.get("decimate"), average=request.average,
                                       algorithm=algorithm, rows=rows)
        check_average(request.average, restarts, request.hidden, request.restart_score)
    else:
        restarts = int(request.restarts)
    return Plan(dataset, request, kw, added, restarts, note, algorithm, algorithm_note)


class Trained:
    """A trained model with everything its model directory holds. Unpacks as (model, info, split),
    dampnet.train's result before it carried the envelope."""

    def __init__(self, model, info, split, envelope, added: Sequence[dict] = (), note: str | None = None,
                 restarts: int = 1, algorithm_note: str | None = None):
        self.model, self.info, self.split, self.envelope = model, info, split, envelope
        # restarts_note: why the automatic restarts ran `restarts` and not the default;
        # algorithm_note: which algorithm "auto" chose and why
        self.added, self.restarts_note, self.restarts = list(added), note, int(restarts)
        self.algorithm_note = algorithm_note

    def __iter__(self):
        return iter((self.model, self.info, self.split))

    def __len__(self) -> int:
        return 3

    def __getitem__(self, i):
        return (self.model, self.info, self.split)[i]

    @cached_property
    def metrics(self) -> dict[str, Any]:
        """metrics.json's content (dampnet.training.pipeline.model_metrics)."""
        from dampnet.training.pipeline import model_metrics

        return model_metrics(self.model, self.info, self.split)

    def save(self, out, force: bool = False, prefix: str | None = None, inputs: Sequence = ()):
        """Write the model directory `dampnet train --out` writes (dampnet.modeldir.save_model_dir
        with the envelope); the path written."""
        from dampnet.modeldir import HEADER_PREFIX, save_model_dir

        return save_model_dir(self.model, self.metrics, out, force=force, prefix=prefix or HEADER_PREFIX,
                              inputs=inputs, envelope=self.envelope)


def load_data(data) -> Any:
    """A Dataset from a Dataset, a path, or a list of either (merged: dampnet.data.merge_datasets)."""
    import os

    from dampnet.data import Dataset, load_dataset, merge_datasets

    items = list(data) if isinstance(data, (list, tuple)) else [data]
    sets = [d if isinstance(d, Dataset) else load_dataset(os.fspath(d)) for d in items]
    return sets[0] if len(sets) == 1 else merge_datasets(sets)


def train(data, features: Sequence[str] | None = None, algorithm: str = "lm", *,
          request: TrainingRequest | None = None, progress: Callable[[dict], Any] | None = None,
          threads: int | None = None, workers: int | None = None, init=None, **options: Any) -> Trained:
    """Train a damper model (`dampnet.train`): `data` a Dataset, a path or a list of them;
    `request` a TrainingRequest, or its fields as keyword options (features, algorithm, hidden,
    restarts, average, add, seed, holdout_voltage, ...; algorithm "lm" and restarts 1 unless told,
    "auto" for either lets the data decide as `dampnet train` does). Returns the
    Trained model with its envelope; `model, info, split = dampnet.train(...)` still unpacks."""
    if request is None:
        request = TrainingRequest.of(features=features, algorithm=algorithm, **options)
    elif options or features is not None or algorithm != "lm":
        raise TypeError("train: give the options either as a request or as keywords, not both")
    return plan(load_data(data), request).run(progress=progress, threads=threads, workers=workers, init=init)
