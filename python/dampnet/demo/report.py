"""The demo's one-page HTML report (images embedded, no other file needed) and a check
that it renders in a real browser (headless Chromium)."""

from __future__ import annotations

import base64
import html
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

from dampnet.figures import save_figure
from dampnet.training.restarts import BR_MAX_ROWS, SCORE_HELP
from dampnet.training.settings import ALGORITHM_NAMES

CSS = """body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222;line-height:1.45}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}
th{background:#eee}td:first-child,th:first-child{text-align:left}img{max-width:100%;border:1px solid #ddd;margin:4px 0}
.ok{color:#070}.bad{color:#a00}h2{border-bottom:2px solid #446;padding-bottom:2px;margin-top:1.8em}
pre{background:#f6f6f6;padding:8px;overflow-x:auto}figure{margin:0 0 1em 0}figcaption{font-size:90%;color:#555}"""

# Sets data-render-check on <body> once every image has loaded (or failed): the browser test reads it.
CHECK_JS = """<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var bad = imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); }).length;
  var rows = Array.prototype.slice.call(document.querySelectorAll('table')).filter(function (t) {
    return t.querySelectorAll('tr').length < 2; }).length;
  document.body.setAttribute('data-render-check', 'images=' + imgs.length + ';broken=' + bad + ';emptytables=' + rows);
});
</script>"""


def _fmt(v: Any, digits: int = 4) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return html.escape(str(v))


def _table(headers: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{_fmt(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _img(path: Path, caption: str) -> str:
    if not path.is_file():
        return ""
    data = base64.b64encode(path.read_bytes()).decode()
    return (f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _plan_section(plan: dict | None) -> str:
    """The planning story: the tests plan-tests proposed for the impulse, and the impulse after them."""
    if not plan:
        return ""
    e, o = plan["impulse_error_vs_truth"], plan["impulse_time_outside"]
    rows = [[p["test_id"], p["frequency_hz"], 1e3 * p["amplitude_m"], p["peak_velocity_m_s"],
             p["peak_acceleration_m_s2"], p["control"], p["peak_force_n"], 100 * p["share_covered_after"]]
            for p in plan["tests"]]
    res = [[k, 100 * e["before"][k], 100 * e["after"][k], 100 * o.get("before", {}).get(k, float("nan")),
            100 * o.get("after", {}).get(k, float("nan"))] for k in e["before"]]
    return ("<h3 id='plan'>The dyno tests the impulse needs (dampnet plan-tests)</h3>"
            "<p>The impulse drives the damper far beyond the 1-inch sines, so the model is guessing there. "
            f"<code>dampnet plan-tests MODEL impulse --budget {plan['budget']}</code> proposes the sines, within "
            "the dyno's stroke, velocity and force limits, that cover the damper inputs the impulse needs and the "
            f"training data lack (covered {100 * plan['share_covered_by_training']:.0f} % before, "
            f"{100 * plan['share_covered']:.0f} % with them). The virtual dyno ran them "
            f"(<code>{html.escape(plan['plan'])}</code>, the operator's table <code>{html.escape(plan['table'])}</code>), "
            "the improved model was retrained on all the tests, and the impulse was run again against the truth "
            "damper:</p>"
            + _table(["test", "frequency [Hz]", "amplitude [mm]", "peak velocity [m/s]", "peak acceleration [m/s²]",
                      "control [V]", "expected peak force [N]", "required points covered after [%]"], rows)
            + _table(["impulse, damping", "error vs truth before [%]", "after [%]", "time outside the training data "
                      "before [%]", "after [%]"], res)
            + f"<p><span class='{'ok' if plan['fixed'] else 'bad'}'>{html.escape(plan['headline'])}</span></p>")


def _coverage_section(study: dict) -> str:
    """How much of each quarter-car run the neural models spent outside their training data
    (dampnet.envelope.coverage): the runs whose verdict is 'extrapolated' are the ones not to trust."""
    cov = study.get("coverage") or {}
    if not cov:
        return ""
    rows = []
    for section, cases in cov.items():
        for case, by_model in cases.items():
            for name, c in by_model.items():
                w = c["worst_excursion"]
                rows.append([f"{section.replace('_', ' ')} {case}", name, 100 * c["outside"]["share_time"],
                             f"{w['input']} {w['ranges']:.2f}" if w["ranges"] > 0 else "none",
                             "extrapolated" if c["extrapolated"] else "within"])
    ex = study.get("extrapolated") or {}
    words = "; ".join(f"{html.escape(k)}: {len(v['extrapolated'])} of {v['runs']} runs extrapolated"
                      for k, v in ex.items())
    return ("<h3 id='coverage'>Where the models were guessing: coverage of their training data</h3>"
            "<p>Each run's damper inputs (velocity, acceleration, control, and the added features) against "
            "the model's training envelope: outside a training range, or farther from every training "
            "sample than the data's own spacing allows (dampnet.envelope.coverage). A run outside it for more than "
            "5 % of its time, or beyond a range by more than one range's width, is marked "
            f"<b>extrapolated</b>: its error against the truth is the model guessing. {words}.</p>"
            + _table(["run", "model", "time outside the training data [%]",
                      "worst excursion (input, training ranges beyond)", "verdict"], rows))


def _valve_paragraph(rec: dict | None) -> str:
    """What valve "auto" chose for the first model (dampnet.training.valve_choice), in words."""
    from dampnet.training.valve_choice import MIN_GAIN, sentence

    line = sentence(rec)
    if line is None:
        return ""
    kept = "the hybrid, the network on what the valve term leaves" if rec.get("used") else "the network alone"
    return ("<p><b>Physics first.</b> A hydraulic damper's valves have a blow-off knee in each direction, where a "
            "tanh network bends poorly, so dampnet train trains the model twice, without and with a valve term "
            "(bleed and blow-off, fitted first by least squares) under the network, and keeps the hybrid when its "
            f"validation error is lower by {100 * MIN_GAIN:g} % at least (a term costs the real-time step): here {kept}. {html.escape(line[0].upper() + line[1:])}.</p>")


def _restarts_section(restarts: dict, fig: Path) -> str:
    """Each training's restarts: the score that chose, the held-out error it could not see."""
    runs = {k: v for k, v in restarts.items() if v}
    if not runs:
        return ""
    first = next(iter(runs.values()))
    out = [f"<p>Each training ran <b>{first['n']} restarts</b> from different seeds in "
           f"{first['workers']} processes and kept the one with the lowest {html.escape(first['score'])} score "
           f"({html.escape(SCORE_HELP.get(first['score'], ''))}). The score never sees the held-out 2.25 V tests; "
           "their NRMSE is shown here after the fact, to show what a single unlucky seed would have cost.</p>"]
    rows = []
    for which, r in runs.items():
        for x in r["runs"]:
            rows.append([which, x["restart"], x["seed"], x["score"], x.get("held_back"), x.get("interpolation"),
                         x["holdout_nrmse"], "kept" if x["kept"] else ""])
    out.append(_table(["training", "restart", "seed", "score", "held-back error", "interpolation score",
                       "held-out NRMSE (not seen)", ""], rows))
    try:
        _restarts_figure(runs, fig)
        out.append(_img(fig, "held-out NRMSE of every restart (bars) and the kept one (dark): the choice "
                             "was made on the training voltages alone"))
    except Exception as e:  # a figure is a nicety; the table says it all
        out.append(f"<p>(restarts figure not drawn: {html.escape(str(e))})</p>")
    return "".join(out)


def _restarts_figure(runs: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(runs), figsize=(4.2 * len(runs), 3.2), squeeze=False)
    for ax, (which, r) in zip(axes[0], runs.items()):
        h = [x["holdout_nrmse"] for x in r["runs"]]
        colors = ["#1f4e79" if x["kept"] else "#9dc3e6" for x in r["runs"]]
        ax.bar([str(x["restart"]) for x in r["runs"]], h, color=colors)
        ax.set_ylim(0.0, 1.15 * max(h))  # from zero: the bars' heights compare honestly
        ax.set_xlabel("restart")
        ax.set_ylabel("held-out NRMSE [-]")
        ax.set_title(f"{which} model")
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, 90)


def _per_frequency(rep: dict) -> list[list[Any]]:
    rows = []
    for r in rep.get("per_frequency", []):
        rows.append([r.get("frequency_hz"), r.get("max_abs_error_n"), r.get("mean_pct_error"), r.get("nrmse")])
    return rows


THREE_WAY = {"known_effect": "a catalogue effect explains it",
             "unknown_structure": "structure left that no catalogue effect explains",
             "nothing_left": "nothing the recorded inputs predict (noise, or not testable: see the sentence)",
             "artefact": "a measurement artefact",
             "artefact_and_unknown_structure": "a measurement artefact, and structure left that no catalogue "
                                               "effect explains"}


def _three_way(dg: dict) -> str:
    """The diagnosis's three-way verdict before and after the effect is added (issue 35)."""
    rows = []
    for label, f in (("original model", dg.get("finding")), ("improved model", dg.get("finding_after"))):
        if not f:
            continue
        rows.append([label, THREE_WAY.get(f["kind"], f["kind"]), "yes" if f["structure_left"] else "no",
                     f["structure_rms_n"], 100.0 * f["structure_share"], f["model_residual_rms_n"],
                     f["noise_floor_rms_n"]])
    if not rows:
        return ""
    return ("<p>Three-way verdict: besides ranking the catalogue's effects, the diagnosis tests, without the "
            "catalogue, whether the residual is predictable at all from the inputs and their history (held out, "
            "against a null), so it can say <i>a catalogue effect explains it</i>, <i>structure is left that no "
            "catalogue effect explains</i> (not a known effect: how much and where) or <i>nothing above the noise "
            "floor</i>; measurement artefacts (a force channel recorded late, a drift along the run order) are "
            "named as such.</p>"
            + _table(["diagnosis of", "verdict", "structure left", "its RMS [N]", "share of the residual [%]",
                      "model residual RMS [N]", "noise floor RMS [N]"], rows)
            + "".join(f"<p>{html.escape(label)}: {html.escape(f['sentence'])}</p>"
                      for label, f in (("Original", dg.get("finding")), ("Improved", dg.get("finding_after")))
                      if f))


def write(work: Path, summary: dict, m0: dict, m1: dict, d0: dict, d1: dict, study: dict, bench: dict,
          vehicle: dict) -> Path:
    figs = work / "figures"
    th = summary["thesis"]
    hn = summary["holdout_nrmse"]
    dg = summary["diagnosis"]
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>dampnet demo report</title>"
             f"<style>{CSS}</style>{CHECK_JS}</head><body>",
             "<h1>dampnet demo: a neural damper model, diagnosed, improved and run in real time</h1>",
             f"<p>Plan <b>{_fmt(summary['data']['plan'])}</b>: {summary['data']['tests']} dyno tests, "
             f"{summary['data']['samples']} samples. Total time {summary['total_time_s']} s.</p>"]

    parts.append("<h2>1. The test campaign (virtual shock dyno)</h2>"
                 "<p>The thesis's Table 2 plan (12 frequencies 0.25–3 Hz × 15 control voltages, "
                 "1 inch sine) run on dampnet's virtual dyno, whose damper is physics (asymmetric, "
                 "digressive valves, voltage → current → valve opening, friction, compressibility, "
                 "sensor noise). One physical effect was switched on that the thesis's inputs cannot "
                 "see; which one is revealed only after the diagnosis below.</p>")

    algo = ALGORITHM_NAMES.get(summary.get("algorithm", {}).get("original"), "?")
    parts.append(f"<h2>2. The thesis's model: 3-30-1 MLP trained with {algo}</h2>"
                 f"<p>dampnet train's default algorithm: {ALGORITHM_NAMES['br']} up to {BR_MAX_ROWS:,} training "
                 f"rows, {ALGORITHM_NAMES['lm']} beyond (the thesis's full plan).</p>")
    parts.append(_valve_paragraph(summary.get("valve")))
    o0 = m0["holdout"]["overall"]
    lk = m0.get("holdout_lookup", {}).get("overall", {})
    parts.append(_table(["model (held-out 2.25 V tests)", "NRMSE", "RMSE [N]", "max |error| [N]",
                         "mean % error", "training time, all restarts [s]"],
                        [[f"dampnet MLP ({algo})", o0["nrmse"], o0["rmse_n"], o0["max_abs_error_n"],
                          o0["mean_pct_error"], summary["training_time_s"]["original"]],
                         ["lookup table (industry baseline)", lk.get("nrmse"), lk.get("rmse_n"),
                          lk.get("max_abs_error_n"), lk.get("mean_pct_error"), None],
                         ["thesis (Table 3, LM)", th["lm_nrmse"], None, None, None, th["lm_minutes"] * 60.0]]))
    parts.append("<p>Per frequency of the held-out voltage (the thesis's Table 4 reports max error "
                 "9.8–23 lbf = 44–102 N and average error 0.95–18.9 %):</p>")
    parts.append(_table(["frequency [Hz]", "max |error| [N]", "mean % error", "NRMSE"], _per_frequency(m0["holdout"])))
    parts.append(_restarts_section(summary.get("restarts") or {}, figs / "restarts.png"))
    for name in sorted((figs / "original").glob("*.png")):
        parts.append(_img(name, f"original model: {name.stem.replace('_', ' ')}"))

    parts.append("<h2>3. Diagnosis: where the model fails and what is missing</h2>")
    rows = [[c["effect"], c.get("score"), c.get("p_value"), "yes" if c.get("significant") else "no",
             c.get("evidence", "")[:160]] for c in d0["candidates"]]
    parts.append(_table(["candidate effect", "score (held-out residual share)", "p", "significant", "evidence"], rows))
    parts.append(f"<p>Verdict: <b>{_fmt(dg['verdict'])}</b>. The hidden effect in the data was "
                 f"<b>{dg['hidden_effect']}</b>: the diagnosis "
                 f"<span class='{'ok' if dg['named_hidden_effect'] else 'bad'}'>"
                 f"{'named it' if dg['named_hidden_effect'] else 'did not name it'}</span>.</p>")

    parts.append(_three_way(dg))

    parts.append("<h2>4. The effect added: the error falls</h2>")
    o1 = m1["holdout"]["overall"]
    parts.append(f"<p>Added as: {_fmt(dg.get('added_as'))}. {_fmt(dg.get('why'))}</p>")
    parts.append(_table(["held-out 2.25 V", "NRMSE", "RMSE [N]", "max |error| [N]", "mean % error"],
                        [["before (thesis inputs)", o0["nrmse"], o0["rmse_n"], o0["max_abs_error_n"], o0["mean_pct_error"]],
                         ["after (effect added)", o1["nrmse"], o1["rmse_n"], o1["max_abs_error_n"], o1["mean_pct_error"]],
                         ["noise floor of the data", hn.get("noise_floor"), None, None, None]]))
    parts.append(f"<p>NRMSE fell by <b>{summary['error_fall_pct']:.0f} %</b>. Diagnosis of the improved "
                 f"model: significant effects now {', '.join(dg['significant_after']) or 'none'}.</p>")
    hv = m1.get("noise_floor", {}).get("holdout_vs_floor")
    if hv:
        parts.append("<p>Against the noise floor (the rig's sensor noise, which the measured force carries): the "
                     f"improved model's held-out RMSE is <b>{hv['ratio']:.1f}×</b> the noise's RMS; per frequency "
                     + ", ".join(f"{r['frequency_hz']:g} Hz {r['ratio']:.1f}×" for r in hv["per_frequency"]
                                 if r["frequency_hz"] is not None)
                     + ". 1× would be a model as good as these data can show.</p>")
    for name in sorted((figs / "improved").glob("*.png")):
        parts.append(_img(name, f"improved model: {name.stem.replace('_', ' ')}"))

    cp = summary["c_program"]
    parts.append("<h2>5. Export to C and a C controller program</h2>"
                 f"<p>The improved model was exported to <code>model_improved/model.h</code> and compiled "
                 f"into <code>{_fmt(cp['source'])}</code> against the dampnet C library. On {cp['samples']} held-out "
                 f"samples its force differs from Python's by at most {cp['max_abs_diff_n']:.3g} N "
                 f"(tolerance {cp['tolerance_n']:.3g} N): "
                 f"<span class='{'ok' if cp['match'] else 'bad'}'>{'match' if cp['match'] else 'MISMATCH'}</span>.</p>")
    parts.append(_fmu_section(work, summary.get("fmu")))

    parts.append("<h2>6. Quarter-car study (thesis chapter 5)</h2>"
                 "<p>Thesis Table 6 (sine sweep, acceleration RMS m/s²): ANN 0.1966 / 0.2467, lookup "
                 "0.1837 / 0.1644 (low / high damping). Table 7 (rough road): ANN 0.5633–0.8676, "
                 "lookup 0.6786–1.2166. dampnet can also run the truth damper:</p>")
    parts.append(f"<pre>{html.escape(study.get('text', ''))}</pre>")
    worst = study.get("worst_acc_rms_error_vs_truth", {})
    if worst:
        case = study.get("worst_case_vs_truth", {})
        ride = study.get("worst_rough_road_error_vs_truth", {})
        parts.append("<p>Largest sprung-acceleration RMS error against the truth damper over all cases: " +
                     ", ".join(f"{html.escape(k)} {100 * v:.1f} % ({html.escape(str(case.get(k)))})"
                               for k, v in worst.items() if v is not None) +
                     "; on the rough road, passive and under skyhook, at most " +
                     ", ".join(f"{html.escape(k)} {100 * v:.1f} %" for k, v in ride.items() if v is not None) +
                     ". The thesis could not measure this. Its campaign (and this one) is 1-inch sines at "
                     "0.25–3 Hz, whose relative accelerations stay below about 9 m/s²; the impulse (a 50 mm, "
                     "50 ms bump) and the rough road drive the damper beyond that, where every model trained "
                     "on the campaign saturates or extrapolates. A campaign with road-like random excitation "
                     "on the rig closes most of the gap: a model trained on it is within 3 % of the truth on "
                     "the rough road, on the impulse and under skyhook (tests/python/test_simulate.py).</p>")
    parts.append(_coverage_section(study))
    for name in sorted((figs / "study").glob("*.png")):
        parts.append(_img(name, f"study: {name.stem.replace('_', ' ')}"))

    parts.append(_plan_section(summary.get("plan")))

    parts.append("<h2>7. Full vehicle (thesis chapter 5.2)</h2>"
                 "<p>The damper model at all four corners of a compact pickup (the runtime's full car: "
                 "heave, pitch, roll, yaw, side-slip, four wheels, Magic-Formula tyres), beside the lookup "
                 "table and the truth damper, at the low and high damping setting and under on-off skyhook. The bounce sine sweep "
                 "(0.5–20 Hz under all four wheels, the thesis's Figure 59) shows ride, as the body's and the "
                 "wheels' transmissibility with the heave and wheel-hop peaks beside the linear model's; the ISO "
                 "3888-1 double lane change driven by MacAdam's optimal-preview driver along the path of least "
                 "peak lateral acceleration through the gates (Figure 60) shows handling: at 80 km/h, the "
                 "standard's speed, the test is passed when no cone is hit; at the thesis's 120 km/h this "
                 "pickup needs about 7 m/s² of its ~8 m/s² grip and the driver fails it. "
                 "As in the thesis, the models differ in ride, hardly in handling."
                 + (" (The quick demo drives the lane change at 120 km/h only.)" if summary.get("quick") else "")
                 + "</p>")
    parts.append(f"<pre>{html.escape(vehicle.get('text', ''))}</pre>")
    parts.append(f"<p>{html.escape(vehicle.get('headline', ''))}</p>")
    for name in sorted((figs / "vehicle").glob("*.png")):
        parts.append(_img(name, f"full vehicle: {name.stem.replace('_', ' ')}"))

    parts.append("<h2>8. Real-time latency and the HIL budget</h2>")
    rows = [[k, v.get("p50_ns"), v.get("p99_ns"), v.get("p999_ns"), v.get("max_ns"), v.get("loop_ns_per_call")]
            for k, v in bench["results"].items()]
    parts.append(_table(["case", "p50 [ns]", "p99 [ns]", "p99.9 [ns]", "max [ns]", "loop [ns/call]"], rows))
    parts.append(f"<p>{html.escape(bench['headline'])}</p>")
    parts.append("</body></html>")
    path = work / "report.html"
    path.write_text("\n".join(parts))
    return path


def _fmu_section(work: Path, fm: dict | None) -> str:
    """Section 5's FMU part: the improved model as an FMU, run by FMPy, beside the runtime."""
    head = "<h3 id='fmu'>The improved model as an FMU, run by FMPy</h3>"
    if not fm:
        return ""
    if "skipped" in fm:
        built = (f" The FMU was built (<code>{_fmt(fm['path'])}</code>) but not simulated." if "path" in fm else "")
        return head + f"<p>Not checked: {_fmt(fm['skipped'])}.{built}</p>"
    ok = fm["match"]
    return (head +
            f"<p>The improved model exported as an FMI {_fmt(fm['fmi_version'])} damper FMU "
            f"(<code>{_fmt(fm['path'])}</code>; inputs x, v, a, u, "
            f"temperature, output the force), the form CarSim, CarMaker, Simulink and other vehicle "
            f"tools import. FMPy, an independent FMI importer, ran it in co-simulation at the rig's "
            f"sample time ({fm['step_s'] * 1e3:.2g} ms) on the first {fm['samples']} samples of held-out test "
            f"{_fmt(fm['test'])}, with the test's x, v, a and u as input signals. Its force differs from "
            f"the runtime's by at most <b>{fm['max_abs_diff_n']:.3g} N</b> over a force range of "
            f"{fm['force_range_n']:.0f} N (tolerance {fm['tolerance_n']:.0e} N): "
            f"<span class='{'ok' if ok else 'bad'}'>{'match' if ok else 'MISMATCH'}</span>. "
            f"FMPy records a co-simulation output one step late (after the step, with the inputs of "
            f"its start), so the FMU's trace is drawn shifted back one sample. Built in "
            f"{fm['build_time_s']:.1f} s, simulated in {fm['simulate_time_s']:.2f} s.</p>" +
            _fmu_envelope(fm.get("envelope_flags")) +
            _img(work / fm["figure"], "FMU: its force trace in FMPy beside the runtime's"))


def _fmu_envelope(ef: dict | None) -> str:
    """The FMU's envelope_flags output on the same run, in a sentence."""
    if not ef:
        return ""
    what = ("the training envelope's grid (ranges and pairs of inputs)" if ef["grid"]
            else "the training ranges only (no envelope)")
    return (f"<p>The FMU also carries {what}: its <code>envelope_flags</code> output marked "
            f"{100 * ef['share_flagged']:.1f} % of these samples outside the training data "
            f"({100 * ef['share_outside_joint']:.1f} % between training samples with every input in range), "
            f"<span class='{'ok' if ef['match'] else 'bad'}'>{'the same flags' if ef['match'] else 'NOT the flags'}"
            f"</span> as the runtime's check on the same inputs, so a vehicle tool running the FMU sees "
            f"when the model is guessing.</p>")


def check_rendering(path: Path) -> dict:
    """Open the report in headless Chromium; every image must load and every table have rows."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if not browser:
        return {"checked": False, "ok": None, "reason": "no Chromium found (Debian package chromium)"}
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=5000",
           "--dump-dom", path.resolve().as_uri()]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        return {"checked": True, "ok": False, "reason": "Chromium timed out"}
    m = re.search(r'data-render-check="images=(\d+);broken=(\d+);emptytables=(\d+)"', proc.stdout)
    if not m:
        return {"checked": True, "ok": False, "reason": "the page's load check did not run",
                "stderr": proc.stderr[-500:]}
    images, broken, empty = map(int, m.groups())
    return {"checked": True, "ok": bool(images > 0 and broken == 0 and empty == 0), "images": images,
            "broken_images": broken, "empty_tables": empty}
