"""A study's result (dampnet.sim.quarter_car.study.run_study) as text: tables, and the dict for JSON."""

from __future__ import annotations

from dampnet.sim.quarter_car.study import SKYHOOK_LAWS


def text_tables(res: dict) -> str:
    """Short text tables: Table 6 (sweep/impulse), Table 7 (rough road), skyhook, errors vs truth."""
    models = res["models"]
    lines = []

    def table(title, section, cases, metric, fmt="{:10.4f}"):
        lines.append(title)
        lines.append("  " + f"{'case':<22}" + "".join(f"{m:>12}" for m in models))
        for c in cases:
            row = res[section].get(c, {})
            lines.append("  " + f"{c:<22}" + "".join(
                f"{fmt.format(row[m][metric]) if m in row else '':>12}" for m in models))

    table("Table 6 - sine sweep: sprung acceleration RMS [m/s^2]", "sine_sweep", ("low", "high"), "acc_rms_m_s2")
    table("Table 6 - sine sweep: sprung displacement peak-to-RMS", "sine_sweep", ("low", "high"), "disp_peak_to_rms")
    table("Impulse: sprung acceleration RMS [m/s^2]", "impulse", ("low", "high"), "acc_rms_m_s2")
    table("Impulse: sprung displacement peak-to-RMS", "impulse", ("low", "high"), "disp_peak_to_rms")
    table("Table 7 - rough road: sprung acceleration RMS [m/s^2]", "rough_road", list(res["rough_road"]),
          "acc_rms_m_s2")
    table("Skyhook vs passive, rough road: sprung acceleration RMS [m/s^2]", "skyhook", list(res["skyhook"]),
          "acc_rms_m_s2")
    table("Skyhook vs passive, rough road: sprung displacement RMS [m]", "skyhook", list(res["skyhook"]),
          "disp_rms_m", fmt="{:10.5f}")
    sky = res["skyhook"]
    # cases "<v>_<law>" against "<v>_passive_low" / "<v>_passive_high" of the same speed
    gains = [(f"{c} vs {p}", c, f"{c.split('_', 1)[0]}_{p}") for c in sky
             if c.split("_", 1)[1] in SKYHOOK_LAWS
             for p in ("passive_low", "passive_high") if f"{c.split('_', 1)[0]}_{p}" in sky]
    if gains:
        c = res["settings"]["skyhook"]["continuous"]
        lines.append(f"Skyhook against passive: change of sprung acceleration RMS, % (continuous: c_sky "
                     f"{c['c_sky']:.0f}, c_min {c['c_min']:.0f}, c_max {c['c_max']:.0f} N s/m; both laws: "
                     f"command filter {1e3 * c['u_tau_s']:g} ms)")
        lines.append("  " + f"{'case':<40}" + "".join(f"{m:>12}" for m in models))
        for label, c, p in gains:
            lines.append("  " + f"{label:<40}" + "".join(
                f"{100 * (sky[c][m]['acc_rms_m_s2'] / sky[p][m]['acc_rms_m_s2'] - 1):>11.2f}%"
                if m in sky[c] and m in sky[p] else f"{'':>12}" for m in models))
    if res.get("errors"):
        lines.append(f"Error of sprung acceleration RMS against the truth ({res['truth']}), %")
        others = [m for m in models if m != res["truth"]]
        lines.append("  " + f"{'case':<34}" + "".join(f"{m:>12}" for m in others))
        for section, cases in res["errors"].items():
            for c, by in cases.items():
                lines.append("  " + f"{section + ' ' + c:<34}" + "".join(
                    f"{100 * by[m]['acc_rms_m_s2']:>11.2f}%" for m in others))
    lines += coverage_lines(res)
    return "\n".join(lines)


def coverage_lines(res: dict) -> list[str]:
    """The coverage table (dampnet.envelope.coverage): per case and neural model, the share of the run's
    time outside the training envelope, '*' when the run is extrapolated; then each model's verdict."""
    cov = res.get("coverage") or {}
    names = list(res.get("extrapolated") or {})
    if not names:
        return []
    lines = ["Coverage: share of the run's time outside the training envelope, % (* extrapolated: over "
             f"{100 * _first(cov)['threshold_share']:g} % of the time, or beyond {_first(cov)['excursion_limit_ranges']:g} "
             "training range)"]
    lines.append("  " + f"{'case':<34}" + "".join(f"{m:>12}" for m in names))
    for section, cases in cov.items():
        for c, by in cases.items():
            lines.append("  " + f"{section + ' ' + c:<34}" + "".join(
                f"{100 * by[m]['outside']['share_time']:>10.1f}{'*' if by[m]['extrapolated'] else ' '} "
                if m in by else f"{'':>12}" for m in names))
    for m in names:
        ex = res["extrapolated"][m]
        envelope = next((by[m]["envelope"] for cases in cov.values() for by in cases.values() if m in by), "?")
        lines.append(f"  {m}: extrapolated in {len(ex['extrapolated'])} of {ex['runs']} runs"
                     + (" (no envelope file beside the model: per-input training ranges only)"
                        if envelope != "joint" else ""))
    return lines


def _first(cov: dict) -> dict:
    return next(r for cases in cov.values() for by in cases.values() for r in by.values())


def without_arrays(res: dict) -> dict:
    """The study dict without its run arrays (the "_"-prefixed keys), for its JSON file
    (written through dampnet.outputs.json_text)."""
    return {k: v for k, v in res.items() if not k.startswith("_")}
