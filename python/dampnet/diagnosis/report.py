"""The diagnosis as pictures and an HTML page (matplotlib, no other dependency)."""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from dampnet.figures import save_figure
from dampnet.outputs import json_text


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path):
    save_figure(fig, path, 90)
    return Path(path).name


def figures(ctx, diag: dict, out: Path, tag: str = "") -> list[tuple[str, str]]:
    """Write the pictures into `out`; returns [(file name, caption)]."""
    plt = _plt()
    out.mkdir(parents=True, exist_ok=True)
    figs = []
    # heat map: RMS residual per test, frequency x control (replay / random tests in their own row)
    rows = diag["localisation"]["per_test_rms_n"]
    if len(rows) > 1:
        from dampnet.evaluation.plots import test_heatmap

        test_heatmap(rows, "rms_n", out / f"{tag}heatmap.png", "RMS residual [N]",
                     "RMS residual per test", ctx.control_name)
        figs.append((f"{tag}heatmap.png", "RMS residual per test (frequency x control; replay and random "
                                          "tests in their own row)"))
    # loops of the worst tests
    worst = [w["test_id"] for w in diag["worst_tests"][:3]]
    for td in ctx.tests:
        if td.test.test_id not in worst:
            continue
        t = td.test
        fig, axs = plt.subplots(1, 2, figsize=(9, 3.5))
        axs[0].plot(t.channels["velocity"], t.channels["force"], ".", ms=1, label="measured")
        axs[0].plot(t.channels["velocity"], td.pred, ".", ms=1, label="predicted")
        axs[0].set_xlabel("velocity [m/s]")
        axs[0].set_ylabel("force [N]")
        axs[0].legend(markerscale=8)
        if "displacement" in t.channels:
            axs[1].plot(t.channels["displacement"], t.channels["force"], ".", ms=1)
            axs[1].plot(t.channels["displacement"], td.pred, ".", ms=1)
            axs[1].set_xlabel("displacement [m]")
        fig.suptitle(f"test {t.test_id}: f = {t.frequency_hz} Hz, {t.control_name} = {t.control_nominal}")
        figs.append((_save(fig, out / f"{tag}loops_{t.test_id}.png"),
                     f"measured and predicted force-velocity and force-displacement loops, test {t.test_id}"))
    # residual surface over displacement x velocity
    xs = ctx.at_rows("displacement")
    r = np.concatenate(ctx.resid_rows())
    v = np.concatenate(ctx.at_rows("velocity"))
    if all(x is not None for x in xs):
        x = np.concatenate(xs)
        fig, ax = plt.subplots(figsize=(6, 4.5))
        hb = ax.hexbin(x, v, C=r, gridsize=30, reduce_C_function=np.mean, cmap="coolwarm")
        ax.set_xlabel("displacement [m]")
        ax.set_ylabel("velocity [m/s]")
        fig.colorbar(hb, ax=ax, label="mean residual [N]")
        figs.append((_save(fig, out / f"{tag}residual_surface.png"),
                     "restoring-force surface of the residual: horizontal bands = position-dependent force, "
                     "a split across v = 0 = friction or lag"))
    # residual against each channel
    by = diag["localisation"]["by_channel"]
    n = len(by)
    fig, axs = plt.subplots(1, n, figsize=(3 * n, 3), squeeze=False)
    for ax, (name, b) in zip(axs[0], by.items()):
        ax.errorbar(b["centres"], b["mean_n"], yerr=b["rms_n"], fmt="o-", ms=3)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(name)
    axs[0][0].set_ylabel("residual [N] (mean, RMS bar)")
    figs.append((_save(fig, out / f"{tag}residual_vs_channels.png"),
                 "residual against displacement, velocity, acceleration, control, temperature and time in the test"))
    left = _leftover_figure(ctx, diag, out, tag, plt)
    if left:
        figs.append(left)
    # residual against each candidate's fitted effect
    fits = ctx.notes.get("candidate_effects", {})
    if fits:
        fig, axs = plt.subplots(1, len(fits), figsize=(3 * len(fits), 3), squeeze=False)
        for ax, (cid, e) in zip(axs[0], fits.items()):
            e = np.concatenate(e)
            k = np.random.default_rng(0).choice(len(e), size=min(4000, len(e)), replace=False)
            ax.plot(e[k], r[k], ".", ms=1)
            ax.set_xlabel(f"{cid} fitted [N]")
        axs[0][0].set_ylabel("residual [N]")
        figs.append((_save(fig, out / f"{tag}residual_vs_candidates.png"),
                     "residual against each candidate effect's cross-validated fit (a diagonal = the effect is there)"))
    return figs


def _num(x) -> str:
    return "-" if x is None else f"{x:g}"


def _leftover_figure(ctx, diag, out, tag, plt):
    """What the structure the leftover test found looks like: its force-displacement loops, and where
    it is along the run order and the cycle (None when the diagnosis kept no fit of it)."""
    part = ctx.notes.get("leftover_part")
    fd = diag.get("leftover") or {}
    left = fd.get("before_effects")
    if part is None or left is None:
        return None
    fig, axs = plt.subplots(1, 3, figsize=(13, 3.8))
    rms = [float(np.sqrt(np.mean(p * p))) for p in part]
    show = sorted(range(len(part)), key=lambda i: -rms[i])[:3]
    for i in show:
        td = ctx.tests[i]
        x = td.test.channels.get("displacement")
        if x is None:
            continue
        o = np.argsort(td.test.time[td.rows])
        axs[0].plot(1000 * x[td.rows][o], part[i][o], lw=1,
                    label=f"{td.test.test_id}: {_num(td.test.frequency_hz)} Hz, {ctx.control_name} {_num(td.test.control_nominal)}")
    axs[0].set_xlabel("displacement [mm]")
    axs[0].set_ylabel("structure left (fitted) [N]")
    axs[0].set_title("force-displacement loop of the structure left", fontsize=9)
    axs[0].legend(fontsize=7)
    r = [float(np.mean(td.resid)) for td in ctx.tests]
    axs[1].bar(range(len(rms)), rms, color="tab:orange", label="structure left, RMS [N]")
    axs[1].plot(range(len(r)), r, "k.", ms=4, label="model residual, mean [N]")
    axs[1].axhline(0, color="k", lw=0.5)
    axs[1].set_xlabel("test in run order (dataset order)")
    axs[1].set_ylabel("[N]")
    axs[1].set_title("along the run order", fontsize=9)
    axs[1].legend(fontsize=7)
    ph = left["where"].get("by_phase_deg", [])
    if ph:
        axs[2].bar([b["phase_deg"] for b in ph], [b["rms_n"] for b in ph], width=40, color="tab:green")
        axs[2].set_xticks([0, 90, 180, 270, 360])
    axs[2].set_xlabel("phase of the cycle [deg] (90: full extension)")
    axs[2].set_ylabel("structure left, RMS [N]")
    axs[2].set_title(f"noise floor {left['noise_floor_rms_n']:.2f} N RMS", fontsize=9)
    fig.suptitle(f"structure left before the catalogue's effects: {'significant' if left['significant'] else 'not significant'}, "
                 f"{left['structure_rms_n']:.1f} N RMS ({100 * left['score']:.1f} % of the residual held out)", fontsize=10)
    return (_save(fig, out / f"{tag}structure_left.png"),
            "the catalogue-independent fit of the residual on the inputs and their history: its "
            "force-displacement loops in the three tests where it is largest, its size along the run "
            "order (with each test's mean residual) and over the phase of the cycle")


def _pct(x):
    return "" if x is None else f"{100 * x:.2f} %"


def _leftover_table(diag: dict) -> str:
    rows = []
    for when, left in (("before the catalogue's effects", diag["leftover"]["before_effects"]),
                       ("after the accepted effects", diag["leftover"]["after_effects"]),
                       ("on the data with the artefacts' fixes applied", diag["leftover"].get("after_artefact_fixes"))):
        if left is None:
            continue
        rows.append(f"<tr><td>{when}</td><td>{'yes' if left['significant'] else 'no'}</td>"
                    f"<td>{left['structure_rms_n']:.2f}</td><td>{_pct(left['score'])}</td><td>{left['z']:.1f}</td>"
                    f"<td>{left['model_residual_rms_n']:.2f}</td><td>{left['noise_floor_rms_n']:.2f}</td>"
                    f"<td>{html.escape(str(left['where'].get('most_uneven')))}</td></tr>")
    arts = "".join(f"<li><b>{html.escape(a['artefact'])}</b>: {html.escape(a['sentence'])}</li>"
                   for a in diag["artefacts"] if a.get("detected"))
    untested = "".join(f"<li>{html.escape(a['artefact'])}: not testable here: {html.escape(a.get('note', ''))}</li>"
                       for a in diag["artefacts"] if not a.get("testable", True))
    return ("<table><tr><th>structure left</th><th>significant</th><th>RMS [N]</th><th>share of the residual "
            "(held out)</th><th>z</th><th>model residual RMS [N]</th><th>noise floor RMS [N]</th>"
            "<th>most uneven by</th></tr>" + "".join(rows) + "</table>"
            + (f"<p>Measurement artefacts found:</p><ul>{arts}</ul>" if arts else
               "<p>Measurement artefacts tested (force channel time offset, drift over the run order, sign, unit "
               "and zero of each channel): none found.</p>")
            + (f"<p>Not testable on these data:</p><ul>{untested}</ul>" if untested else ""))


def not_addable_words(cid: str, channels: list[str]) -> str:
    """Why an effect the diagnosis names cannot be added to a model of these data, and what to do."""
    chans = " and ".join(f"a {c} channel" for c in channels)
    return (f"{cid} cannot be added from these data: its model input needs {chans}, which they lack "
            f"(record it, then `dampnet train DATA --add {cid}`)")


def write_report(ctx, diag: dict, out_dir, title: str = "dampnet diagnose") -> Path:
    out = Path(out_dir)
    figs = figures(ctx, diag, out)
    rows = "".join(
        f"<tr><td>{i + 1}</td><td><b>{html.escape(c['effect'])}</b><br>{html.escape(c['title'])}</td>"
        f"<td>{_pct(c['score'])}</td>"
        f"<td>{'yes' if c['significant'] else 'no'}</td>"
        f"<td>{html.escape(json.dumps(c['parameters']))}</td><td>{html.escape(c['evidence'])}</td>"
        + (f"<td><code>{html.escape(c['add_command'])}</code></td></tr>" if c.get("add_command") else
           f"<td>{html.escape(not_addable_words(c['effect'], c['missing_channels']))}</td></tr>")
        for i, c in enumerate(diag["candidates"]))
    ov = diag["overall"]
    worst = ", ".join(f"{w['test_id']} ({w['nrmse']:.4f})" for w in diag["worst_tests"])
    regions = "".join(f"<tr><td>{k}</td><td>{v['rms_n']:.2f}</td><td>{v['ratio']:.2f}</td></tr>"
                      for k, v in diag["localisation"]["regions"].items() if v["rms_n"] is not None)
    imgs = "".join(f"<figure><img src='{f}'><figcaption>{html.escape(c)}</figcaption></figure>" for f, c in figs)
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto}}td,th{{border:1px solid #ccc;padding:3px}}
table{{border-collapse:collapse}}img{{max-width:100%}}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>Model features {diag['model']['features']}; data {html.escape(str(diag['data']['source']))}
({diag['data']['n_tests']} tests).</p>
<h2>Compare</h2><p>Overall NRMSE {ov['nrmse']:.5f}, RMSE {ov['rmse_n']:.2f} N, max |error| {ov['max_abs_error_n']:.1f} N.
Worst tests: {worst}.</p>
<h2>Which physical effect is missing</h2>
<p>Catalogue verdict: <b>{diag['verdict'] or 'no catalogue effect named'}</b>. Score = held-out share of residual variance
the effect explains beyond a flexible function of the model's inputs (cross-validation over tests);
significant = above every phase-randomised surrogate, z &ge; {diag['method']['z_min']}, score &ge; {diag['method']['min_score']}.</p>
<table><tr><th>#</th><th>effect</th><th>score</th><th>significant</th><th>parameters</th><th>evidence</th><th>add</th></tr>{rows}</table>
<h2>Is anything left? (without the catalogue)</h2>
<p><b>{html.escape(diag['finding']['kind'].replace('_', ' '))}</b>: {html.escape(diag['finding']['sentence'])}</p>
{_leftover_table(diag)}
<h2>Where it fails</h2><table><tr><th>region</th><th>RMS residual [N]</th><th>ratio to overall</th></tr>{regions}</table>
{imgs}</body></html>"""
    (out / "index.html").write_text(page)
    (out / "diagnosis.json").write_text(json_text(diag))
    return out / "index.html"
