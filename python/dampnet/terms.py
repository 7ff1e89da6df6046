"""Physics terms of hybrid damper models, in numpy: the Python mirror of the C++ table.

A hybrid model's force is its MLP's output plus the sum of its terms,
`MlpModel.terms = [{"kind": str, "params": [float, ...]}, ...]`. Each kind is
one entry of `KINDS` here and one line of `DN_TERM_LIST` in
`cpp/include/dampnet/dampnet.h` (its force in `cpp/include/dampnet/terms.hpp`);
the two must give the same force (tests/python/test_loop_dampers.py checks).

Sign convention (the dyno's): displacement x [m] is the damper's extension from
its mid position, positive in rebound; a force is positive when it resists
extension (tension). A gas charge pushes the rod out, so its preload p0 is
negative and its stiffness p1 positive.

To add a kind: add one `Kind` to `KINDS` (its force and parameter check) and
the same formula to the C++ table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np


@dataclass(frozen=True)
class Kind:
    params: tuple[str, ...]  # parameter names with units, in order
    force: Callable[[np.ndarray, dict[str, np.ndarray]], np.ndarray]  # (params, inputs) -> F [N]
    check: Callable[[np.ndarray], str | None]  # a reason the params are invalid, or None
    doc: str


def _position_poly(p: np.ndarray, q: dict[str, np.ndarray]) -> np.ndarray:
    x = q["x"]
    return p[0] + x * (p[1] + x * (p[2] + x * p[3]))


def _bump_stop(p: np.ndarray, q: dict[str, np.ndarray]) -> np.ndarray:
    x = q["x"]
    over = np.abs(x) - p[0]
    mag = np.where(over > 0, p[1] * np.power(np.maximum(over, 0.0), p[2]), 0.0)
    return np.sign(x) * mag


def _bump_check(p: np.ndarray) -> str | None:
    if p[0] < 0 or p[1] < 0 or p[2] <= 0:
        return "bump_stop needs x_free >= 0, k >= 0, n > 0"
    return None


KINDS: dict[str, Kind] = {
    "position_poly": Kind(("p0 [N]", "p1 [N/m]", "p2 [N/m^2]", "p3 [N/m^3]"), _position_poly,
                          lambda p: None,
                          "F = p0 + p1 x + p2 x^2 + p3 x^3: gas charge preload, stiffness, progression"),
    "bump_stop": Kind(("x_free [m]", "k [N/m^n]", "n [-]"), _bump_stop, _bump_check,
                      "F = sgn(x) k (|x| - x_free)^n beyond x_free: elastomer stops both ways"),
}


def validate(term: Mapping[str, Any]) -> np.ndarray:
    """The parameters of a term as an array, or ValueError naming what is wrong."""
    kind = term.get("kind")
    if kind not in KINDS:
        raise ValueError(f"unknown term kind {kind!r}; known: {', '.join(sorted(KINDS))}")
    p = np.asarray(term.get("params", []), dtype=np.float64).ravel()
    k = KINDS[kind]
    if p.size != len(k.params):
        raise ValueError(f"term {kind!r}: expected {len(k.params)} params {k.params}, got {p.size}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"term {kind!r}: params must be finite, got {p.tolist()}")
    why = k.check(p)
    if why:
        raise ValueError(f"term {kind!r}: {why} (got {p.tolist()})")
    return p


def term_force(term: Mapping[str, Any], x, v=None, **inputs) -> np.ndarray:
    """Force [N] of one term at displacement x [m] (and other inputs by name: v, a, u, ...)."""
    p = validate(term)
    q = {"x": np.asarray(x, dtype=np.float64)}
    if v is not None:
        q["v"] = np.asarray(v, dtype=np.float64)
    q.update({k: np.asarray(val, dtype=np.float64) for k, val in inputs.items()})
    return np.asarray(KINDS[term["kind"]].force(p, q), dtype=np.float64)


def terms_force(terms: Sequence[Mapping[str, Any]], x, v=None, **inputs) -> np.ndarray:
    """Sum of the terms' forces [N] (0 for no terms), broadcast over the inputs."""
    total = np.zeros(np.shape(np.asarray(x, dtype=np.float64)))
    for t in terms:
        total = total + term_force(t, x, v, **inputs)
    return total
