"""The diagnosis loop on any data (issue 53): train as `dampnet train` trains by default, diagnose
the model on its TRAINING tests (never the held-out ones), add every effect the diagnosis names,
in its order (as `dampnet train --add A --add B --diagnosis d.json`), retrain, and again, until
the diagnosis names nothing new, names only effects the data cannot carry (an input needs a
channel they lack), or `max_steps` effects were added.

    steps = run_loop(dataset, holdout_tests=["t3", "t7"], max_steps=3)
    steps[0].label, steps[0].holdout_rmse_n      # "default", RMSE on the held-out tests [N]
    steps[-1].added                              # ("friction", "gas_spring"): in the order added

The diagnosis names several effects when each explains the residual left after the ones before it
(its forward selection), so they are added together: on Labcontrol's MR damper (bench/RESULTS.md,
"Real dampers") adding the three it named at once (friction, gas_spring, compressibility) gives
18.3 N held out, where adding only the first and diagnosing again gave 29.8 N and then named
nothing (the first addition changed the residual under the others' regressors). Step k's model
carries every effect added before it, so the last step is what adding them together gives.
`dampnet demo --data` and bench/real_data.py run it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from dampnet.recipes.training import Trained, TrainingRequest, train
from dampnet.training.settings import command_defaults

#: additions the loop makes at most unless told (each a training and a diagnosis), and the most it takes
MAX_STEPS = 3
MAX_STEPS_LIMIT = 10


def check_max_steps(n: int, name: str = "max_steps") -> int:
    """n if it is a number of additions the loop takes (0..MAX_STEPS_LIMIT); ValueError naming
    `name` otherwise."""
    if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= MAX_STEPS_LIMIT:
        raise ValueError(f"{name}: expected 0..{MAX_STEPS_LIMIT} additions, got {n!r}")
    return n


@dataclass
class LoopStep:
    """One model of the loop: what was added to reach it, its scores, and what its diagnosis named."""
    label: str                          # "default", "+ friction", "+ friction + gas_spring"
    added: tuple[str, ...]              # effects added, in order
    request: TrainingRequest            # what trained it
    trained: Trained
    train_s: float                      # its training's wall time [s]
    diagnosis: dict | None = None       # the diagnosis of this model on the training tests
    diagnose_s: float | None = None     # its wall time [s]
    stop: str | None = None             # why the loop ended after this model (None: it went on)
    scores: dict[str, Any] = field(default_factory=dict)  # held-out RMSE [N], NRMSE, per test

    @property
    def named(self) -> str | None:
        """The effect this model's diagnosis named first (its verdict), or None."""
        return (self.diagnosis or {}).get("verdict")

    @property
    def named_all(self) -> list[str]:
        """Every effect this model's diagnosis named, in its order (the verdict first)."""
        return list(((self.diagnosis or {}).get("finding") or {}).get("effects") or [])

    @property
    def not_addable(self) -> dict[str, list[str]]:
        """{effect named: the channels its input needs and the data lack}."""
        return dict(((self.diagnosis or {}).get("finding") or {}).get("not_addable") or {})

    @property
    def holdout_rmse_n(self) -> float | None:
        return self.scores.get("rmse_n")

    def to_add(self, max_steps: int) -> tuple[tuple[str, ...], dict[str, str], str | None]:
        """(the effects to add after this model: every effect its diagnosis named, in its order,
        that is addable and not added yet, up to max_steps additions in all; {named effect left
        out: why}; why the loop stops here, or None)."""
        named, lacking = self.named_all, self.not_addable
        new = [e for e in named if e not in self.added]
        skipped = {e: f"the data have no {' or '.join(lacking[e])} channel" for e in new if lacking.get(e)}
        addable = [e for e in new if e not in skipped]
        room = max(max_steps - len(self.added), 0)
        skipped.update({e: f"max_steps {max_steps}" for e in addable[room:]})
        if not named:
            return (), skipped, "the diagnosis names no effect"
        if not new:
            return (), skipped, f"the diagnosis names {', '.join(named)} again, already added"
        if not addable:
            return (), skipped, "; ".join(f"the diagnosis names {e}, whose input needs a {' or '.join(lacking[e])} "
                                          "channel the data lack" for e in new)
        if not room:
            return (), skipped, (f"the diagnosis names {', '.join(addable)}; the loop stops at {max_steps} "
                                 "additions (max_steps)")
        return tuple(addable[:room]), skipped, None


def next_request(request: TrainingRequest, model, diagnosis: dict, effects: Sequence[str]) -> TrainingRequest:
    """The request after a diagnosis: `request` with the model's features (those added before
    included), its feature parameters and physics terms (refitted: their values are not kept),
    and `effects` (ids, in order) added with the diagnosis's parameters, as `dampnet train --add A
    --add B --diagnosis FILE` makes it. A valve "auto" the model decided stays decided: its terms hold
    the valve term or not (dampnet.training.valve_choice), and the next model trains one way."""
    terms = [{k: v for k, v in t.items() if k != "params"} for t in model.terms]
    decided = ((getattr(model, "meta", None) or {}).get("valve") or {}).get("choice") == "auto"
    return request.replace(features=list(model.features), terms=terms,
                           feature_params=dict(model.feature_params) or None, add=tuple(effects),
                           diagnosis=diagnosis, **({"valve": "off"} if decided else {})).check()


def holdout_scores(model, tests, envelope=None) -> dict[str, Any]:
    """dampnet.evaluation over the held-out tests: RMSE [N], NRMSE (over their force range, max -
    min) and the largest error [N] over every sample, RMSE [N] per test, and where the model
    guessed (dampnet.evaluation.regions): "at_rest" (its error where the damper stands still; None,
    with "at_rest_note" saying why, when the tests never do) and "outside_envelope" (the share of
    time outside `envelope`, the model's training envelope, and the error there)."""
    from dampnet.evaluation.report import evaluation

    if not tests:
        return {}
    rep = evaluation(model, tests, envelope=envelope)
    reg, o = rep["regions"], rep["overall"]
    return {"rmse_n": o["rmse_n"], "nrmse": o["nrmse"], "max_abs_error_n": o["max_abs_error_n"],
            "per_test_rmse_n": {r["test_id"]: r["rmse_n"] for r in rep["per_test"]},
            "at_rest": reg["at_rest"], "at_rest_note": reg["note"], "outside_envelope": reg["outside_envelope"]}


def run_loop(data, request: TrainingRequest | None = None, *, max_steps: int = MAX_STEPS, seed: int = 0,
             log: Callable[[str], None] = lambda s: None, workers: int | None = None,
             progress: Callable[[dict], Any] | None = None, **options: Any) -> list[LoopStep]:
    """The loop on `data` (a Dataset or a path): the first model from `request` (or the keyword
    options: `dampnet train`'s defaults, algorithm, restarts and valve "auto"), then one model per
    addition. Returns every model's step; the last step's `stop` says why the loop ended."""
    from dampnet.data import Dataset
    from dampnet.diagnosis.run import diagnose
    from dampnet.recipes.training import load_data

    check_max_steps(max_steps)
    if request is None:
        request = TrainingRequest.of(**{**command_defaults(), "seed": seed, **options})
    elif options:
        raise TypeError("run_loop: give the options either as a request or as keywords, not both")
    else:
        request = request.check()
    ds = load_data(data)

    def fit(req: TrainingRequest, label: str, added: tuple[str, ...]) -> LoopStep:
        log(f"training {label} ...")
        t0 = time.perf_counter()
        trained = train(ds, request=req, workers=workers, progress=progress)
        step = LoopStep(label, added, req, trained, time.perf_counter() - t0)
        hold = trained.split.holdout
        step.scores = holdout_scores(trained.model, hold.tests if hold is not None else [], trained.envelope)
        if step.scores:
            rest = step.scores["at_rest"]
            log(f"  {label}: held-out RMSE {step.scores['rmse_n']:.1f} N, NRMSE {step.scores['nrmse']:.4f}"
                + (f", at rest {rest['rmse_n']:.1f} N (bias {rest['bias_n']:+.1f} N)" if rest else "")
                + f" ({step.train_s:.0f} s)")
        return step

    steps = [fit(request, "default", ())]
    while True:
        step = steps[-1]
        train_tests = step.trained.split.train
        train_ds = Dataset(tests=list(train_tests.tests), source=ds.source, meta=dict(ds.meta))
        log(f"diagnosing {step.label} on its {len(train_ds.tests)} training tests ...")
        t0 = time.perf_counter()
        step.diagnosis = diagnose(step.trained.model, train_ds, seed=seed)
        step.diagnose_s = time.perf_counter() - t0
        effects, skipped, step.stop = step.to_add(max_steps)
        if step.stop:
            log(f"  stop: {step.stop}")
            return steps
        log(f"  the diagnosis names {', '.join(step.named_all)}: adding {' and '.join(effects)}"
            + (f" (not {'; '.join(f'{e}: {why}' for e, why in skipped.items())})" if skipped else ""))
        try:
            req = next_request(step.request, step.trained.model, step.diagnosis, effects)
            steps.append(fit(req, "+ " + " + ".join((*step.added, *effects)), (*step.added, *effects)))
        except ValueError as e:  # the addition was refused (the message says why): the loop ends here
            step.stop = f"adding {' and '.join(effects)} was refused: {e}"
            log(f"  stop: {step.stop}")
            return steps


def loop_summary(steps: Sequence[LoopStep]) -> dict[str, Any]:
    """A JSON-ready record of the loop: per model its label, additions, held-out scores, training
    and diagnosis times, what its diagnosis named and the three-way finding; why it stopped."""
    rows = []
    for s in steps:
        finding = (s.diagnosis or {}).get("finding") or {}
        rows.append({"label": s.label, "added": list(s.added), "scores": s.scores, "train_s": round(s.train_s, 2),
                     "diagnose_s": None if s.diagnose_s is None else round(s.diagnose_s, 2), "named": s.named,
                     "named_all": s.named_all,
                     "finding": {k: finding.get(k) for k in ("kind", "effects", "sentence", "not_addable")},
                     "features": list(s.trained.model.features), "stop": s.stop})
    first, last = steps[0].scores.get("rmse_n"), steps[-1].scores.get("rmse_n")
    return {"steps": rows, "order": list(steps[-1].added), "stop": steps[-1].stop,
            "together": None if len(steps) < 2 or not first or last is None else
            {"added": list(steps[-1].added), "rmse_n": last, "change_pct": 100.0 * (last / first - 1.0)}}
