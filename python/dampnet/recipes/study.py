"""The thesis's chapter 5 comparison by names: what `dampnet study` runs and writes.

    run(model, data=None, dt=1e-3, seed=0, quick=False, vehicle=False, control=False, keep_runs=True,
        progress=None)
        -> {"quarter_car": the quarter-car study (dampnet.sim.quarter_car.study.run_study: impulse,
            sine sweep, rough road at two speeds, skyhook), "vehicle": the full-vehicle study
            (bounce sweep and lane change) or None, "control": MODEL's force laws through its
            inverse against the ideal on ISO 8608 roads (dampnet.recipes.control_study) or None}
    save(out, study, plots=True)   study.json (the marker), study.txt, the PNGs (control_vs_ideal.png
                                   with the control study) and inputs.npz
    lines(study, out, plots=True)  what the command prints

The models: MODEL (a model directory or model.json, 'default', a lookup table, 'truth', ...),
the lookup table fitted to DATA (a dataset) when given, and the rig's truth damper (its effects
as the data's) when DATA comes from the virtual rig. The control laws are built and calibrated
by the control-law registry (dampnet.recipes.control_laws.make).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Sequence

#: the files of a study directory (study.json is its marker: the study's schema)
FILES = ("study.json", "study.txt", "inputs.npz")
#: the control study's figure in a study directory
CONTROL_PLOT = "control_vs_ideal.png"
#: the control study's roads and speeds with --quick: one case
QUICK_CONTROL = {"classes": ("C",), "speeds": (80.0,)}


def check(out: str | Path, inputs, force: bool) -> None:
    """Before the study: `out` is new, or (force) a study directory (never an input)."""
    from dampnet.outputs import check_run_dir
    from dampnet.sim.quarter_car.study import SCHEMA
    from dampnet.sim.run_dir import schema_family

    check_run_dir(Path(out), FILES, "study.json", schema_family(SCHEMA),
                  [p for p in inputs if p and Path(p).exists()], force)


def run(model: str, data: str | None = None, *, dt: float = 1e-3, seed: int = 0, quick: bool = False,
        vehicle: bool = False, control: bool = False, control_classes: Sequence[str] | None = None,
        control_speeds: Sequence[float] | None = None, keep_runs: bool = True,
        progress: Callable[[str], Any] | None = None) -> dict[str, Any]:
    """The study (see the module docstring); `progress(line)` hears each run as it starts. The
    control study runs on MODEL alone, on ISO 8608 classes `control_classes` at `control_speeds`
    [km/h] (default: control_study's B, C, D at 40, 80, 120; QUICK_CONTROL with quick)."""
    from dampnet.data.types import RIG_GENERATOR
    from dampnet.recipes import control_laws, maneuvers
    from dampnet.sim.dampers import load_spec, lookup_spec, truth_spec
    from dampnet.sim.quarter_car.study import run_study
    from dampnet.sim.roads import sine_sweep, thesis_rough_road

    say = progress or (lambda s: None)
    roads = ({"sweep": sine_sweep(rate_oct_s=0.5), "rough": thesis_rough_road(seed=seed, base_length_m=46.0)}
             if quick else {})
    specs = [load_spec(model)]
    if control:   # before any run: the control study needs a damper the runtime can invert
        from dampnet.recipes import control_study

        control_study.check_spec(specs[0], str(model))
    truth = None
    if data:
        from dampnet.data import load_dataset
        from dampnet.evaluation.lookup import fit_lookup

        ds = load_dataset(data)
        specs.append(lookup_spec(fit_lookup(ds)))
        if ds.meta.get("generator") == RIG_GENERATOR:
            truth = truth_spec(list(ds.meta.get("effects", {})))
    res = run_study(specs, truth, dt=dt, seed=seed, keep_runs=keep_runs, laws=control_laws.make,
                    progress=say, **roads)
    full = None
    if vehicle:   # BSST (a 4x faster sweep with quick) and the lane change, low / high damping and skyhook
        tests = {"bsst_heave": maneuvers.build("bsst", dt, {"bsst_rate_oct_s": 1.0 if quick else 0.25}),
                 "dlc": maneuvers.build("dlc", dt)}
        full = maneuvers.run_study(specs + ([truth] if truth else []), tests, progress=lambda s: say(f"vehicle {s}"))
    ctrl = None
    if control:
        from dampnet.recipes import control_study

        default = QUICK_CONTROL if quick else {"classes": control_study.ROAD_CLASSES,
                                               "speeds": control_study.SPEEDS_KMH}
        ctrl = control_study.run(specs[0], tuple(control_classes or default["classes"]),
                                 tuple(control_speeds or default["speeds"]), seed=seed,
                                 label=str(model), progress=lambda s: say(f"control {s}"))
    return {"quarter_car": res, "vehicle": full, "control": ctrl}


def table(study: dict[str, Any]) -> str:
    """The study's tables as text (study.txt)."""
    from dampnet.sim.quarter_car.report import text_tables

    text = text_tables(study["quarter_car"])
    if study["vehicle"] is not None:
        from dampnet.sim.full_car.study import text_table

        text += "\n\nfull vehicle (chapter 5.2)\n" + text_table(study["vehicle"])
    if study.get("control") is not None:
        from dampnet.recipes import control_study

        text += ("\n\nsemi-active control through the damper's inverse against the ideal (ISO 8608 roads)\n"
                 + "\n".join(control_study.text_tables(study["control"])))
    return text


def save(out: str | Path, study: dict[str, Any], plots: bool = True) -> Path:
    """study.json (moved into place last), study.txt and, with plots, the PNGs and the neural
    models' damper inputs (inputs.npz, for `dampnet plan-tests STUDY_DIR`); a replaced study's
    inputs.npz is removed when this one has none."""
    from dampnet.outputs import json_text, staged_files
    from dampnet.sim.plots import write_plots
    from dampnet.sim.quarter_car.report import without_arrays
    from dampnet.sim.quarter_car.study import INPUTS_FILE, neural_inputs

    out = Path(out)
    res, full = study["quarter_car"], study["vehicle"]
    wrote_inputs = False
    with staged_files(out) as tmp:
        data = without_arrays(res)
        if full is not None:
            data["vehicle"] = {k: full[k] for k in ("results", "errors", "coverage") if k in full}
        if study.get("control") is not None:
            data["control"] = study["control"]
        (tmp / "study.json").write_text(json_text(data))
        (tmp / "study.txt").write_text(table(study) + "\n")
        if plots:
            write_plots(res, tmp)
            if study.get("control") is not None:
                from dampnet.recipes import control_study

                control_study.plot(study["control"], tmp / CONTROL_PLOT)
            inputs = neural_inputs(res)
            if inputs:
                import numpy as np

                np.savez_compressed(tmp / INPUTS_FILE, **inputs)
                wrote_inputs = True
    if not wrote_inputs and (out / INPUTS_FILE).is_file():
        (out / INPUTS_FILE).unlink()
    if not (plots and study.get("control") is not None) and (out / CONTROL_PLOT).is_file():
        (out / CONTROL_PLOT).unlink()    # a replaced study's figure that this one does not draw
    return out


def _worst_run(res: dict, name: str) -> str:
    """The run where model `name` spent the largest share of time outside its envelope, in words."""
    runs = [(by[name]["outside"]["share_time"], f"{section} {case}", by[name]["verdict"])
            for section, cases in res["coverage"].items() for case, by in cases.items() if name in by]
    share, where, verdict = max(runs)
    return f"{100 * share:.1f} % of {where}, the most ({verdict})"


def lines(study: dict[str, Any], out: str | Path, plots: bool = True) -> list[str]:
    """What `dampnet study` prints: the tables, each neural model's coverage, where it wrote."""
    res = study["quarter_car"]
    text = [table(study)]
    for name, ex in res.get("extrapolated", {}).items():
        text.append(f"coverage of {name}: " + (f"extrapolated in {len(ex['extrapolated'])} of {ex['runs']} runs: the "
                    f"model was outside its training data for {_worst_run(res, name)}" if ex["any"]
                    else f"within its training data in all {ex['runs']} runs"))
    if study.get("control") is not None:
        from dampnet.recipes import control_study

        text.append(control_study.headline(study["control"]))
    text.append(f"-> {out}/study.json, study.txt" + ("" if not plots else ", PNG plots"))
    return text
