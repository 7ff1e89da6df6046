"""What one Levenberg-Marquardt epoch costs on a rig plan, and where the time goes (issue 33).

Two measurements, one torch thread:

1. Whole epochs: `dampnet.training.fit` on the plan's training rows exactly as `dampnet train`
   prepares them (default features, decimation, rest points, control prior), LM for --epochs
   epochs with the validation stop off, with and without the control prior, the runs interleaved
   (A, B, A, B, ...); per-epoch wall time from the progress records: median and 90th percentile.
2. Its parts, on the same shapes (N training rows, the prior's M points at K = levels + 1 inputs
   each, the plan's inputs and 30 hidden), repeated and interleaved: the data rows' Jacobian,
   the control prior's rows by `Layout.combination_jacobian` and, as the reference it replaced, by
   K separate `Layout.jacobian` calls (the same numbers, checked), JᵀJ over all rows on
   MlpProblem's one [n_params, rows] buffer (by lm.gram, numpy's syrk, and by torch's general product
   as before) and, as before that, the copy of the data's and the
   prior's Jacobians into one [rows, n_params] tensor and JᵀJ on that, the damped Cholesky solve,
   one trial's residual, and a whole LM epoch (`LevenbergMarquardt.step` from the same start) on
   `MlpProblem` and on a copy of it that concatenates the Jacobians as it did before.

    python bench/epoch_cost.py                      # the thesis plan, 40 epochs x 2 runs each
    python bench/epoch_cost.py --plan quick --epochs 20 --runs 1

Prints two tables; bench/LOG.md ("An LM epoch's cost on the thesis plan") quotes them.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch


def whole_epochs(prep, control_prior: float, epochs: int) -> list[float]:
    """Per-epoch wall times [s] of one LM fit of `prep`'s rows."""
    from dampnet.training import fit

    stamps = [time.perf_counter()]

    def progress(rec):
        stamps.append(time.perf_counter())

    fit(prep.X, prep.force, features=prep.features, hidden=prep.request.hidden, algorithm="lm", seed=0,
        max_epochs=epochs, max_fail=epochs, threads=1, progress=progress, control_prior=control_prior)
    return list(np.diff(stamps[1:]))  # from the first epoch's end: the set-up is not an epoch


def parts(n_rows: int, n_in: int, n_levels: int, repeats: int) -> dict[str, list[float]]:
    """Times [s] of an LM epoch's parts on random inputs of the plan's shapes."""
    from dampnet.training.control_prior import POINTS_PER_ROW, prior_rows
    from dampnet.training.lm import damped_solve, gram
    from dampnet.training.net import DTYPE, Layout

    g = torch.Generator().manual_seed(0)
    layout = Layout(n_in, (30,), "tanh")
    x = layout.init(g)
    xs = 2 * torch.rand(n_rows, n_in, dtype=DTYPE, generator=g) - 1
    levels = np.linspace(-1, 1, n_levels)[:, None]
    rows = prior_rows(xs, [n_in - 1], levels, 1.0, np.random.default_rng(0))
    assert len(rows) == int(np.ceil(min(POINTS_PER_ROW, 1 / n_levels) * n_rows))
    buf = torch.empty(layout.n_params, n_rows + len(rows), dtype=DTYPE)  # MlpProblem's layout

    def separate():  # the reference: K full Jacobians, summed
        r, jac = layout.jacobian(x, rows.xs[0])
        jac = jac.contiguous()
        for k in range(1, rows.xs.shape[0]):
            y, j = layout.jacobian(x, rows.xs[k])
            r = r + rows.coef[k] * y
            jac += rows.coef[k].unsqueeze(1) * j
        return r, jac

    r_sep, j_sep = separate()
    r_new, j_new = layout.combination_jacobian(x, rows.xs, rows.coef)
    torch.testing.assert_close(j_new, j_sep, rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(r_new, r_sep, rtol=1e-12, atol=1e-12)
    _, J = layout.jacobian(x, xs, out=buf[:, :n_rows])
    layout.combination_jacobian(x, rows.xs, rows.coef, out=buf[:, n_rows:])
    J_all = buf.T
    jj = J_all.T @ J_all
    torch.testing.assert_close(gram(J_all), jj, rtol=1e-12, atol=1e-9 * float(jj.abs().max()))
    rhs = J_all.T @ torch.randn(J_all.shape[0], dtype=DTYPE, generator=g)
    jobs = {
        "the data rows' Jacobian": lambda: layout.jacobian(x, xs, out=buf[:, :n_rows]),
        "the control prior's rows: Layout.combination_jacobian": lambda: layout.combination_jacobian(x, rows.xs, rows.coef,
                                                                                   out=buf[:, n_rows:]),
        "the same rows as K separate Jacobians, summed (before)": separate,
        "JᵀJ over all rows by lm.gram (numpy's matmul: BLAS syrk, one triangle)": lambda: gram(J_all),
        "JᵀJ over all rows by torch's product (before: gemm, both triangles)": lambda: J_all.T @ J_all,
        "copying the data's and the prior's Jacobians into one tensor (before)": lambda: torch.cat([J, j_new]),
        "that copy, then JᵀJ on it (before)": lambda: (lambda c: c.T @ c)(torch.cat([J, j_new])),
        "the damped Cholesky solve": lambda: damped_solve(jj, rhs, 1e-3),
        "one trial's residual (data and prior)": lambda: (layout.forward(x, xs), layout.combination(x, rows.xs, rows.coef)),
    }
    # one whole LM epoch from the same start, on MlpProblem and on the same problem copying the
    # Jacobians into one tensor as it did before: the same numbers, so the same trials
    from dampnet.training.lm import LevenbergMarquardt
    from dampnet.training.problem import MlpProblem

    class Copying(MlpProblem):
        def residual_jacobian(self, x):
            with torch.no_grad():
                y, J = self.layout.jacobian(x, self.xs)
                rp, jp = self.priors[0].residual_jacobian(self.layout, x)
            return torch.cat([y - self.t, rp]), torch.cat([J, jp])

    target = layout.forward(layout.init(g), xs) + 0.01 * torch.randn(n_rows, dtype=DTYPE, generator=g)
    problems = {"a whole LM epoch from one start (LevenbergMarquardt.step)": MlpProblem(layout, xs, target, prior=rows),
                "the same with the Jacobians copied (before; the prior's rows by the new path)": Copying(layout, xs, target, prior=rows)}
    for name, problem in problems.items():
        jobs[name] = (lambda pr: lambda: LevenbergMarquardt(pr, x).step())(problem)
    times: dict[str, list[float]] = {k: [] for k in jobs}
    for _ in range(repeats):  # interleaved: a busy spell hits every part alike
        for name, job in jobs.items():
            t0 = time.perf_counter()
            job()
            times[name].append(time.perf_counter() - t0)
    return times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plan", default="thesis", help="a rig plan (thesis, quick, a plan JSON)")
    ap.add_argument("--epochs", type=int, default=40, help="LM epochs per run (default 40)")
    ap.add_argument("--runs", type=int, default=2, help="runs with and without the prior, interleaved (default 2)")
    ap.add_argument("--repeats", type=int, default=15, help="repetitions of each part (default 15)")
    a = ap.parse_args()
    torch.set_num_threads(1)
    from threadpoolctl import threadpool_limits

    threadpool_limits(1, user_api="blas")  # numpy's BLAS (lm.gram) at one thread too, as fit runs it

    from dampnet.features import control_columns, control_levels
    from dampnet.rig import generate
    from dampnet.training.pipeline import prepare_training

    prep = prepare_training(generate(a.plan, seed=0))
    cols = control_columns(prep.features)
    n_levels = len(control_levels(prep.X, cols)) if cols else 0
    print(f"plan {a.plan}: {len(prep.X):,} rows x {len(prep.features)} inputs ({', '.join(prep.features)}), "
          f"{n_levels} control levels, 30 hidden; torch {torch.__version__}, 1 thread")

    epochs: dict[str, list[float]] = {"with the control prior (the default)": [], "without it": []}
    for _ in range(a.runs):
        epochs["with the control prior (the default)"] += whole_epochs(prep, 1.0, a.epochs)
        epochs["without it"] += whole_epochs(prep, 0.0, a.epochs)
    print("\n| LM epoch | median [ms] | p90 [ms] | epochs |\n|---|---|---|---|")
    for name, t in epochs.items():
        print(f"| {name} | {1e3 * np.median(t):.0f} | {1e3 * np.percentile(t, 90):.0f} | {len(t)} |")

    n_train = int(0.7 * len(prep.X))  # fit's split: 70 % trains
    times = parts(n_train, len(prep.features), max(n_levels, 2), a.repeats)
    print(f"\n| part ({n_train:,} training rows) | median [ms] | p90 [ms] |\n|---|---|---|")
    for name, t in times.items():
        print(f"| {name} | {1e3 * np.median(t):.1f} | {1e3 * np.percentile(t, 90):.1f} |")
    ratio = np.median(times["the control prior's rows: Layout.combination_jacobian"]) / np.median(
        times["the same rows as K separate Jacobians, summed (before)"])
    print(f"\ncontrol prior's rows: combination_jacobian takes {ratio:.2f}x the time of K separate Jacobians "
          "(the same numbers to 1e-12)")


if __name__ == "__main__":
    main()
