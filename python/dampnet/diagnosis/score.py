"""Honest statistics for a candidate effect: cross-validation over tests and a null distribution.

For a candidate with regressors C (per test, from the physics) and the baseline
basis B of the model's own inputs (`dampnet.diagnosis.basis`):

  score = sum over folds of [SSE(held-out | B) - SSE(held-out | B + C)] / sum of held-out r^2

with both fits made on the other tests only (folds are whole tests, stratified
by frequency and control). It is the share of the held-out residual variance
the effect explains beyond what a function of the model's own inputs can. A
candidate's nonlinear parameter (a time constant) is chosen within each fold on
the training tests only.

Null: surrogate residuals with each test's residual's power spectrum and random
phases (per test, so autocorrelation and per-test level are kept while any
relation to the inputs is destroyed) go through exactly the same
cross-validation. A candidate is significant when its score exceeds every
surrogate's, lies at least Z_MIN null standard deviations above the null mean,
and is at least MIN_SCORE (it explains a share of the residual worth adding
an input for; below that the model is at its noise or capacity floor).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from dampnet.diagnosis.basis import baseline_basis

N_SURROGATES = 49
Z_MIN = 3.0
MIN_SCORE = 0.05
MAX_FOLDS = 10
RIDGE = 1e-2


@dataclass
class Design:
    """Per-test cross products of [B, C] (standardised columns) with each other and with the residual
    and surrogates. G is kept in two blocks: B's own, the same for every candidate of a pass (its sums
    over folds are cached in `shared`), and C's with [B, C]."""

    GB: np.ndarray       # [n_tests, p0, p0]  B^T B
    GC: np.ndarray       # [n_tests, p, q]  [B, C]^T C (q = 0: the baseline alone)
    H: np.ndarray        # [n_tests, p, 1 + S]  (column 0: the residual, then surrogates)
    SS: np.ndarray       # [n_tests, 1 + S]
    scale: np.ndarray    # [p] column scales
    p0: int              # number of baseline columns
    shared: dict         # the pass's baseline products (B's fold sums are kept there)

    @property
    def G(self) -> np.ndarray:
        """[n_tests, p, p], assembled from the blocks"""
        return _joined(self.GB, self.GC)


def folds_of(ctx, k_max: int = MAX_FOLDS) -> list[np.ndarray]:
    """Test indices per fold: tests sorted by (frequency, control, id), dealt round-robin."""
    n = ctx.n_tests
    order = sorted(range(n), key=lambda i: (ctx.tests[i].test.frequency_hz or 0.0,
                                            ctx.tests[i].test.control_nominal or 0.0,
                                            ctx.tests[i].test.test_id))
    k = min(n, k_max)
    return [np.array(sorted(order[j::k])) for j in range(k)]


def surrogates(resid_rows: list[np.ndarray], n: int, seed: int = 0) -> list[np.ndarray]:
    """[rows, n] phase-randomised copies of each test's residual (same power spectrum)."""
    rng = np.random.default_rng(seed)
    out = []
    for r in resid_rows:
        m = len(r)
        spec = np.fft.rfft(r)
        ph = rng.uniform(0, 2 * np.pi, size=(n, spec.size))
        ph[:, 0] = 0.0
        if m % 2 == 0:
            ph[:, -1] = 0.0
        s = np.fft.irfft(spec[None, :] * np.exp(1j * ph), m, axis=1)
        out.append(s.T)
    return out


def baseline_rows(ctx) -> list[np.ndarray]:
    """Baseline basis per test, plus the regressors of effects the model already has as inputs."""
    if "baseline" not in ctx.notes:
        B = [baseline_basis(ctx.normalised_inputs(i), ctx.model.features) for i in range(ctx.n_tests)]
        for cand, theta in ctx.notes.get("included", []):
            C = cand.columns(ctx, theta)
            if C is not None:
                B = [np.hstack([b, c]) for b, c in zip(B, C)]
        ctx.notes["baseline"] = B
    return ctx.notes["baseline"]


def _baseline_gram(ctx) -> dict:
    """B^T B per test and B's column scales (RMS over all rows): computed once for the reference
    residual and every design of a pass."""
    cache = ctx.notes.setdefault("baseline_products", {})
    if "gram" not in cache:
        B = baseline_rows(ctx)
        n = sum(len(b) for b in B)
        cache["gram"] = {"BB": np.stack([b.T @ b for b in B]), "n": n,
                         "scale": _column_scale(np.sum(np.stack([np.sum(b * b, axis=0) for b in B]), axis=0), n)}
    return cache["gram"]


def _baseline_products(ctx, Y) -> dict:
    """B's cross products per test with itself and with Y, divided by B's column scales, the
    scales, the row count, Y's sums of squares per test and B transposed (contiguous: B^T C is twice
    as fast from it): the same for every candidate of a pass (a candidate's columns leave the
    baseline's scales alone), so computed once."""
    key = id(Y)
    cache = ctx.notes.setdefault("baseline_products", {})
    if key not in cache:
        B = baseline_rows(ctx)
        gram = _baseline_gram(ctx)
        scale, n = gram["scale"], gram["n"]
        BY = np.stack([b.T @ y for b, y in zip(B, Y)])
        cache[key] = {"GB": gram["BB"] / scale[None, :, None] / scale[None, None, :],
                      "HB": BY / scale[None, :, None], "scale": scale, "n": n,
                      "SS": np.stack([np.sum(y * y, axis=0) for y in Y]),
                      "Bt": [np.ascontiguousarray(b.T) for b in B], "fold_sums": {}}
    return cache[key]


def _column_scale(sq, n):
    scale = np.sqrt(sq / n)
    scale[scale <= 1e-12] = 1.0
    return scale


def design(ctx, cand_cols: list[np.ndarray] | None, Y: list[np.ndarray]) -> Design:
    """Cross products of [B, C] per test (columns divided by their RMS); B's are cached."""
    base = _baseline_products(ctx, Y)
    GB, scale_b = base["GB"], base["scale"]
    if cand_cols is None:
        return Design(GB=GB, GC=np.zeros(GB.shape[:2] + (0,)), H=base["HB"], SS=base["SS"], scale=scale_b,
                      p0=len(scale_b), shared=base)
    sc = _column_scale(np.sum(np.stack([np.sum(c * c, axis=0) for c in cand_cols]), axis=0), base["n"])
    BC = np.stack([bt @ c for bt, c in zip(base["Bt"], cand_cols)]) / scale_b[None, :, None] / sc[None, None, :]
    CC = np.stack([c.T @ c for c in cand_cols]) / sc[None, :, None] / sc[None, None, :]
    CY = np.stack([c.T @ y for c, y in zip(cand_cols, Y)]) / sc[None, :, None]
    return Design(GB=GB, GC=np.concatenate([BC, CC], axis=1), H=np.concatenate([base["HB"], CY], axis=1),
                  SS=base["SS"], scale=np.concatenate([scale_b, sc]), p0=len(scale_b), shared=base)


def _joined(GB: np.ndarray, GC: np.ndarray) -> np.ndarray:
    """[..., p, p] cross products from the blocks B^T B [..., p0, p0] and [B, C]^T C [..., p, q]."""
    p0, q = GB.shape[-1], GC.shape[-1]
    if q == 0:
        return GB
    G = np.empty(GB.shape[:-2] + (p0 + q, p0 + q))
    G[..., :p0, :p0] = GB
    G[..., :, p0:] = GC
    G[..., p0:, :p0] = np.swapaxes(GC[..., :p0, :], -1, -2)
    return G


def _solve(G, H):
    """Ridge solve of G beta = H; G may be a stack [..., p, p] (each with its own ridge)."""
    p = G.shape[-1]
    lam = RIDGE * np.maximum(np.trace(G, axis1=-2, axis2=-1) / p, 1e-12)
    return np.linalg.solve(G + np.multiply.outer(lam, np.eye(p)), H)


def _sse(G, H, SS, beta):
    """Sum over the given tests of |y - X beta|^2, per column of beta (stacks broadcast)."""
    return SS - 2 * np.sum(beta * H, axis=-2) + np.sum(beta * (G @ beta), axis=-2)


def _fold_sums(A: np.ndarray, folds) -> tuple[np.ndarray, np.ndarray]:
    """Sums of A [n_tests, ...] over each fold's held-out tests and over its training tests
    ([n_folds, ...] each), in one product with 0/1 membership rows: A is read once, not once
    per fold."""
    n, k = A.shape[0], len(folds)
    held = np.zeros((k, n))
    for j, f in enumerate(folds):
        held[j, f] = 1.0
    sums = (np.vstack([held, 1.0 - held]) @ A.reshape(n, -1)).reshape((2 * k,) + A.shape[1:])
    return sums[:k], sums[k:]


def _fold_systems(D: Design, folds):
    """(G, H, SS) summed over each fold's held-out tests, and over its training tests ([n_folds, ...]);
    B's block's sums are computed once per pass and folds."""
    key = tuple(tuple(int(i) for i in f) for f in folds)
    if key not in D.shared["fold_sums"]:
        D.shared["fold_sums"][key] = _fold_sums(D.GB, folds)
    GB_held, GB_train = D.shared["fold_sums"][key]
    (GC_held, GC_train), (H_held, H_train), (SS_held, SS_train) = (_fold_sums(A, folds) for A in (D.GC, D.H, D.SS))
    return (_joined(GB_held, GC_held), H_held, SS_held), (_joined(GB_train, GC_train), H_train, SS_train)


def _cv_fits(D: Design, folds):
    """Held-out and training SSE per fold [n_folds, 1 + S], the training fits' beta
    [n_folds, p, 1 + S] (all folds' systems solved as one stack) and the all-test sums (G, H, SS)."""
    held, train = _fold_systems(D, folds)
    beta = _solve(train[0], train[1])
    total = tuple(a.sum(0) for a in held)  # every test is held out once
    return _sse(*held, beta), _sse(*train, beta), beta, total


def cv_sse(D: Design, folds):
    """Held-out SSE per fold [n_folds, 1 + S], and training-set SSE."""
    held, train, _, _ = _cv_fits(D, folds)
    return held, train


class _ThetaFit(NamedTuple):
    """A candidate's cross-validation at one value of its parameter."""

    theta: object
    columns: list           # per test [rows, q]
    design: Design
    held: np.ndarray        # held-out SSE [n_folds, 1 + S]
    train: np.ndarray       # training SSE [n_folds, 1 + S]
    fold_betas: np.ndarray  # [n_folds, p, 1 + S]
    total: tuple            # (G, H, SS) summed over all tests


def score_candidate(ctx, cand, Y: list[np.ndarray], folds, base_cv) -> dict:
    """CV score, null, chosen parameter per fold and the full-data fit of one candidate."""
    ok, note = cand.testable(ctx)
    if not ok:
        return {"testable": False, "note": note}
    grid = list(cand.grid(ctx))
    per_theta = []
    for theta in grid:
        C = cand.columns(ctx, theta)
        if C is None or all(np.allclose(c, 0) for c in C):
            continue
        D = design(ctx, C, Y)
        per_theta.append(_ThetaFit(theta, C, D, *_cv_fits(D, folds)))
    if not per_theta:
        return {"testable": False, "note": "its regressors are zero on these data"}
    base_held, base_train = base_cv
    # choose theta per fold by the training tests' SSE (per column: residual and each surrogate)
    train_stack = np.stack([t.train for t in per_theta])  # [n_theta, n_folds, 1 + S]
    held_stack = np.stack([t.held for t in per_theta])
    pick = np.argmin(train_stack, axis=0)                  # [n_folds, 1 + S]
    held_best = np.take_along_axis(held_stack, pick[None], axis=0)[0]
    gain = (base_held - held_best).sum(0)                  # [1 + S]
    ss_tot = per_theta[0].design.SS.sum(0)
    scores = gain / ss_tot
    obs, null = float(scores[0]), scores[1:]
    mu, sd = float(np.mean(null)), float(np.std(null, ddof=1)) if len(null) > 1 else 0.0
    z = (obs - mu) / sd if sd > 0 else float("inf") if obs > mu else 0.0
    p = (1 + int(np.sum(null >= obs))) / (1 + len(null))
    significant = bool(obs >= MIN_SCORE and p <= 1.0 / (1 + len(null)) + 1e-12 and z >= Z_MIN)
    # theta: full-data choice (all tests' SSE), refined by a parabola in log(theta)
    full_sse = np.array([float(_full_fit(t.total)[1][0]) for t in per_theta])
    j = int(np.argmin(full_sse))
    theta_hat = _refine(grid_vals=[t.theta for t in per_theta], sse=full_sse, j=j)
    fold_thetas = [per_theta[int(k)].theta for k in pick[:, 0]]
    best = per_theta[j]
    beta_full, _ = _full_fit(best.total)
    D = best.design
    bc = beta_full[D.p0:, 0] / D.scale[D.p0:]
    effect_rows = [c @ bc for c in best.columns]
    fold_betas = [b[D.p0:, 0] / D.scale[D.p0:] for b in best.fold_betas]  # the folds' own fits
    per_test_gain = _per_test_gain(D, folds)
    return {"testable": True, "note": note, "score": obs, "null_mean": mu, "null_sd": sd, "null_max": float(np.max(null)),
            "z": float(z), "p_value": p, "significant": significant,
            "theta": theta_hat if theta_hat is not None else best.theta, "theta_grid": best.theta,
            "fold_thetas": fold_thetas, "beta": bc, "effect_rows": effect_rows, "fold_betas": fold_betas,
            "per_test_gain": per_test_gain, "columns": best.columns,
            # the full-data choice is the grid's largest value: the effect wants more than its
            # physical range allows (it may stand in for something else)
            "at_grid_top": bool(len(grid) > 1 and best.theta == max(g for g in grid if g is not None))}


def _full_fit(total):
    """The fit on all tests from their summed (G, H, SS), and its SSE."""
    Gt, Ht, St = total
    beta = _solve(Gt, Ht)
    return beta, _sse(Gt, Ht, St, beta)


def _refine(grid_vals, sse, j):
    if grid_vals[j] is None or len(grid_vals) < 3 or j == 0 or j == len(grid_vals) - 1:
        return grid_vals[j]
    x = np.log([grid_vals[j - 1], grid_vals[j], grid_vals[j + 1]])
    y = sse[j - 1:j + 2]
    a = np.polyfit(x, y, 2)
    if a[0] <= 0:
        return grid_vals[j]
    xm = float(np.clip(-a[1] / (2 * a[0]), x[0], x[2]))
    return float(np.exp(xm))


def _per_test_gain(D: Design, folds) -> np.ndarray:
    """Per test: held-out SSE with baseline minus with baseline + candidate (residual column),
    each test scored with its fold's training fits (all tests at once)."""
    p0 = D.p0
    fold_of = np.empty(len(D.SS), dtype=int)
    for k, f in enumerate(folds):
        fold_of[f] = k
    _, (G_train, H_train, _) = _fold_systems(D, folds)
    b_full = _solve(G_train, H_train[..., :1])[fold_of]
    b_base = _solve(G_train[:, :p0, :p0], H_train[:, :p0, :1])[fold_of]
    s_full = _sse(D.G, D.H[:, :, :1], D.SS[:, :1], b_full)[:, 0]
    s_base = _sse(D.GB, D.H[:, :p0, :1], D.SS[:, :1], b_base)[:, 0]
    return s_base - s_full


def reference_residual(ctx) -> list[np.ndarray]:
    """Measured force minus the baseline basis's least-squares fit over all tests, per test (rows).

    Why not the network's own residual: a network whose inputs identify each test
    (frequency through the velocity-acceleration phase, the control level) learns
    a per-test effect (each test's oil temperature, a position force through
    x = -a / w^2) on its training tests, leaving nothing of it in their residual.
    The baseline basis is smooth across tests and cannot memorise them, so what
    a hidden effect adds stays in this reference residual.
    """
    B = baseline_rows(ctx)
    F = [td.test.channels["force"][td.rows] for td in ctx.tests]
    gram = _baseline_gram(ctx)  # the stacked rows' cross products are the sums of the tests'
    scale = gram["scale"]
    G = gram["BB"].sum(0) / scale[:, None] / scale[None, :]
    beta = _solve(G, sum(b.T @ f for b, f in zip(B, F)) / scale)
    return [f - (b / scale) @ beta for b, f in zip(B, F)]


def baseline_cv(ctx, Y, folds):
    D = design(ctx, None, Y)
    return cv_sse(D, folds)
