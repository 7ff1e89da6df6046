"""`dampnet compare MODEL_A MODEL_B DATA`: the error before and after, side by side."""

from __future__ import annotations

import argparse
import json

from dampnet.commands.common import error, load_data


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "compare", help="compare two models on the same data (e.g. before and after --add)",
        description="Overall and per-frequency error tables of two models side by side, per-test changes, "
                    "and the diagnosis pictures of both (--report).")
    p.add_argument("model_a")
    p.add_argument("model_b")
    p.add_argument("data")
    p.add_argument("--holdout", action="store_true", help="only tests both models held out in training")
    p.add_argument("--json", metavar="FILE")
    p.add_argument("--report", metavar="DIR")
    p.set_defaults(handler=run)
    return p


def compare(model_a, model_b, ds) -> dict:
    from dampnet.diagnosis.context import build_context
    from dampnet.diagnosis.localise import overall_metrics

    ma = overall_metrics(build_context(model_a, ds))
    mb = overall_metrics(build_context(model_b, ds))
    keys = ("nrmse", "rmse_n", "max_abs_error_n", "mean_pct_error")
    per_freq = []
    for a, b in zip(ma["per_frequency"], mb["per_frequency"]):
        per_freq.append({"frequency_hz": a["frequency_hz"], **{f"{k}_a": a[k] for k in keys},
                         **{f"{k}_b": b[k] for k in keys}})
    per_test = [{"test_id": a["test_id"], "frequency_hz": a["frequency_hz"], "control": a["control"],
                 "nrmse_a": a["nrmse"], "nrmse_b": b["nrmse"],
                 "change_pct": 100 * (b["nrmse"] / a["nrmse"] - 1) if a["nrmse"] else None}
                for a, b in zip(ma["per_test"], mb["per_test"])]
    oa, ob = ma["overall"], mb["overall"]
    return {"a": {"id": model_a.model_id(), "features": model_a.features},
            "b": {"id": model_b.model_id(), "features": model_b.features},
            "overall": {"a": {k: oa[k] for k in keys}, "b": {k: ob[k] for k in keys},
                        "nrmse_change_pct": 100 * (ob["nrmse"] / oa["nrmse"] - 1)},
            "per_frequency": per_freq, "per_test": per_test}


def run(args) -> int:
    from dampnet.data import DataError
    from dampnet.model import MlpModel, ModelError
    from dampnet.outputs import check_output_file, check_report_dir

    try:
        if args.json:
            check_output_file(args.json, [args.model_a, args.model_b, args.data])
        if args.report:
            check_report_dir(args.report, [args.model_a, args.model_b, args.data])
        a, b = MlpModel.load(args.model_a), MlpModel.load(args.model_b)
        ds = load_data(args.data)
        if args.holdout:
            held = set((a.meta.get("data") or {}).get("holdout_tests", [])) & \
                set((b.meta.get("data") or {}).get("holdout_tests", []))
            if not held:
                raise ValueError("--holdout: the models share no held-out tests")
            ds = ds.subset([t for t in ds.tests if t.test_id in held], note="held-out tests")
        c = compare(a, b, ds)
    except (DataError, ModelError, ValueError, OSError) as e:
        return error(str(e))
    o = c["overall"]
    print(f"{'':16s}{'A':>12s}{'B':>12s}")
    for k in ("nrmse", "rmse_n", "max_abs_error_n", "mean_pct_error"):
        print(f"{k:16s}{o['a'][k]:12.5g}{o['b'][k]:12.5g}")
    print(f"NRMSE change: {o['nrmse_change_pct']:+.1f} %  (A features {c['a']['features']}, B {c['b']['features']})")
    print(f"{'f [Hz]':>8s}{'NRMSE A':>12s}{'NRMSE B':>12s}")
    for r in c["per_frequency"]:
        print(f"{str(r['frequency_hz']):>8s}{r['nrmse_a']:12.5f}{r['nrmse_b']:12.5f}")
    worse = [r for r in c["per_test"] if r["change_pct"] is not None and r["change_pct"] > 0]
    print(f"tests improved: {len(c['per_test']) - len(worse)} of {len(c['per_test'])}")
    if args.json:
        from dampnet.outputs import atomic_write_text

        try:
            atomic_write_text(args.json, json.dumps(c, indent=1) + "\n", overwrite=True)
        except OSError as e:
            return error(f"{args.json}: cannot write ({e.strerror or e})")
    if args.report:
        from pathlib import Path

        from dampnet.outputs import staged_files

        try:
            with staged_files(args.report) as tmp:
                write_report(a, b, ds, c, tmp)
        except OSError as e:
            return error(f"{args.report}: cannot write the report ({e.strerror or e})")
        print(f"report: {Path(args.report) / 'index.html'}")
    return 0


def write_report(a, b, ds, c: dict, out) -> None:
    """index.html with the per-frequency table and both models' diagnosis pictures, into `out`."""
    from dampnet.diagnosis.context import build_context
    from dampnet.diagnosis.report import figures
    from dampnet.diagnosis.run import diagnose

    o = c["overall"]
    parts = []
    for tag, m in (("a_", a), ("b_", b)):
        ctx = build_context(m, ds)
        d = diagnose(m, ds, ctx=ctx, n_surrogates=19)
        figs = figures(ctx, d, out, tag)
        parts.append((tag, d, figs))
    rows = "".join(f"<tr><td>{r['frequency_hz']}</td><td>{r['nrmse_a']:.5f}</td><td>{r['nrmse_b']:.5f}</td></tr>"
                   for r in c["per_frequency"])
    cols = "".join(f"<td valign=top><h3>{'before (A)' if t == 'a_' else 'after (B)'}: verdict "
                   f"{d['verdict']}</h3>" + "".join(f"<img src='{f}' width=480><p>{cap}</p>" for f, cap in figs)
                   + "</td>" for t, d, figs in parts)
    (out / "index.html").write_text(
        f"<!doctype html><html><body><h1>dampnet compare</h1><p>NRMSE A {o['a']['nrmse']:.5f}, "
        f"B {o['b']['nrmse']:.5f} ({o['nrmse_change_pct']:+.1f} %)</p><table border=1><tr><th>f [Hz]</th>"
        f"<th>NRMSE A</th><th>NRMSE B</th></tr>{rows}</table><table><tr>{cols}</tr></table></body></html>")

