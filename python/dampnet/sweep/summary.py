"""The summary of a sweep: counts, the best cells of each kind, the main sensitivities.

    summary(df, objectives, stats) -> the summary.json dict;  text(summary) -> summary.txt

Best: the cells with status ok of lowest objective (the spec's objective per section: training
holdout_nrmse, simulation acc_wk_rms_m_s2, fullcar acc_rms_m_s2 or, for lane changes only,
roll_peak_deg by default; lower is better; cells without the metric are not ranked). Sensitivity: for each
parameter that takes more than one value among the ok cells, the objective's mean, min and max
over the cells at each value, and the spread of those means (max - min): the parameters that
move the objective most come first.
"""

from __future__ import annotations

import math
from typing import Any

from dampnet.sweep.spec import KINDS, section_params

SUMMARY_SCHEMA = "dampnet.sweep.summary/1"
N_BEST = 5
MAX_LEVELS = 6


def varied(df, kind: str) -> list[str]:
    """The parameters of `kind` taking more than one value among its ok cells."""
    ok = df[(df["kind"] == kind) & (df["status"] == "ok")]
    return [p.name for p in section_params(kind)
            if p.name in ok.columns and ok[p.name].dropna().astype(str).nunique() > 1]


def sensitivity(df, kind: str, objective: str) -> list[dict[str, Any]]:
    """Per varied parameter: the objective at each of its values (levels), or, for a number taking
    more than MAX_LEVELS values (random draws), the least-squares line through the cells (slope
    per unit of the parameter) and the rank correlation. "spread": how far the objective moves
    across the parameter (max - min of the level means, or |slope| x the parameter's range)."""
    import numpy as np

    ok = df[(df["kind"] == kind) & (df["status"] == "ok")]
    if objective not in ok.columns:
        return []
    out: list[dict[str, Any]] = []
    for name in varied(df, kind):
        sub = ok[[name, objective]].dropna()
        if sub.empty:
            continue
        x = _numbers(sub[name])
        if x is not None and len(set(x)) > MAX_LEVELS:
            y = sub[objective].to_numpy(dtype=float)
            slope = float(np.polyfit(x, y, 1)[0])
            rx, ry = (np.argsort(np.argsort(a)) for a in (x, y))
            rho = float(np.corrcoef(rx, ry)[0, 1]) if np.std(rx) > 0 and np.std(ry) > 0 else 0.0
            out.append({"parameter": name, "spread": abs(slope) * float(np.ptp(x)), "slope": slope,
                        "rank_correlation": rho, "range": [float(x.min()), float(x.max())], "cells": int(x.size)})
            continue
        g = sub.groupby(sub[name].astype(str), sort=False)[objective]
        levels: list[dict[str, Any]] = [{"value": str(v), "mean": float(s_.mean()), "min": float(s_.min()),
                                         "max": float(s_.max()), "cells": int(s_.size)} for v, s_ in g]
        means: list[float] = [lv["mean"] for lv in levels]
        out.append({"parameter": name, "spread": max(means) - min(means), "levels": levels})
    out.sort(key=lambda d: -float(d["spread"]) if math.isfinite(d["spread"]) else 0.0)
    return out


def _numbers(col):
    import numpy as np

    try:
        x = np.asarray(col, dtype=float)
    except (TypeError, ValueError):
        return None
    return x if np.all(np.isfinite(x)) else None


def best(df, kind: str, objective: str, n: int = N_BEST) -> list[dict[str, Any]]:
    ok = df[(df["kind"] == kind) & (df["status"] == "ok")]
    if objective not in ok.columns:
        return []
    ok = ok.dropna(subset=[objective]).sort_values(objective, kind="stable").head(n)
    params = [p.name for p in section_params(kind) if p.name in ok.columns]
    vary = varied(df, kind)
    rows = []
    for _, r in ok.iterrows():
        d = {"cell": r["cell"], objective: float(r[objective]),
             "params": {k: _plain(r[k]) for k in params if _plain(r[k]) is not None},
             "varied": [k for k in vary if _plain(r[k]) is not None]}
        if "model_dir" in r and isinstance(r["model_dir"], str):
            d["model_dir"] = r["model_dir"]
        rows.append(d)
    return rows


def _plain(v: Any) -> Any:
    """A table value as plain JSON (None for NaN / NA)."""
    import pandas as pd

    if v is None or (not isinstance(v, (list, tuple, str)) and pd.isna(v)):
        return None
    return v.item() if hasattr(v, "item") else v


def summary(df, objectives: dict[str, str], stats: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {"schema": SUMMARY_SCHEMA, "cells": int(len(df)),
                           "ok": int((df["status"] == "ok").sum()), "errors": int((df["status"] == "error").sum()),
                           **stats}
    for kind, objective in objectives.items():
        sel = df[df["kind"] == kind]
        errs = sel[sel["status"] == "error"]
        out[kind] = {"objective": objective, "lower_is_better": True, "cells": int(len(sel)),
                     "errors": [{"cell": r["cell"], "error": r["error"]} for _, r in errs.head(20).iterrows()],
                     "best": best(df, kind, objective), "sensitivity": sensitivity(df, kind, objective)}
    return out


def _short(v: Any) -> str:
    """A value for summary.txt: numbers to 4 significant digits."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return str(v) if isinstance(v, (int, bool)) or (isinstance(v, str) and not v.replace(".", "").isdigit()) \
        else f"{f:.4g}"


def text(s: dict[str, Any]) -> str:
    lines = [f"dampnet sweep: {s['cells']} cells, {s['ok']} ok, {s['errors']} errors "
             f"({s.get('computed', 0)} computed, {s.get('reused', 0)} reused from an earlier run) "
             f"in {s.get('wall_s', 0.0):.1f} s on {s.get('workers', '?')} workers ({s.get('scheduler', '?')}, "
             f"data {s.get('data', '?')})"]
    for kind in KINDS:
        if kind not in s:
            continue
        d = s[kind]
        obj = d["objective"]
        lines += ["", f"{kind}: {d['cells']} cells; best by {obj} (lower is better):"]
        for i, b in enumerate(d["best"], 1):
            where = f"  -> {b['model_dir']}" if "model_dir" in b else ""
            ps = ", ".join(f"{k}={_short(b['params'][k])}" for k in b["varied"]) or "(the only cell)"
            lines.append(f"  {i}. {obj} {b[obj]:.6g}  {ps}{where}")
        if d["sensitivity"]:
            lines.append(f"  sensitivity of {obj} (mean per value; parameters by spread):")
            for sdict in d["sensitivity"]:
                if "slope" in sdict:
                    lo, hi = sdict["range"]
                    lines.append(f"    {sdict['parameter']}: slope {sdict['slope']:.4g} per unit over "
                                 f"[{lo:.4g}, {hi:.4g}] (rank correlation {sdict['rank_correlation']:+.2f}, "
                                 f"{sdict['cells']} cells)")
                    continue
                vals = ", ".join(f"{_short(lv['value'])}: {lv['mean']:.4g}" for lv in sdict["levels"][:8])
                more = " ..." if len(sdict["levels"]) > 8 else ""
                lines.append(f"    {sdict['parameter']}: {vals}{more}")
        for e in d["errors"]:
            lines.append(f"  error in cell {e['cell']}: {e['error']}")
    return "\n".join(lines) + "\n"
