"""A training request: one value of every request option of the options table
(dampnet.training.settings.OPTIONS, rows with `request`), the table's default unless given.

    req = TrainingRequest(algorithm="lm", restarts=6, add=("valve_lag",))
    req.hidden                      # (30,): the table's default
    req = req.check()               # every value checked, once, before any data: the edge
    req.replace(seed=2)             # another request

`check()` is the one validation of a request (each value against its row, then the relations
between them: the settings with their algorithm, average with restarts); below it
(dampnet.training.pipeline, fit) the checked request is passed down as it is. A row registered in
the table (dampnet.training.settings.register) is a field of every request made after.
"""

from __future__ import annotations

from typing import Any, Iterator, Mapping

from dampnet.training.settings import AUTO, OPTIONS, Option, check_settings, option, train_settings

#: the fields whose lists are kept as tuples (a request is immutable)
_SEQUENCES = ("features", "hidden", "holdout_tests", "terms", "add")


def request_rows() -> dict[str, Option]:
    """The rows of OPTIONS that are TrainingRequest fields, in table order."""
    return {name: row for name, row in OPTIONS.items() if row.request}


class TrainingRequest:
    """Everything that decides a trained model: one attribute per request row of the options
    table (its meaning: the row's), the row's default unless given. `restarts` AUTO ("auto") and
    `algorithm` AUTO let the data decide (dampnet.training.restarts: auto_restarts,
    auto_algorithm); `diagnosis` is the parsed JSON of `dampnet diagnose --json` and
    `diagnosis_source` its file (for messages). Immutable; equal when the values are (but the
    diagnosis's, which its source names)."""

    #: True for a request check() made: train_dataset need not check it again
    checked = False

    def __init__(self, **options: Any):
        rows = request_rows()
        unknown = sorted(set(options) - set(rows))
        if unknown:
            raise TypeError(f"unknown training option(s) {', '.join(map(repr, unknown))}; the options are "
                            + ", ".join(sorted(rows)))
        for k in _SEQUENCES:
            if options.get(k) is not None and not isinstance(options[k], (str, bytes)):
                options[k] = tuple(options[k])
        self.__dict__["_values"] = {name: options.get(name, row.default) for name, row in rows.items()}

    @classmethod
    def of(cls, **options: Any) -> "TrainingRequest":
        """A request from keyword options (lists as tuples); TypeError naming an unknown option."""
        return cls(**options)

    def __getattr__(self, name: str) -> Any:
        values = self.__dict__.get("_values", {})
        if name in values:
            return values[name]
        raise AttributeError(f"TrainingRequest has no option {name!r}")

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("a TrainingRequest is immutable: use replace(...)")

    def __iter__(self) -> Iterator[tuple[str, Any]]:
        return iter(self._values.items())

    def _compared(self) -> tuple:
        rows = request_rows()
        return tuple((k, v) for k, v in self._values.items() if rows.get(k) is None or rows[k].compare)

    def __eq__(self, other: Any) -> bool:
        return isinstance(other, TrainingRequest) and self._compared() == other._compared()

    def __hash__(self) -> int:
        return hash(self._compared())

    def __repr__(self) -> str:
        rows = request_rows()
        given = ", ".join(f"{k}={v!r}" for k, v in self._values.items() if k in rows and v != rows[k].default)
        return f"TrainingRequest({given})"

    def replace(self, **changes: Any) -> "TrainingRequest":
        """This request with `changes`: a new request (unchecked, unless nothing changed)."""
        new = TrainingRequest(**{**self._values, **changes})
        if new._values == self._values:
            return self
        return new

    def check(self) -> "TrainingRequest":
        """Every value against its row of the options table, then the relations between them,
        before any data: the request with the checked values (ints as int, reals as float, hidden a
        tuple); ValueError of one line naming the option and its range."""
        from dampnet.training.restarts import check_average, check_restarts

        checked = {}
        for name, value in self._values.items():
            checked[name] = value if (name == "restarts" and value == AUTO) else option(name, value)
        algorithm, settings = checked["algorithm"], checked["settings"]
        if algorithm == AUTO:
            if settings:
                raise ValueError("settings (--settings): the settings are one algorithm's; name it with --algorithm "
                                 "('auto' chooses br or lm by the size of the data)")
        else:
            check_settings(algorithm, train_settings(algorithm, settings))
        for t in checked["terms"]:
            if not isinstance(t, Mapping) or "kind" not in t:
                raise ValueError(f"terms (--terms): each term must be an object with a 'kind', got {t!r}")
        if checked["diagnosis"] is not None and not checked["add"]:
            raise ValueError("--diagnosis: name the effect(s) to add with --add EFFECT (e.g. the diagnosis's verdict)")
        auto = checked["restarts"] == AUTO
        n = check_restarts(1 if auto else checked["restarts"], None, checked["restart_score"])
        # with restarts "auto" the count is known with the data: its relation to average is checked then
        check_average(checked["average"], checked["average"] if auto else n, checked["hidden"],
                      checked["restart_score"])
        out = TrainingRequest(**checked)
        out.__dict__["checked"] = True
        return out

    def kwargs(self) -> dict[str, Any]:
        """The request's values as keyword arguments (lists as lists, mappings as dicts), e.g. of
        dampnet.training.pipeline.train_dataset."""
        out = {}
        for k, v in self._values.items():
            if k in _SEQUENCES and v is not None:
                v = [dict(t) for t in v] if k == "terms" else list(v)
            elif isinstance(v, Mapping):
                v = dict(v)
            out[k] = v
        return out

    def recorded(self) -> dict[str, Any]:
        """What model.meta["request"] records: every value but the diagnosis's (its source is
        named), JSON-ready."""
        from dampnet.outputs import jsonable

        return jsonable({k: v for k, v in self.kwargs().items() if k != "diagnosis"})
