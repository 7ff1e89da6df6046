"""Physics terms of hybrid damper models, in numpy: the Python mirror of the C++ table.

A hybrid model's force is its MLP's output plus the sum of its terms,
`MlpModel.terms = [{"kind": str, "params": [float, ...]}, ...]`. Each kind is
one entry of `KINDS` here and one line of `DN_TERM_LIST` in
`cpp/include/dampnet/dn_xmacro.h` (its force in `cpp/include/dampnet/terms.hpp`);
the two must give the same force (tests/python/test_loop_dampers.py checks).

Sign convention (the dyno's): displacement x [m] is the damper's extension from
its mid position, positive in rebound; a force is positive when it resists
extension (tension). A gas charge pushes the rod out, so its preload p0 is
negative and its stiffness p1 positive.

To add a kind: add one `Kind` to `KINDS` (its force, parameter check, and which
parameters are linear for fitting) and the same formula to the C++ table; its name
and parameter count must match `_core.TERM_KINDS` (tests/python/test_terms_registry.py).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np


@dataclass(frozen=True)
class Kind:
    """One term kind: its formula once, and how `fit_terms` fits it.

    The force is linear in the parameters at `linear` (least squares: their columns are
    the force with that parameter 1 and the other linear ones 0); the others (the
    "shape") are chosen on the grid `shapes(x)` gives, by least residual.
    """
    params: tuple[str, ...]  # parameter names with units, in order
    force: Callable[[np.ndarray, dict[str, np.ndarray]], np.ndarray]  # (params, inputs) -> F [N]
    check: Callable[[np.ndarray], str | None]  # a reason the params are invalid, or None
    doc: str
    linear: tuple[int, ...]  # indices of the parameters the force is linear in
    shapes: Callable[[np.ndarray], list[tuple[float, ...]]] = lambda x: [()]  # x [m] -> grid of the others
    # the fitted parameters made valid (e.g. a negative stiffness switched off)
    settle: Callable[[np.ndarray], np.ndarray] = lambda p: p
    # whether fit_terms' linear fit (the basis and shapes above) can fit it
    fittable: bool = True
    # fitted instead by nonlinear least squares after the others (fit_terms: the valve)
    nonlinear_fit: bool = False
    # trailing parameters a term may leave out, all of them (then 0): those added to a kind after
    # models were written with it (the valve's digressions k_d); the runtime's min_params agrees
    optional: int = 0

    def with_shape(self, shape: tuple[float, ...], linear_values) -> np.ndarray:
        """The full parameter vector from a shape (the non-linear parameters) and the linear ones."""
        p = np.empty(len(self.params))
        nonlinear = [i for i in range(len(self.params)) if i not in self.linear]
        p[list(self.linear)] = linear_values
        p[nonlinear] = shape
        return p

    def basis(self, x: np.ndarray, shape: tuple[float, ...]) -> np.ndarray:
        """Columns [n, len(linear)]: F(x) = basis(x, shape) @ (the linear parameters)."""
        eye = np.eye(len(self.linear))
        return np.stack([self.force(self.with_shape(shape, e), {"x": x}) for e in eye], axis=1)


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


def _bump_shapes(x: np.ndarray) -> list[tuple[float, ...]]:
    """(x_free, n): x_free 50-95 % of the largest |x| [m], n in 1, 1.5, 2, 3."""
    xmax = float(np.max(np.abs(x)))
    return [(f * xmax, n) for f in (0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95) for n in (1.0, 1.5, 2.0, 3.0)]


def _bump_settle(p: np.ndarray) -> np.ndarray:
    # k < 0 would pull towards the stop: not a bump stop, so the term is switched off
    return np.array([p[0], max(p[1], 0.0), p[2]])


#: the valve term's bounds (dn_xmacro.h DN_TERM_VALVE_V_MAX_M_S, DN_TERM_VALVE_U_MAX,
#: DN_TERM_VALVE_K_D_MAX_S_M: the largest digression the runtime accepts)
VALVE_V_MAX = 50.0  # [m/s]
VALVE_U_MAX = 1000.0  # [V or A]
VALVE_K_D_MAX = 1e6  # [s/m]


def _valve_opening(kd, d):
    """(z, r) of the digressive opening: z = ln(1 + k_d d) / k_d (d itself at k_d = 0, and where
    k_d d underflows), r = dz/dd = 1 / (1 + k_d d)."""
    x = kd * d
    pos = x > 0
    xs = np.where(pos, x, 1.0)
    z = d * np.where(pos, np.log1p(xs) / xs, 1.0)
    r = np.where(pos, 1.0 / (1.0 + xs), 1.0)
    return z, r


def _valve_parts(p: np.ndarray, q: dict[str, np.ndarray]):
    """(sgn(v), s(u), ds/du, g_d(|v|), g_d'(|v|), |v| below its clamp) of the valve term."""
    if "v" not in q or "u" not in q:
        raise ValueError("a valve term needs the velocity v [m/s] and the control u [V or A]")
    v = np.asarray(q["v"], dtype=np.float64)
    u = np.asarray(q["u"], dtype=np.float64)
    v, u = np.broadcast_arrays(v, u)
    ext = v > 0
    vk, cb, cv = (np.where(ext, p[i], p[i + 3]) for i in range(3))
    kd = np.where(ext, p[8], p[9])
    w_raw = np.abs(v)
    w = np.where(w_raw < VALVE_V_MAX, w_raw, VALVE_V_MAX)
    w = np.where(np.isnan(w), 0.0, w)
    below = w <= vk
    d = np.maximum(w - vk, 0.0)
    z, r = _valve_opening(kd, d)
    one_minus_e = -np.expm1(-z / vk)
    m = 2 * cb * vk - cv
    g = np.where(below, cb * w * w, cb * vk * vk + cv * z + m * vk * one_minus_e)
    dg = np.where(below, 2 * cb * w, r * (cv + m * (1 - one_minus_e)))
    inside = (u > 0) & (u < VALVE_U_MAX)  # NaN: outside, as u = 0
    uc = np.where(inside, u, np.where(u >= VALVE_U_MAX, VALVE_U_MAX, 0.0))
    den = 1 + p[7] * uc
    s = (1 + p[6] * uc) / den
    ds = np.where(inside, (p[6] - p[7]) / (den * den), 0.0)
    sgn = np.where(ext, 1.0, np.where(v < 0, -1.0, 0.0))  # 0 at v = 0 and NaN
    return sgn, s, ds, g, dg, w_raw < VALVE_V_MAX


def _valve(p: np.ndarray, q: dict[str, np.ndarray]) -> np.ndarray:
    sgn, s, _, g, _, _ = _valve_parts(p, q)
    return sgn * s * g


def valve_gradient(params, v, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The valve term's (F [N], dF/dv [N s/m], dF/du [N per control unit]) at v [m/s], u [V or A]."""
    p = validate({"kind": "valve", "params": params})
    sgn, s, ds, g, dg, unclamped = _valve_parts(p, {"v": np.asarray(v, float), "u": np.asarray(u, float)})
    return sgn * s * g, np.where(unclamped & (sgn != 0), s * dg, 0.0), sgn * ds * g


def _dz_dkd(kd, d, z, r):
    """dz/dk_d of z = ln(1 + k_d d) / k_d: (d r - z) / k_d, by its series -d^2 (1/2 - 2x/3 + 3x^2/4
    - 4x^3/5) in x = k_d d where that cancels (x < 1e-3; -d^2 / 2 at k_d = 0)."""
    x = kd * d
    small = x < 1e-3
    series = -d * d * (0.5 - x * (2 / 3 - x * (0.75 - 0.8 * x)))
    return np.where(small, series, (d * r - z) / np.where(small, 1.0, kd))


def valve_param_jacobian(p, v, u) -> np.ndarray:
    """dF/dp [n, 10] of the valve term at v [m/s], u [V or A] (p as KINDS["valve"].params, 8 or 10
    of them): the columns the nonlinear fit uses, in the parameters' units (N per unit of each)."""
    p = full_params("valve", p)
    sgn, s, _, g, _, _ = _valve_parts(p, {"v": np.asarray(v, float), "u": np.asarray(u, float)})
    v, u = np.broadcast_arrays(np.asarray(v, float), np.asarray(u, float))
    ext = v > 0
    vk, cb, cv = (np.where(ext, p[i], p[i + 3]) for i in range(3))
    kd = np.where(ext, p[8], p[9])
    w = np.minimum(np.where(np.isnan(v), 0.0, np.abs(v)), VALVE_V_MAX)
    below = w <= vk
    d = np.maximum(w - vk, 0.0)
    z, r = _valve_opening(kd, d)
    ome = -np.expm1(-z / vk)
    e = 1 - ome
    m = 2 * cb * vk - cv
    # d/dv_k: d = w - v_k moves (dz/dv_k = -r) and so does the transition's scale v_k
    dg_dvk = np.where(below, 0.0, 2 * cb * vk - cv * r + (2 * cb * vk + m) * ome - m * e * (z / vk + r))
    dg_dcb = np.where(below, w * w, vk * vk + 2 * vk * vk * ome)
    dg_dcv = np.where(below, 0.0, z - vk * ome)
    dg_dkd = np.where(below, 0.0, (cv + m * e) * _dz_dkd(kd, d, z, r))
    inside = (u > 0) & (u < VALVE_U_MAX)
    uc = np.where(inside, u, np.where(u >= VALVE_U_MAX, VALVE_U_MAX, 0.0))
    den = 1 + p[7] * uc
    J = np.zeros(v.shape + (10,))
    for k, dg in ((0, dg_dvk), (1, dg_dcb), (2, dg_dcv)):
        J[..., k] = np.where(ext, sgn * s * dg, 0.0)
        J[..., k + 3] = np.where(ext, 0.0, sgn * s * dg)
    J[..., 8] = np.where(ext, sgn * s * dg_dkd, 0.0)
    J[..., 9] = np.where(ext, 0.0, sgn * s * dg_dkd)
    J[..., 6] = sgn * g * uc / den
    J[..., 7] = -sgn * g * s * uc / den
    return J


def _valve_check(p: np.ndarray) -> str | None:
    if not (p[0] > 0 and p[3] > 0) or min(p[1], p[2], p[4], p[5], p[6], p[7]) < 0:
        return "valve needs v_k > 0 and c_b, c_v, g_num, g_den >= 0"
    if not (0 <= p[8] <= VALVE_K_D_MAX and 0 <= p[9] <= VALVE_K_D_MAX):
        return f"valve needs 0 <= k_d <= {VALVE_K_D_MAX:g} s/m"
    return None


KINDS: dict[str, Kind] = {
    "position_poly": Kind(("p0 [N]", "p1 [N/m]", "p2 [N/m^2]", "p3 [N/m^3]"), _position_poly,
                          lambda p: None,
                          "F = p0 + p1 x + p2 x^2 + p3 x^3: gas charge preload, stiffness, progression",
                          linear=(0, 1, 2, 3)),
    "bump_stop": Kind(("x_free [m]", "k [N/m^n]", "n [-]"), _bump_stop, _bump_check,
                      "F = sgn(x) k (|x| - x_free)^n beyond x_free: elastomer stops both ways",
                      linear=(1,), shapes=_bump_shapes, settle=_bump_settle),
    "valve": Kind(("v_k_ext [m/s]", "c_b_ext [N s^2/m^2]", "c_v_ext [N s/m]",
                   "v_k_comp [m/s]", "c_b_comp [N s^2/m^2]", "c_v_comp [N s/m]", "g_num [1/u]", "g_den [1/u]",
                   "k_d_ext [s/m]", "k_d_comp [s/m]"),
                  _valve, _valve_check,
                  "F = sgn(v) s(u) g_d(|v|): per direction d (ext v > 0, comp v < 0) a bleed c_b v^2 below "
                  "the knee v_k and a blow-off valve above it of slope c_v at the opening z, joined C1 "
                  "(g = c_b v_k^2 + c_v z + (2 c_b v_k - c_v) v_k (1 - exp(-z/v_k)), z = ln(1 + k_d (w - v_k)) / k_d: "
                  "digressive, its slope c_v / (1 + k_d (w - v_k)) far above the knee; k_d = 0: z = w - v_k, the "
                  "straight line, and the default of a valve given 8 parameters); control gain "
                  "s(u) = (1 + g_num u) / (1 + g_den u), u in [0, 1000], |v| <= 50 m/s",
                  linear=(), fittable=False, nonlinear_fit=True, optional=2),
}


def full_params(kind: str, params) -> np.ndarray:
    """A term's parameters at its kind's full count: the optional trailing ones (Kind.optional)
    a term left out are 0 (the runtime's terms::make does the same)."""
    p = np.asarray(params, dtype=np.float64).ravel()
    return np.concatenate([p, np.zeros(len(KINDS[kind].params) - p.size)])


def validate(term: Mapping[str, Any]) -> np.ndarray:
    """The parameters of a term as an array of its kind's full count (optional ones left out are
    0), or ValueError naming what is wrong."""
    kind = term.get("kind")
    if kind not in KINDS:
        raise ValueError(f"unknown term kind {kind!r}; known: {', '.join(sorted(KINDS))}")
    p = np.asarray(term.get("params", []), dtype=np.float64).ravel()
    k = KINDS[kind]
    n = len(k.params)
    if p.size not in (n, n - k.optional):
        count = f"{n} or {n - k.optional}" if k.optional else f"{n}"
        raise ValueError(f"term {kind!r}: expected {count} params {k.params}, got {p.size}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"term {kind!r}: params must be finite, got {p.tolist()}")
    p = full_params(kind, p)
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


def fit_terms(terms: Sequence[dict[str, Any]], x: np.ndarray, v: np.ndarray, u: np.ndarray,
              y: np.ndarray) -> list[dict[str, Any]]:
    """Terms with parameters: those given keep theirs; the others are fitted by least squares.

    Fitted jointly (one linear least-squares problem) on the training samples:
    y - sum(fixed terms) ~ sum(fitted terms) + the simple velocity model of
    _velocity_basis, whose coefficients are then dropped (the MLP learns the
    velocity dependence). Each kind's linear parameters are least-squares
    coefficients of its `basis`; the others are chosen on its `shapes` grid by
    least residual (e.g. bump_stop's x_free and n; position_poly has none).
    A free valve term (at most one; `nonlinear_fit` kinds) is fitted after those, to the force
    they and the given terms leave, by bounded nonlinear least squares on all its parameters
    (`_fit_valve`): it takes the velocity force the velocity model stood in for.
    """
    terms = [dict(t) for t in terms]
    for t in terms:
        if "kind" not in t:
            raise ValueError(f"physics term {t}: expected a 'kind'")
    fixed = [t for t in terms if t.get("params") is not None]
    free_all = [i for i, t in enumerate(terms) if t.get("params") is None]
    if not free_all:
        return terms
    unknown = [terms[i]["kind"] for i in free_all if terms[i]["kind"] not in KINDS
               or not (KINDS[terms[i]["kind"]].fittable or KINDS[terms[i]["kind"]].nonlinear_fit)]
    if unknown:
        fittable = sorted(k for k, kind in KINDS.items() if kind.fittable or kind.nonlinear_fit)
        raise ValueError(f"cannot fit physics term kind {unknown[0]!r} (fittable: {', '.join(fittable)}; give its params)")
    late = [i for i in free_all if KINDS[terms[i]["kind"]].nonlinear_fit]
    if len(late) > 1:
        raise ValueError(f"cannot fit {len(late)} valve terms at once (they are interchangeable): give the params "
                         "of all but one")
    free = [i for i in free_all if i not in late]
    target = y - terms_force(fixed, x, v, u=u)
    shapes = _fit_linear(terms, free, x, v, u, target) if free else ()
    for i in late:
        # jointly with the others' linear parameters (variable projection: for each valve, the
        # others' least-squares coefficients at the shapes chosen above), without the velocity
        # model: the valve is the velocity force
        kinds = [KINDS[terms[j]["kind"]] for j in free]
        A = np.hstack([k.basis(x, s) for k, s in zip(kinds, shapes)]) if free else np.zeros((len(target), 0))
        p = _fit_valve(v, u, target, A)
        terms[i]["params"] = p
        terms[i]["fitted"] = ("nonlinear least squares (scipy trf) jointly with the other fitted terms' linear "
                              "parameters (dampnet.terms.fit_terms)")
        if free:
            coef, *_ = np.linalg.lstsq(A, target - _valve(np.asarray(p), {"v": v, "u": u}), rcond=None)
            pos = 0
            for j, k, s in zip(free, kinds, shapes):
                w = len(k.linear)
                terms[j]["params"] = [float(a) for a in k.settle(k.with_shape(s, coef[pos:pos + w]))]
                pos += w
    return terms


def _fit_linear(terms: list[dict[str, Any]], free: list[int], x, v, u, target) -> tuple:
    """The linearly fittable terms `free` (their basis and shape grids) with the velocity model;
    returns the shapes chosen."""
    base = _velocity_basis(v, u)
    kinds = [KINDS[terms[i]["kind"]] for i in free]
    best: tuple[float, tuple, np.ndarray] | None = None
    for shapes in itertools.product(*[k.shapes(x) for k in kinds]):
        A = np.hstack([k.basis(x, s) for k, s in zip(kinds, shapes)] + [base])
        coef, *_ = np.linalg.lstsq(A, target, rcond=None)
        resid = float(np.sum((A @ coef - target) ** 2))
        if best is None or resid < best[0]:
            best = (resid, shapes, coef)
    assert best is not None  # product() of non-empty grids yields at least once
    _, shapes, coef = best
    pos = 0
    for i, k, s in zip(free, kinds, shapes):
        w = len(k.linear)
        terms[i]["params"] = [float(a) for a in k.settle(k.with_shape(s, coef[pos:pos + w]))]
        pos += w
        terms[i]["fitted"] = "least squares with a velocity model (dampnet.terms.fit_terms)"
    return shapes


class _ValveSamples:
    """A valve fit's samples split once by direction (v > 0 extension, v < 0 compression; v = 0
    adds no force), each sorted by speed, with what no parameter changes: the speed and the
    control clamped as `_valve_parts` clamps them. `force` and `jacobian` equal `_valve` and
    `valve_param_jacobian` bit for bit (the same operations on each sample, computed only on
    its side of the knee: a sorted direction's samples below the knee are a prefix), and the
    Jacobian reuses the force's evaluation at the same parameters (scipy's trf asks for both
    at each accepted point). Finite v and u only (the fit drops the others)."""

    def __init__(self, v: np.ndarray, u: np.ndarray):
        self.n = v.size
        self.sides = []
        for sign, sel in ((1.0, v > 0), (-1.0, v < 0)):
            idx = np.flatnonzero(sel)
            w_raw = np.abs(v[idx])
            w = np.where(w_raw < VALVE_V_MAX, w_raw, VALVE_V_MAX)
            order = np.argsort(w, kind="stable")
            ui = u[idx[order]]
            inside = (ui > 0) & (ui < VALVE_U_MAX)
            uc = np.where(inside, ui, np.where(ui >= VALVE_U_MAX, VALVE_U_MAX, 0.0))
            self.sides.append((sign, idx[order], w[order], uc))
        # the sorted rows (extension, compression, then v = 0) back in the samples' order: a gather,
        # much faster than scattering into the samples' rows
        sorted_rows = np.concatenate([idx for _, idx, _, _ in self.sides])
        self.n_sorted = sorted_rows.size
        self.unsort = np.full(self.n, self.n_sorted, dtype=np.intp)  # v = 0: the zero row past them
        self.unsort[sorted_rows] = np.arange(self.n_sorted)
        # dF/dp in the sorted rows, written in place at each call (a side's other columns stay 0)
        self._sorted_jacobian = np.zeros((self.n_sorted + 1, 10))
        self._at: np.ndarray | None = None
        self._parts: list = []

    def _evaluate(self, p: np.ndarray) -> list:
        """Per direction: (s, the knee's index k in the sorted speeds, g below, and above the
        knee d, z, r, 1 - e, g)."""
        if self._at is not None and np.array_equal(p, self._at):
            return self._parts
        parts = []
        for side, (_, _, w, uc) in enumerate(self.sides):
            vk, cb, cv = p[3 * side], p[3 * side + 1], p[3 * side + 2]
            kd = p[8 + side]
            s = (1 + p[6] * uc) / (1 + p[7] * uc)
            k = int(np.searchsorted(w, vk, side="right"))  # w[:k] <= v_k: the bleed
            wb, d = w[:k], w[k:] - vk  # > 0 above the knee (w > v_k)
            z, r = _valve_opening(kd, d)
            one_minus_e = -np.expm1(-z / vk)
            m = 2 * cb * vk - cv
            g_above = cb * vk * vk + cv * z + m * vk * one_minus_e
            parts.append((s, k, cb * wb * wb, d, z, r, one_minus_e, g_above))
        self._at, self._parts = p.copy(), parts
        return parts

    def force(self, p: np.ndarray) -> np.ndarray:
        """The valve's force [N] at every sample, in the samples' order (`_valve`)."""
        parts = []
        for (sign, *_), (s, k, g_below, *_, g_above) in zip(self.sides, self._evaluate(p)):
            f = np.concatenate([s[:k] * g_below, s[k:] * g_above])
            parts.append(f if sign > 0 else -f)
        return np.take(np.concatenate([*parts, [0.0]]), self.unsort)

    def jacobian(self, p: np.ndarray) -> np.ndarray:
        """dF/dp [n, 10] in the samples' order (`valve_param_jacobian`). A compression sample's
        columns are its extension twin's negated, written as products with sgn(v) s or sgn(v) g
        (a negation is exact)."""
        J = self._sorted_jacobian
        start = 0
        for side, ((sign, idx, w, uc), (s, k, g_below, d, z, r, ome, g_above)) in enumerate(
                zip(self.sides, self._evaluate(p))):
            vk, cb, cv, kd = p[3 * side], p[3 * side + 1], p[3 * side + 2], p[8 + side]
            c_vk, c_cb, c_cv, c_kd = 3 * side, 3 * side + 1, 3 * side + 2, 8 + side
            e = 1 - ome
            m = 2 * cb * vk - cv
            rows, below, above = (slice(start, start + idx.size), slice(start, start + k),
                                  slice(start + k, start + idx.size))
            ss = s if sign > 0 else -s                                      # sgn(v) s
            sg = np.concatenate([g_below, g_above]) * sign                  # sgn(v) g
            J[below, c_vk] = J[below, c_cv] = J[below, c_kd] = 0.0  # the bleed: no knee, valve or digression
            J[above, c_vk] = ss[k:] * (2 * cb * vk - cv * r + (2 * cb * vk + m) * ome - m * e * (z / vk + r))
            J[below, c_cb] = ss[:k] * (w[:k] * w[:k])
            J[above, c_cb] = ss[k:] * (vk * vk + 2 * vk * vk * ome)
            J[above, c_cv] = ss[k:] * (z - vk * ome)
            J[above, c_kd] = ss[k:] * ((cv + m * e) * _dz_dkd(kd, d, z, r))
            den = 1 + p[7] * uc
            J[rows, 6] = sg * uc / den
            J[rows, 7] = -sg * s * uc / den
            start += idx.size
        return np.take(J, self.unsort, axis=0)


def _fit_valve(v: np.ndarray, u: np.ndarray, r: np.ndarray, A: np.ndarray | None = None) -> list[float]:
    """The valve's parameters fitted to the force r [N] at v [m/s], u [V or A] by bounded
    nonlinear least squares (scipy.optimize.least_squares, trf; v_k > 0, the others >= 0, the
    digressions k_d in [0, VALVE_K_D_MAX]), from a few knee guesses (15, 30, 50 % of each
    direction's largest speed) each with the bleed's and the valve's slopes estimated below and
    above it, no control gain and straight (k_d = 0); fitted digressive (10 parameters), and
    when the best of those barely bends over the data, fitted again straight (the 8, k_d held at
    0); the best kept.
    A [n, k]: columns other terms add with free coefficients (projected out of the residual)."""
    from scipy.optimize import least_squares

    v, u, r = (np.asarray(a, dtype=np.float64).ravel() for a in (v, u, r))
    A = np.zeros((r.size, 0)) if A is None else np.asarray(A, dtype=np.float64).reshape(r.size, -1)
    ok = np.isfinite(v) & np.isfinite(u) & np.isfinite(r) & np.all(np.isfinite(A), axis=1)
    v, u, r, A = v[ok], u[ok], r[ok], A[ok]
    if A.shape[1]:
        Q, _ = np.linalg.qr(A)  # the residual's part outside A's span: r - Q Q^T r
        project = lambda e: e - Q @ (Q.T @ e)  # noqa: E731
    else:
        project = lambda e: e  # noqa: E731
    if v.size < 8 or not (np.any(v > 0) and np.any(v < 0)):
        raise ValueError("fitting a valve term needs samples in extension and in compression")

    def guess(frac: float) -> np.ndarray:
        p = np.zeros(10)
        for d, sel in ((0, v > 0), (3, v < 0)):
            w, m = np.abs(v[sel]), r[sel] * np.sign(v[sel])
            vk = max(frac * float(np.max(w)), 1e-6)
            lo, hi = w <= vk, w > vk
            cb = float(np.sum(m[lo] * w[lo] ** 2) / max(np.sum(w[lo] ** 4), 1e-300)) if np.any(lo) else 0.0
            cb = max(cb, 0.0) if np.any(lo) else max(float(np.median(m / np.maximum(w, 1e-9) ** 2)), 0.0)
            cv = 0.0
            if np.count_nonzero(hi) > 1:
                cv = max(float(np.polyfit(w[hi], m[hi], 1)[0]), 0.0)
            p[d:d + 3] = (vk, cb, cv)
        return p

    samples = _ValveSamples(v, u)

    def resid(p: np.ndarray) -> np.ndarray:
        return project(samples.force(p) - r)

    def jac(p: np.ndarray) -> np.ndarray:
        J = samples.jacobian(p)
        return J - Q @ (Q.T @ J) if A.shape[1] else J

    lower = np.array([1e-6, 0, 0, 1e-6, 0, 0, 0, 0, 0, 0], dtype=np.float64)
    upper = np.array([np.inf] * 8 + [VALVE_K_D_MAX] * 2)
    best = None

    def solve(p0: np.ndarray, straight: bool):
        # straight: the 8 parameters of the straight blow-off line (k_d = 0, held), a model nested in
        # the digressive one that trf does not reliably reach from inside (it stops short against
        # the k_d = 0 bound), so fitted on its own and kept when its residual is the smaller
        n = 8 if straight else 10
        full = lambda q: np.concatenate([q, np.zeros(10 - n)])  # noqa: E731
        return least_squares(lambda q: resid(full(q)), np.clip(p0[:n], lower[:n], upper[:n]),
                             jac=lambda q: jac(full(q))[:, :n], bounds=(lower[:n], upper[:n]), method="trf",
                             x_scale="jac", max_nfev=400, ftol=1e-12, xtol=1e-12, gtol=1e-12,
                             tr_solver="lsmr"), full  # ("exact": a full SVD of the n x 10 Jacobian, slow)

    w_max = np.array([np.max(v), -np.min(v)])
    for straight in (False, True):
        if straight and best is not None:
            # only when the digressive fit barely bends over the data (k_d (w_max - v_k) < 0.5 both ways:
            # the slope falls by a third at most), as a straight valve's fit does
            bend = best[1][8:10] * np.maximum(w_max - best[1][[0, 3]], 0.0)
            if np.any(bend >= 0.5):
                break
        for frac in (0.15, 0.3, 0.5):
            sol, full = solve(guess(frac), straight)
            if best is None or sol.cost < best[0]:
                best = (sol.cost, full(sol.x))
    p = np.clip(best[1], lower, upper)
    why = _valve_check(p)
    if why:  # cannot happen within the bounds; kept as the runtime's check would refuse it
        raise ValueError(f"valve fit: {why}")
    return [float(a) for a in p]
