"""`dampnet demo --data DATA`: the story on a user's own dyno data (issue 53): train as `dampnet
train` does by default, diagnose the model on its training tests, add what the diagnosis names,
retrain, and again (dampnet.recipes.loop), then report each model's error on held-out tests
before and after, what each diagnosis named, and what the additions give together.

Writes OUT/summary.json (every number), OUT/report.html (the table, the diagnosis's sentences,
the figures), OUT/figures/ (per-test errors of every model; the worst held-out test, measured
against the first and the last model) and OUT/models/<step>/ (each model directory, as `dampnet
train` writes it).
"""

from __future__ import annotations

import html
import time
from pathlib import Path
from typing import Any, Callable, Sequence

from dampnet.figures import save_figure

#: without a stated hold-out: every HOLDOUT_EVERY-th test in the data's order, from the third
HOLDOUT_EVERY = 5
HOLDOUT_FIRST = 2


def default_holdout(test_ids: Sequence[str]) -> list[str]:
    """Every fifth test in the data's order, starting from the third (a fifth of the tests,
    spread over the campaign); DataError with fewer than 3 tests."""
    from dampnet.data import DataError

    if len(test_ids) < 3:
        raise DataError(f"the data hold {len(test_ids)} test(s): the loop needs at least 3 (some to train on, "
                        "some held out to score on), or name the held-out ones with --holdout-tests")
    return list(test_ids[HOLDOUT_FIRST::HOLDOUT_EVERY])


def run_data_demo(ds, out_dir: str | Path, label: str, request=None, *, max_steps: int = 3,
                  force: bool = False, log: Callable[[str], None] = print, inputs: Sequence[str] = (),
                  workers: int | None = None) -> dict[str, Any]:
    """The loop on `ds` (a Dataset; `label` names it in the report) from `request` (a
    dampnet.recipes.training.TrainingRequest: `dampnet train`'s options; None: its defaults,
    algorithm, restarts and valve "auto", without the thesis's 2.25 V hold-out), written to out_dir;
    returns the summary. Held out: the request's hold-out (its tests, its control level), or
    default_holdout's tests when it holds out none."""
    from dampnet.outputs import check_output_dir, json_text, staged_dir
    from dampnet.recipes.loop import loop_summary, run_loop
    from dampnet.recipes.training import TrainingRequest
    from dampnet.training.settings import command_defaults

    out = check_output_dir(out_dir, "demo", inputs, force)
    if request is None:
        request = TrainingRequest.of(**command_defaults(), holdout_voltage=None)
    if request.holdout_tests or request.holdout_voltage is not None:
        how = " and ".join(filter(None, [
            f"the tests named ({len(request.holdout_tests)})" if request.holdout_tests else "",
            f"every test at control {request.holdout_voltage:g}" if request.holdout_voltage is not None else ""]))
    else:
        request = request.replace(holdout_tests=tuple(default_holdout(ds.test_ids)))
        how = f"every {HOLDOUT_EVERY}th test in the data's order, from the {HOLDOUT_FIRST + 1}rd (the default)"
    t_start = time.perf_counter()
    with staged_dir(out) as work:
        steps = run_loop(ds, request, max_steps=max_steps, seed=request.seed, log=lambda s: log(f"  {s}"),
                         workers=workers)
        models = work / "models"
        for step in steps:
            step.trained.save(models / _dirname(step.added))
        held = steps[0].trained.split.holdout.tests
        summary: dict[str, Any] = {
            "schema": "dampnet.demo/data-1", "data": {"label": label, "tests": len(ds.tests),
                                                      "samples": int(sum(len(t) for t in ds.tests))},
            "holdout": {"how": how, "tests": [t.test_id for t in held]}, "seed": request.seed,
            "max_steps": max_steps, **loop_summary(steps)}
        for row, step in zip(summary["steps"], steps):
            row["model_dir"] = f"models/{_dirname(step.added)}"
        figs = work / "figures"
        figs.mkdir()
        summary["figures"] = [p.relative_to(work).as_posix() for p in _figures(steps, held, figs)]
        summary["total_time_s"] = round(time.perf_counter() - t_start, 1)
        (work / "report.html").write_text(_report_html(summary))
        (work / "summary.json").write_text(json_text(summary))
    log(f"report: {out / 'report.html'}   summary: {out / 'summary.json'}   ({summary['total_time_s']:.0f} s in all)")
    return summary


def _dirname(added: Sequence[str]) -> str:
    return "default" if not added else "plus_" + "_".join(added)


def _figures(steps, held, figs: Path) -> list[Path]:
    """per_test_rmse.png (every model's held-out RMSE per test) and worst_test.png (the test the
    first model fits worst: measured force and the first and last models', over velocity)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from dampnet.predict import predict_force

    paths = []
    ids = [t.test_id for t in held]
    fig, ax = plt.subplots(figsize=(max(6.0, 0.7 * len(ids) * len(steps) / 2 + 3), 4))
    width = 0.8 / len(steps)
    for k, step in enumerate(steps):
        vals = [step.scores["per_test_rmse_n"][i] for i in ids]
        ax.bar(np.arange(len(ids)) + (k - (len(steps) - 1) / 2) * width, vals, width,
               label=f"{step.label}: {step.scores['rmse_n']:.1f} N")
    ax.set_xticks(np.arange(len(ids)), ids, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("held-out RMSE [N]")
    ax.set_title("held-out RMSE per test, each model of the loop\n(legend: its RMSE over every held-out test)",
                 fontsize=10)
    ax.legend(fontsize=8)
    paths.append(save_figure(fig, figs / "per_test_rmse.png", 110))

    worst = max(held, key=lambda t: steps[0].scores["per_test_rmse_n"][t.test_id])
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    v, f = worst.channels["velocity"], worst.channels["force"]
    ax.plot(v, f, color="0.6", lw=2.5, label="measured")
    for step, style in ((steps[0], "--"), (steps[-1], "-"))[: 1 if len(steps) == 1 else 2]:
        ax.plot(v, predict_force(step.trained.model, worst), style, lw=1.0,
                label=f"{step.label} ({step.scores['per_test_rmse_n'][worst.test_id]:.1f} N RMSE)")
    ax.set_xlabel("velocity [m/s]")
    ax.set_ylabel("force [N]")
    ax.set_title(f"held-out test {worst.test_id}: the first model's worst")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    paths.append(save_figure(fig, figs / "worst_test.png", 110))
    return paths


def _rest_cell(rest: dict | None) -> str:
    """The error at rest: RMSE [N] (bias [N]), or '-' when the held-out tests never stand still."""
    return "-" if rest is None else f"{rest['rmse_n']:.1f} ({rest['bias_n']:+.1f})"


def _outside_cell(out: dict) -> str:
    """The share of time outside the training envelope and the RMSE [N] there."""
    from dampnet.evaluation.regions import share_text

    return f"{share_text(out['share_time'])} %: {out['rmse_n']:.0f} N" if out["share_time"] else "never"


def _rest_paragraph(s: dict) -> str:
    """What the at-rest and envelope columns mean, and the at-rest error before and after."""
    first, last = s["steps"][0]["scores"], s["steps"][-1]["scores"]
    rest = first.get("at_rest")
    if rest is None:
        note = first.get("at_rest_note") or "at rest: not measured"
        return (f"<p>{html.escape(note[:1].upper() + note[1:])}. Outside the training "
                "envelope: the share of the held-out time the model's inputs were outside its training data "
                "(dampnet.evaluation.regions), and its RMSE there.</p>")
    controls = ", ".join(f"{c:g}" for c in rest["controls"])
    return (f"<p>At rest: the held-out samples where the damper stands still ({100 * rest['share_time']:.1f} % of "
            f"the time, at controls {html.escape(controls)}): RMSE [N] and bias (mean of model - measured) [N]; "
            f"the measured force there changes by {rest['force_rms_n']:.1f} N RMS within a test, what no model of "
            f"the inputs can follow. The default model's error at rest is {rest['rmse_n']:.1f} N, the loop's last "
            f"model's {last['at_rest']['rmse_n']:.1f} N. Outside the training envelope: the share of the held-out "
            "time the model's inputs were outside its training data, and its RMSE there "
            "(dampnet.evaluation.regions).</p>")


def _report_html(s: dict) -> str:
    e = html.escape
    first = s["steps"][0]["scores"]["rmse_n"]
    rows = []
    for r in s["steps"]:
        sc = r["scores"]
        change = "" if r is s["steps"][0] else f"{100.0 * (sc['rmse_n'] / first - 1.0):+.1f} %"
        sentence = (r["finding"] or {}).get("sentence") or ""
        rows.append(f"<tr><td>{e(r['label'])}</td><td>{sc['rmse_n']:.1f}</td><td>{sc['nrmse']:.4f}</td>"
                    f"<td>{change}</td><td>{_rest_cell(sc.get('at_rest'))}</td>"
                    f"<td>{_outside_cell(sc['outside_envelope'])}</td><td>{r['train_s']:.0f}</td>"
                    f"<td>{e(', '.join(r['named_all']) or 'nothing')}</td>"
                    f"<td>{e(sentence)}</td></tr>")
    together = s.get("together")
    if together and len(together["added"]) > 1:
        tog = (f"<p>Added together, in the order the diagnoses named them ({e(' then '.join(together['added']))}; "
               f"each diagnosis is of the model with the effects added before it): held-out RMSE "
               f"{together['rmse_n']:.1f} N, {together['change_pct']:+.1f} % against the default model.</p>")
    elif together:
        tog = (f"<p>Adding {e(together['added'][0])}: held-out RMSE {together['rmse_n']:.1f} N, "
               f"{together['change_pct']:+.1f} % against the default model.</p>")
    else:
        tog = "<p>Nothing was added: the default model is the loop's result.</p>"
    figs = "".join(f'<p><img src="{e(p)}" alt="{e(p)}" style="max-width:100%"></p>' for p in s["figures"])
    return f"""<!doctype html>
<html><head><meta charset="utf-8"><title>dampnet: the loop on {e(s['data']['label'])}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:0.3em 0.6em;text-align:left}}</style></head><body>
<h1>The loop on {e(s['data']['label'])}</h1>
<p>{s['data']['tests']} tests, {s['data']['samples']:,} samples. Held out (never trained on, never diagnosed):
{e(s['holdout']['how'])}: {e(', '.join(s['holdout']['tests']))}. Each model is diagnosed on its training tests;
every effect its diagnosis names is added, in the diagnosis's order (as <code>dampnet train --add A --add B
--diagnosis FILE</code>: each explains what is left after the ones before it), and the model retrained, up to
{s['max_steps']} effects in all.</p>
<table><tr><th>model</th><th>held-out RMSE [N]</th><th>NRMSE</th><th>against the default</th>
<th>at rest: RMSE (bias) [N]</th><th>outside the envelope: time, RMSE</th><th>training [s]</th>
<th>its diagnosis named</th><th>the diagnosis's sentence</th></tr>
{''.join(rows)}</table>
{_rest_paragraph(s)}
{tog}
<p>The loop stopped: {e(s['stop'] or '')}.</p>
{figs}
<p>Every number: summary.json; each model's directory: {e(', '.join(r['model_dir'] for r in s['steps']))}.</p>
</body></html>
"""
