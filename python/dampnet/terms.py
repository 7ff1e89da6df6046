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

import itertools
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


# -- fitting a hybrid model's terms --------------------------------------------------

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
    raise ValueError(f"cannot fit physics term kind {kind!r} (fittable: position_poly, bump_stop)")


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
            raise ValueError(f"physics term {t}: expected a 'kind'")
    fixed = [t for t in terms if t.get("params") is not None]
    free = [i for i, t in enumerate(terms) if t.get("params") is None]
    if not free:
        return terms
    target = y - terms_force(fixed, x)
    base = _velocity_basis(v, u)
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
        terms[i]["fitted"] = "least squares with a velocity model (dampnet.terms.fit_terms)"
    return terms
