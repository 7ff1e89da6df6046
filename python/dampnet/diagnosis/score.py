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

import numpy as np

from dampnet.diagnosis.basis import baseline_basis

N_SURROGATES = 49
Z_MIN = 3.0
MIN_SCORE = 0.05
MAX_FOLDS = 10
RIDGE = 1e-2


@dataclass
class Design:
    """Per-test cross products of [B, C] (standardised columns) with the residual and surrogates."""

    G: np.ndarray        # [n_tests, p, p]
    H: np.ndarray        # [n_tests, p, 1 + S]  (column 0: the residual, then surrogates)
    SS: np.ndarray       # [n_tests, 1 + S]
    scale: np.ndarray    # [p] column scales
    p0: int              # number of baseline columns


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


def _baseline_products(ctx, Y):
    key = id(Y)
    cache = ctx.notes.setdefault("baseline_products", {})
    if key not in cache:
        B = baseline_rows(ctx)
        BB = np.stack([b.T @ b for b in B])
        BY = np.stack([b.T @ y for b, y in zip(B, Y)])
        sq = np.sum(np.stack([np.sum(b * b, axis=0) for b in B]), axis=0)
        cache[key] = (BB, BY, sq, sum(len(b) for b in B))
    return cache[key]


def design(ctx, cand_cols: list[np.ndarray] | None, Y: list[np.ndarray]) -> Design:
    """Cross products of [B, C] per test; B's own products are computed once and cached."""
    B = baseline_rows(ctx)
    BB, BY, sq_b, n = _baseline_products(ctx, Y)
    p0 = B[0].shape[1]
    if cand_cols is None:
        G, H, sq = BB, BY, sq_b
    else:
        q = cand_cols[0].shape[1]
        G = np.zeros((len(B), p0 + q, p0 + q))
        G[:, :p0, :p0] = BB
        BC = np.stack([b.T @ c for b, c in zip(B, cand_cols)])
        G[:, :p0, p0:] = BC
        G[:, p0:, :p0] = np.transpose(BC, (0, 2, 1))
        G[:, p0:, p0:] = np.stack([c.T @ c for c in cand_cols])
        H = np.concatenate([BY, np.stack([c.T @ y for c, y in zip(cand_cols, Y)])], axis=1)
        sq = np.concatenate([sq_b, np.sum(np.stack([np.sum(c * c, axis=0) for c in cand_cols]), axis=0)])
    scale = np.sqrt(sq / n)
    scale[scale <= 1e-12] = 1.0
    G = G / scale[None, :, None] / scale[None, None, :]
    H = H / scale[None, :, None]
    SS = np.stack([np.sum(y * y, axis=0) for y in Y])
    return Design(G=G, H=H, SS=SS, scale=scale, p0=p0)


def _solve(G, H, n_rows):
    p = G.shape[0]
    lam = RIDGE * max(float(np.trace(G)) / p, 1e-12)
    return np.linalg.solve(G + lam * np.eye(p), H)


def _sse(G, H, SS, beta):
    """Sum over the given tests of |y - X beta|^2, per column of beta."""
    return SS - 2 * np.einsum("pk,pk->k", beta, H) + np.einsum("pk,pq,qk->k", beta, G, beta)


def cv_sse(D: Design, folds, cols: np.ndarray | None = None):
    """Held-out SSE per fold [n_folds, 1 + S], and training-set SSE, using the columns `cols`."""
    G, H, SS = D.G, D.H, D.SS
    if cols is not None:
        G, H = G[:, cols][:, :, cols], H[:, cols]
    n = G.shape[0]
    held, train = [], []
    for f in folds:
        tr = np.setdiff1d(np.arange(n), f)
        Gt, Ht, St = G[tr].sum(0), H[tr].sum(0), SS[tr].sum(0)
        beta = _solve(Gt, Ht, None)
        held.append(_sse(G[f].sum(0), H[f].sum(0), SS[f].sum(0), beta))
        train.append(_sse(Gt, Ht, St, beta))
    return np.array(held), np.array(train)


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
        held, train = cv_sse(D, folds)
        per_theta.append((theta, C, D, held, train))
    if not per_theta:
        return {"testable": False, "note": "its regressors are zero on these data"}
    base_held, base_train = base_cv
    # choose theta per fold by the training tests' SSE (per column: residual and each surrogate)
    train_stack = np.stack([t[4] for t in per_theta])      # [n_theta, n_folds, 1 + S]
    held_stack = np.stack([t[3] for t in per_theta])
    pick = np.argmin(train_stack, axis=0)                  # [n_folds, 1 + S]
    held_best = np.take_along_axis(held_stack, pick[None], axis=0)[0]
    gain = (base_held - held_best).sum(0)                  # [1 + S]
    ss_tot = np.array([sum(float(np.sum(y[:, j] ** 2)) for y in Y) for j in range(Y[0].shape[1])])
    scores = gain / ss_tot
    obs, null = float(scores[0]), scores[1:]
    mu, sd = float(np.mean(null)), float(np.std(null, ddof=1)) if len(null) > 1 else 0.0
    z = (obs - mu) / sd if sd > 0 else float("inf") if obs > mu else 0.0
    p = (1 + int(np.sum(null >= obs))) / (1 + len(null))
    significant = bool(obs >= MIN_SCORE and p <= 1.0 / (1 + len(null)) + 1e-12 and z >= Z_MIN)
    # theta: full-data choice (all tests' SSE), refined by a parabola in log(theta)
    full_sse = np.array([float(_full_fit(t[2])[1][0]) for t in per_theta])
    j = int(np.argmin(full_sse))
    theta_hat = _refine(grid_vals=[t[0] for t in per_theta], sse=full_sse, j=j)
    fold_thetas = [per_theta[int(k)][0] for k in pick[:, 0]]
    beta_full, _ = _full_fit(per_theta[j][2])
    D = per_theta[j][2]
    bc = beta_full[D.p0:, 0] / D.scale[D.p0:]
    effect_rows = [c @ bc for c in per_theta[j][1]]
    fold_betas = []
    for f in folds:
        tr = np.setdiff1d(np.arange(D.G.shape[0]), f)
        b = _solve(D.G[tr].sum(0), D.H[tr].sum(0), None)[:, 0]
        fold_betas.append(b[D.p0:] / D.scale[D.p0:])
    per_test_gain = _per_test_gain(per_theta[j][2], folds, base_cv_design=None)
    return {"testable": True, "note": note, "score": obs, "null_mean": mu, "null_sd": sd, "null_max": float(np.max(null)),
            "z": float(z), "p_value": p, "significant": significant,
            "theta": theta_hat if theta_hat is not None else per_theta[j][0], "theta_grid": per_theta[j][0],
            "fold_thetas": fold_thetas, "beta": bc, "effect_rows": effect_rows, "fold_betas": fold_betas,
            "per_test_gain": per_test_gain, "columns": per_theta[j][1],
            # the full-data choice is the grid's largest value: the effect wants more than its
            # physical range allows (it may stand in for something else)
            "at_grid_top": bool(len(grid) > 1 and per_theta[j][0] == max(g for g in grid if g is not None))}


def _full_fit(D: Design):
    Gt, Ht, St = D.G.sum(0), D.H.sum(0), D.SS.sum(0)
    beta = _solve(Gt, Ht, None)
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


def _per_test_gain(D: Design, folds, base_cv_design=None) -> np.ndarray:
    """Per test: held-out SSE with baseline minus with baseline + candidate (residual column)."""
    n = D.G.shape[0]
    out = np.zeros(n)
    for f in folds:
        tr = np.setdiff1d(np.arange(n), f)
        Gt, Ht = D.G[tr].sum(0), D.H[tr].sum(0)
        b_full = _solve(Gt, Ht[:, :1], None)
        p0 = D.p0
        b_base = _solve(Gt[:p0, :p0], Ht[:p0, :1], None)
        for i in f:
            s_full = _sse(D.G[i], D.H[i][:, :1], D.SS[i][:1], b_full)[0]
            s_base = _sse(D.G[i][:p0, :p0], D.H[i][:p0, :1], D.SS[i][:1], b_base)[0]
            out[i] = s_base - s_full
    return out


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
    X = np.vstack(B)
    scale = np.sqrt(np.mean(X * X, axis=0))
    scale[scale <= 1e-12] = 1.0
    Xs = X / scale
    G = Xs.T @ Xs
    beta = _solve(G, Xs.T @ np.concatenate(F), None)
    return [f - (b / scale) @ beta for b, f in zip(B, F)]


def baseline_cv(ctx, Y, folds):
    D = design(ctx, None, Y)
    return cv_sse(D, folds)
