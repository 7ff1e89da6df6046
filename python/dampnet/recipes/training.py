"""A training request, and the one way to train it: `dampnet train`, the sweep's [training]
cells and the Python `dampnet.train` all build a `TrainingRequest` and call `train`, which
returns the model WITH its training envelope, so every way of training saves the same model
directory (model.json, metrics.json, model.h, envelope.npz, envelope.json).

    req = TrainingRequest(algorithm="lm", restarts=6, average=2, add=("valve_lag",))
    trained = train(dataset, req)              # or train(dataset, algorithm="lm", restarts=6)
    model, info, split = trained               # as dampnet.train always returned
    trained.envelope, trained.metrics          # the envelope (dampnet.envelope), metrics.json's dict
    trained.save("model_dir")                  # = dampnet train's MODEL_DIR

The request's options are the rows of the options table (dampnet.training.settings.OPTIONS:
each option's type, range, default, unit, meaning, `dampnet train` option and sweep key);
`TrainingRequest.check` (dampnet.training.request) checks them, once, before any data are
loaded. `plan(dataset, request)` does what needs
the data (each added effect's features and terms, dampnet.training.pipeline.apply_additions,
with the diagnosis's parameters or ones estimated from the data; restarts "auto" resolved,
dampnet.training.restarts.auto_restarts), `Plan.run` trains. How the work runs (progress,
threads, restart workers) is not part of the request: it does not change the model.

Adding a training option: its row in the table, and its use (docs/recipes.md, "Training requests").
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any, Callable, Sequence

from dampnet.training.request import TrainingRequest
from dampnet.training.settings import AUTO

__all__ = ["AUTO", "Plan", "Trained", "TrainingRequest", "load_data", "plan", "train"]


@dataclass
class Plan:
    """A request with what needs the data resolved: `kw` its values as train_dataset's arguments (the
    added effects' features and terms in), `added` what each effect added, `restarts` the count,
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

        request = self.request.replace(**{**self.kw, "algorithm": self.algorithm, "restarts": self.restarts})
        model, info, split = train_dataset(self.dataset, request=request, progress=progress, threads=threads,
                                           init=init, workers=workers)
        return Trained(model, info, split, envelope_of(model, split), self.added, self.note, self.restarts,
                       self.algorithm_note)


def plan(dataset, request: TrainingRequest, check: bool = True) -> Plan:
    """The request checked (unless `check` is False: `compare-algorithms` checks each algorithm's
    settings as it trains it), its effects added to the training (with the diagnosis's parameters
    or ones estimated from `dataset`) and restarts "auto" resolved; ValueError of one line otherwise."""
    if check:
        request = request.check()
    elif request.diagnosis is not None and not request.add:
        raise ValueError("--diagnosis: name the effect(s) to add with --add EFFECT (e.g. the diagnosis's verdict)")
    kw = {k: v for k, v in request.kwargs().items() if k != "algorithm"}
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

    @property
    def valve_note(self) -> str | None:
        """What valve "auto" chose and why, in one line (dampnet.training.valve_choice); None otherwise."""
        from dampnet.training.valve_choice import sentence

        return sentence(self.model.meta.get("valve"))

    def __iter__(self):
        return iter((self.model, self.info, self.split))

    def __len__(self) -> int:
        return 3

    def __getitem__(self, i):
        return (self.model, self.info, self.split)[i]

    @cached_property
    def metrics(self) -> dict[str, Any]:
        """metrics.json's content (dampnet.training.pipeline.model_metrics), with the hold-out's
        error at rest and outside the training envelope ("holdout_regions":
        dampnet.evaluation.regions) when tests were held out."""
        from dampnet.training.pipeline import model_metrics

        out = model_metrics(self.model, self.info, self.split)
        if self.split.holdout is not None and "holdout" in out:
            from dampnet.evaluation.report import evaluation

            out["holdout_regions"] = evaluation(self.model, self.split.holdout.tests, envelope=self.envelope)["regions"]
        return out

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


def train(data, features: Sequence[str] | None = None, algorithm: str | None = None, *,
          request: TrainingRequest | None = None, progress: Callable[[dict], Any] | None = None,
          threads: int | None = None, workers: int | None = None, init=None, **options: Any) -> Trained:
    """Train a damper model (`dampnet.train`): `data` a Dataset, a path or a list of them;
    `request` a TrainingRequest, or its fields as keyword options (features, algorithm, hidden,
    restarts, average, add, seed, holdout_voltage, ...; algorithm "lm" and restarts 1 unless told,
    "auto" for either lets the data decide as `dampnet train` does). Returns the
    Trained model with its envelope; `model, info, split = dampnet.train(...)` still unpacks."""
    if request is None:
        given = {k: v for k, v in (("features", features), ("algorithm", algorithm)) if v is not None}
        request = TrainingRequest.of(**given, **options)
    elif options or features is not None or algorithm is not None:
        raise TypeError("train: give the options either as a request or as keywords, not both")
    return plan(load_data(data), request).run(progress=progress, threads=threads, workers=workers, init=init)
