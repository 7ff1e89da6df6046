"""Planning dyno tests: the sines that would put a model's missing region into its training data.

`dampnet plan-tests MODEL RUN... --budget N` (issue 20). From

  required   the damper inputs of the runs the model must serve (a `dampnet simulate` or
             `dampnet vehicle` output directory: its run.npz keeps every step's inputs; a
             `dampnet study` directory: its inputs.npz, every run of the model; or a
             built-in case run on the spot with the model: a road by name,
             dampnet.recipes.roads, e.g. `impulse`, `sine-sweep`, `rough-road`, each
             optionally `:low` / `:high` damping), kept where they are
             outside the model's training envelope (dampnet.envelope: beyond a training range
             or farther than the threshold from every training sample), and
  covered    the envelope's training samples,

it proposes the N dyno sines (frequency [Hz], amplitude [m], control level [V or A]) within the
dyno's limits that cover the required points best, by greedy set cover:

  candidates  every frequency x amplitude x control of the grids whose stroke 2A, peak velocity
              2 pi f A and expected peak force stay within the limits; each candidate's
              trajectory is one steady cycle of the model's inputs on that sine, built by the
              feature registry exactly as training would build it (acceleration from velocity
              with the model's filter window, derived features included);
  space       the *planning space*: each input's range over the training data and the required
              points together mapped onto [-1, 1], as the mapminmax of a model retrained on the
              union would scale it (the current model's scaled space would make the threshold
              a few hundredths of today's narrow ranges: far finer than the new data need);
  radius      a required point is covered by a candidate (or by the training data) within the
              envelope's threshold in that space (`radius`, default the envelope's threshold;
              DEFAULT_RADIUS without an envelope);
  greedy      pick the candidate covering the most still-uncovered required points, repeat N
              times (or until no candidate covers another point); the share of required points
              covered after each pick is reported.

The expected peak force of a candidate is the model's own force on the sine, linearly
extrapolated in velocity beyond the model's training range (F at the range's edge x |v| /
|v_edge|: a damper's force grows more slowly than that at high velocity, so the estimate errs
high, on the safe side of the force limit).

`plan_tests` returns a JSON-ready dict; `rig_plan` the plan for `dampnet rig --plan`
(dampnet.rig.plans: an explicit list of tests); `table_rows` / `format_table` the operator's
table.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dampnet.sim.run_dir import FULL_CAR, QUARTER_CAR

SCHEMA = "dampnet.plan-tests/1"
#: candidate grids' defaults: frequencies [Hz] and amplitudes [m]
DEFAULT_FREQUENCIES_HZ = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 18.0, 20.0, 25.0)
DEFAULT_AMPLITUDES_M = (0.002, 0.005, 0.0075, 0.01, 0.0125, 0.015, 0.02, 0.0254)
#: dyno limits' defaults: stroke (peak to peak, 2 A) [m], peak velocity [m/s], force [N]
DEFAULT_MAX_STROKE_M = 0.0508       # the thesis damper's 2-inch stroke (the 1-inch sines use all of it)
DEFAULT_MAX_VELOCITY_M_S = 3.0      # a high-velocity hydraulic dyno's
DEFAULT_MAX_FORCE_N = 10000.0
#: coverage radius in the planning space without an envelope (scaled units)
DEFAULT_RADIUS = 0.1
#: at most this many required points (a seeded subsample beyond)
MAX_REQUIRED = 5000
#: points per candidate cycle used for the cover
CYCLE_POINTS = 400
#: the rig plan's sampling of the proposed tests
SAMPLE_RATE_HZ = 5000.0
MIN_SAMPLES = 2500
MIN_CYCLES = 3.0
#: built-in cases: a road by name (dampnet.recipes.roads; the cases' old names are its aliases),
#: a distance profile at the road's case speeds (the rough road's: the thesis's 10 and 20 m/s)
CASES = ("impulse", "sine-sweep", "rough-road")


def case_names() -> str:
    """The built-in cases as the help and the errors name them: every road of the registry."""
    from dampnet.recipes import roads

    return ", ".join(k.usage() for k in map(roads.get, roads.names()))


def _case_road(text: str):
    """(the road request, the damping level or "") of a built-in case ROAD[:low|:high], or None
    when `text` names no road of the registry."""
    from dampnet.recipes import roads

    head, sep, tail = text.rpartition(":")
    road, level = (head, tail) if sep and tail in ("low", "high") else (text, "")
    if not roads.is_named(road):
        return None
    try:
        return roads.parse(road), level
    except ValueError as e:
        head_req = _parsed(head) if sep and "=" not in tail else None
        if head_req is not None and (head_req.kind.positional is None or ":" in head):   # ROAD:medium: a damping
            raise PlanError(f"RUN {text!r}: damping {tail!r}: expected {head}:low or {head}:high") from None
        raise PlanError(f"RUN {text!r}: {e}") from None


def _parsed(road: str):
    """The road request of `road`, or None when it is none."""
    from dampnet.recipes import roads

    try:
        return roads.parse(road) if roads.is_named(road) else None
    except ValueError:
        return None


class PlanError(ValueError):
    """Bad input to the planner (one line, naming the argument or file)."""


@dataclass
class RunInputs:
    """One run's damper inputs: X [n, n_inputs] in the model's features (feature units),
    durations [n] [s] of each row."""

    name: str
    X: np.ndarray
    durations: np.ndarray
    source: str


# -- the runs --------------------------------------------------------------------------------

def _case_runs(model, spec_obj, text: str) -> list[RunInputs]:
    from dampnet.envelope.coverage import quarter_car_inputs
    from dampnet.recipes import control_laws
    from dampnet.sim.quarter_car.runs import simulate

    req, level = _case_road(text)
    name = text[:len(text) - len(level) - 1] if level else text
    levels = ("low", "high") if level == "" else (level,)
    ctrl = {lvl: control_laws.make(f"passive_{lvl}", spec_obj) for lvl in levels}
    speeds = req.kind.case_speeds_m_s if req.profile == "spatial" else (None,)
    road = None if req.takes("speed_m_s") else req.build()
    out = []
    for lvl in levels:
        for v in speeds:
            at = road or req.build(speed_m_s=v)      # a road that fills the speed: built for each
            r = simulate(spec_obj, at, v, ctrl[lvl], law=f"passive_{lvl}")
            arr = r["arrays"]
            X = quarter_car_inputs(model, arr)
            t = np.asarray(arr["t"], dtype=np.float64)
            dt = float(np.median(np.diff(t))) if t.size > 1 else 1e-3
            label = f"{name}:{lvl}" + (f"@{v:g}m/s" if v is not None else "")
            out.append(RunInputs(label, X, np.full(X.shape[0], dt), f"built-in case {label} (quarter car, "
                                 f"passive at {ctrl[lvl].u_passive:g})"))
    return out


def _npz_inputs(model, arrays: dict, path: Path) -> np.ndarray:
    """A quarter-car run's inputs from its run.npz: each feature's runtime field (x, v, a, u
    and the damper's states, _core.DAMPER_STATES: the step outputs and the loop state's columns,
    by name), else the recorded `features` columns
    (a neural damper's inputs) when they are the model's count."""
    from dampnet.features import feature

    cols = []
    for f in model.features:
        fld = feature(f).field
        if fld in arrays and np.ndim(arrays[fld]) == 1:
            cols.append(np.asarray(arrays[fld], dtype=np.float64))
        else:
            cols = None
            break
    if cols is not None:
        return np.stack(cols, axis=1)
    feats = arrays.get("features")
    if feats is not None and np.ndim(feats) == 2 and feats.shape[1] == model.n_inputs:
        return np.asarray(feats, dtype=np.float64)
    raise PlanError(f"{path}: the run records no input for every feature of the model ({', '.join(model.features)})")


def _dir_runs(model, path: Path) -> list[RunInputs]:
    from dampnet.envelope.coverage import fullcar_inputs

    mj, npz = path / "metrics.json", path / "run.npz"
    if (path / "study.json").is_file():
        return _study_runs(model, path)
    if not mj.is_file() or not npz.is_file():
        raise PlanError(f"{path}: expected a dampnet simulate or vehicle output directory (metrics.json and run.npz)")
    try:
        meta = json.loads(mj.read_text(encoding="utf-8"))
        schema = str(meta.get("schema", ""))
        with np.load(npz) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, AttributeError) as e:
        raise PlanError(f"{path}: unreadable run ({e})") from None
    if "t" in arrays:
        t = np.asarray(arrays["t"], dtype=np.float64)
    elif "state" in arrays:
        from dampnet import _core

        names = _core.FULLCAR_STATE_NAMES if schema.startswith(FULL_CAR.family) else _core.STATE_NAMES
        t = np.asarray(arrays["state"], dtype=np.float64)[:, list(names).index("t")]
    else:
        raise PlanError(f"{path / 'run.npz'}: no time column")
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1e-3
    if schema.startswith(FULL_CAR.family):
        try:
            per = fullcar_inputs(model, arrays)
        except (ValueError, KeyError) as e:
            raise PlanError(f"{path}: {e}") from None
        X = np.concatenate(per)
        return [RunInputs(f"{path.name} (4 corners)", X, np.full(X.shape[0], dt), f"dampnet vehicle run {path}")]
    if schema.startswith(QUARTER_CAR.family):
        X = _npz_inputs(model, arrays, npz)
        return [RunInputs(path.name, X, np.full(X.shape[0], dt), f"dampnet simulate run {path}")]
    raise PlanError(f"{mj}: schema {schema!r}: expected a dampnet simulate or vehicle run")


def _study_runs(model, path: Path) -> list[RunInputs]:
    """Every run of MODEL in a `dampnet study` directory (its inputs.npz, dampnet.sim.quarter_car.study.neural_inputs)."""
    from dampnet.sim.quarter_car.study import INPUTS_FILE

    f = path / INPUTS_FILE
    if not f.is_file():
        raise PlanError(f"{path}: this study kept no per-step damper inputs ({INPUTS_FILE}: run dampnet study "
                        f"without --no-plots), or name its cases instead ({', '.join(CASES)}, each optionally "
                        ":low or :high)")
    try:
        with np.load(f) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise PlanError(f"{f}: unreadable ({e})") from None
    ids = dict(str(m).split("=", 1) for m in arrays.get("models", []))
    mine = [name for name, mid in ids.items() if mid == model.model_id()]
    if not mine:
        raise PlanError(f"{path}: the study ran {', '.join(sorted(ids)) or 'no neural model'} (model_id "
                        f"{', '.join(sorted(ids.values())) or '-'}), not this MODEL (model_id {model.model_id()})")
    out = []
    for key in sorted(k for k in arrays if k.endswith("__features")):
        section, case, name = key[:-len("__features")].split("__", 2)
        if name not in mine:
            continue
        X, t = arrays[key], arrays[key[:-len("__features")] + "__t"]
        dt = float(np.median(np.diff(t))) if t.size > 1 else 1e-3
        out.append(RunInputs(f"{section} {case}", X, np.full(X.shape[0], dt), f"dampnet study {path}: {section} {case}"))
    return out


def load_runs(model, envelope, runs: Sequence[str], note: str | None = None) -> list[RunInputs]:
    """The damper inputs of each RUN: a simulate/vehicle output directory or a built-in case."""
    from dampnet.sim.dampers import neural_spec

    spec_obj = neural_spec(model, envelope=envelope, envelope_note=note)
    out: list[RunInputs] = []
    for r in runs:
        p = Path(r)
        if p.is_dir():
            out += _dir_runs(model, p)
        elif _case_road(r) is not None:
            out += _case_runs(model, spec_obj, r)
        else:
            raise PlanError(f"RUN {r!r}: expected a dampnet simulate or vehicle output directory or a built-in "
                            f"case (a road: {case_names()}; each optionally :low or :high)")
    return out


# -- required and covered points ---------------------------------------------------------------

def outside_mask(model, envelope, X: np.ndarray) -> np.ndarray:
    """Rows of X outside the model's training envelope (a range, or the joint threshold)."""
    out = np.any((X < model.sat_lo) | (X > model.sat_hi), axis=1)
    if envelope is not None:
        out |= envelope.far(X)   # distance > threshold, the k-d tree stopping at the threshold
    return out & np.all(np.isfinite(X), axis=1)


def training_points(model, envelope) -> np.ndarray | None:
    """The envelope's stored training samples in feature units (None without an envelope)."""
    if envelope is None:
        return None
    return (envelope.points - envelope.in_ymin) / envelope.in_gain + envelope.in_offset


class Space:
    """The planning space: each input's [lo, hi] onto [-1, 1]."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray):
        self.lo = np.asarray(lo, dtype=np.float64)
        self.hi = np.asarray(hi, dtype=np.float64)
        self.width = np.where(self.hi > self.lo, self.hi - self.lo, 1.0)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return 2.0 * (np.asarray(X, dtype=np.float64) - self.lo) / self.width - 1.0


# -- candidates --------------------------------------------------------------------------------

def _sine_test(frequency_hz: float, amplitude_m: float, control: float, control_name: str, cycles: float = 3.0):
    from dampnet.data.types import DynoTest

    fs = max(SAMPLE_RATE_HZ, 200.0 * frequency_hz)
    n = int(math.ceil(cycles * fs / frequency_hz)) + 1
    t = np.arange(n) / fs
    w = 2 * np.pi * frequency_hz
    ch = {"displacement": amplitude_m * np.sin(w * t), "velocity": amplitude_m * w * np.cos(w * t),
          "force": np.zeros(n), control_name: np.full(n, float(control))}
    return DynoTest("candidate", t, ch, frequency_hz, amplitude_m, float(control), control_name), fs


def sine_trajectory(model, frequency_hz: float, amplitude_m: float, control: float, control_name: str,
                    points: int = CYCLE_POINTS) -> tuple[np.ndarray, float]:
    """(one steady cycle of the model's inputs [points, n_inputs] on the sine, as training would build
    them; the expected peak force [N], see the module docstring)."""
    from dampnet.features import feature_matrix
    from dampnet.predict import predict_force

    test, fs = _sine_test(frequency_hz, amplitude_m, control, control_name)
    window = (model.meta.get("data") or {}).get("acceleration_window_s")
    X = feature_matrix([test], model.features, model.feature_params, window)
    per = int(round(fs / frequency_hz))
    last = slice(X.shape[0] - per, X.shape[0])
    cyc = X[last]
    step = max(1, per // points)
    F = predict_force(model, test)[last]
    v = test.channels["velocity"][last]
    scale = np.ones_like(v)
    if "velocity" in model.features:
        i = model.features.index("velocity")
        lo, hi = float(model.sat_lo[i]), float(model.sat_hi[i])
        scale = np.where((v > hi) & (hi > 0), v / max(hi, 1e-12),
                         np.where((v < lo) & (lo < 0), v / min(lo, -1e-12), 1.0))
    return cyc[::step], float(np.max(np.abs(F * scale)))


def default_controls(model, required: np.ndarray) -> list[float]:
    """The training control range's ends, its middle, and the required points' most common
    control values (at most 3), each rounded to a power of ten near 1 % of the range, inside it."""
    name = control_name_of(model)
    i = model.features.index(name)
    lo, hi = float(model.sat_lo[i]), float(model.sat_hi[i])
    res = 10.0 ** math.floor(math.log10(max(hi - lo, 1e-9) / 100))

    def snap(v: float) -> float:   # to a round step near 1 % of the range, inside it
        q = round(v / res) * res
        q = q if lo <= q <= hi else (math.floor(v / res) * res if q > hi else math.ceil(v / res) * res)
        return round(q, 6) + 0.0

    levels = [snap(lo), snap((lo + hi) / 2), snap(hi)]
    if required.size:
        vals, counts = np.unique([snap(float(v)) for v in np.clip(required[:, i], lo, hi)], return_counts=True)
        for k in np.argsort(-counts)[:3]:
            levels.append(float(vals[k]))
    out = []
    for v in sorted(levels):
        if not out or abs(v - out[-1]) > res:
            out.append(v)
    return out


def control_name_of(model) -> str:
    for c in ("voltage", "current"):
        if c in model.features:
            return c
    raise PlanError(f"the model has no control input (features {', '.join(model.features)}): expected "
                    "voltage or current")


# -- the plan ----------------------------------------------------------------------------------

def _describe(model, X: np.ndarray, runs: list[str]) -> str:
    parts = []
    for i, f in enumerate(model.features):
        lo, hi = float(np.min(X[:, i])), float(np.max(X[:, i]))
        u = model.units[i]
        parts.append(f"{f} {lo:.3g}..{hi:.3g} {u}" if abs(hi - lo) > 1e-6 * max(1.0, abs(hi)) else f"{f} {lo:.3g} {u}")
    return ", ".join(parts) + (" (" + ", ".join(runs) + ")" if runs else "")


def plan_tests(model, envelope, runs: list[RunInputs], budget: int, *,
               frequencies_hz: Sequence[float] = DEFAULT_FREQUENCIES_HZ,
               amplitudes_m: Sequence[float] = DEFAULT_AMPLITUDES_M,
               controls: Sequence[float] | None = None,
               max_stroke_m: float = DEFAULT_MAX_STROKE_M, max_velocity_m_s: float = DEFAULT_MAX_VELOCITY_M_S,
               max_force_n: float = DEFAULT_MAX_FORCE_N, radius: float | None = None,
               max_required: int = MAX_REQUIRED, seed: int = 0) -> dict[str, Any]:
    """The proposal (JSON-ready): required points, candidates, the picks with the share covered after
    each; see the module docstring."""
    from scipy.spatial import cKDTree

    if budget < 1:
        raise PlanError(f"--budget: expected a positive number of tests, got {budget}")
    for what, v in (("--max-stroke-m", max_stroke_m), ("--max-velocity-m-s", max_velocity_m_s),
                    ("--max-force-n", max_force_n)):
        if not (math.isfinite(v) and v > 0):
            raise PlanError(f"{what}: expected a positive number, got {v}")
    for what, vals in (("--frequencies", frequencies_hz), ("--amplitudes", amplitudes_m)):
        if not vals or any(not (math.isfinite(v) and v > 0) for v in vals):
            raise PlanError(f"{what}: expected positive numbers, got {list(vals)}")
    if not runs:
        raise PlanError("expected at least one RUN")
    cname = control_name_of(model)
    ci = model.features.index(cname)
    # required points: every run's steps outside the envelope, a seeded subsample beyond max_required
    Xs, who, dur = [], [], []
    per_run = []
    for k, r in enumerate(runs):
        m = outside_mask(model, envelope, r.X)
        per_run.append(dict(run=r.name, source=r.source, steps=int(r.X.shape[0]),
                            share_time_outside=float(np.sum(r.durations[m]) / np.sum(r.durations))
                            if r.X.shape[0] else 0.0, required_points=int(np.count_nonzero(m))))
        Xs.append(r.X[m]), who.append(np.full(int(np.count_nonzero(m)), k)), dur.append(r.durations[m])
    Xr, wr = np.concatenate(Xs), np.concatenate(who)
    n_required_all = int(Xr.shape[0])
    if Xr.shape[0] > max_required:
        rows = np.sort(np.random.default_rng(seed).choice(Xr.shape[0], max_required, replace=False))
        Xr, wr = Xr[rows], wr[rows]
    train = training_points(model, envelope)
    lo = np.minimum(model.sat_lo, Xr.min(0)) if Xr.size else model.sat_lo.copy()
    hi = np.maximum(model.sat_hi, Xr.max(0)) if Xr.size else model.sat_hi.copy()
    space = Space(lo, hi)
    rad = float(radius) if radius is not None else (envelope.threshold if envelope is not None else DEFAULT_RADIUS)
    if not (math.isfinite(rad) and rad > 0):
        raise PlanError(f"--radius: expected a positive number, got {rad}")
    S = space(Xr)
    covered = np.zeros(S.shape[0], dtype=bool)
    if train is not None and S.shape[0]:
        d, _ = cKDTree(space(train)).query(S, k=1, distance_upper_bound=rad)
        covered = np.isfinite(d)
    n0 = int(np.count_nonzero(covered))
    ctrl = [float(c) for c in (controls if controls is not None else default_controls(model, Xr))]
    # candidates within the limits
    cands, rejected = [], dict(stroke=0, velocity=0, force=0)
    for f in sorted(set(float(x) for x in frequencies_hz)):
        for a in sorted(set(float(x) for x in amplitudes_m)):
            w = 2 * np.pi * f
            if 2 * a > max_stroke_m * (1 + 1e-9):
                rejected["stroke"] += len(ctrl)
                continue
            if w * a > max_velocity_m_s * (1 + 1e-9):
                rejected["velocity"] += len(ctrl)
                continue
            for c in ctrl:
                traj, fpk = sine_trajectory(model, f, a, c, cname)
                if fpk > max_force_n:
                    rejected["force"] += 1
                    continue
                hit = np.zeros(S.shape[0], dtype=bool)
                if S.shape[0]:
                    d, _ = cKDTree(space(traj)).query(S, k=1, distance_upper_bound=rad)
                    hit = np.isfinite(d)
                cands.append(dict(frequency_hz=f, amplitude_m=a, control=c, peak_force_n=fpk,
                                  peak_velocity_m_s=w * a, peak_acceleration_m_s2=w * w * a, hit=hit))
    picks = []
    for _ in range(budget):
        if not cands:
            break
        gains = [int(np.count_nonzero(c["hit"] & ~covered)) for c in cands]
        # the most new points; ties: the gentler test (lower peak force, then velocity)
        best = max(range(len(cands)), key=lambda k: (gains[k], -cands[k]["peak_force_n"],
                                                     -cands[k]["peak_velocity_m_s"]))
        if gains[best] == 0:
            break
        c = cands.pop(best)
        new = c["hit"] & ~covered
        covered |= new
        rn = sorted({runs[k].name for k in np.unique(wr[new])})
        picks.append(dict({k: v for k, v in c.items() if k != "hit"}, new_points=int(np.count_nonzero(new)),
                          share_covered_after=float(np.mean(covered)) if covered.size else 1.0,
                          why=f"covers {int(np.count_nonzero(new))} required points "
                              f"({100 * np.count_nonzero(new) / max(covered.size, 1):.0f} %): "
                              + _describe(model, Xr[new], rn)))
    for i, p in enumerate(picks, start=1):
        p["test_id"] = f"P{i:02d}"
    left = ~covered
    return dict(schema=SCHEMA, model_id=model.model_id(), features=list(model.features), units=list(model.units),
                control_name=cname, control_unit=model.units[ci], budget=int(budget),
                limits=dict(max_stroke_m=max_stroke_m, max_velocity_m_s=max_velocity_m_s, max_force_n=max_force_n),
                grids=dict(frequencies_hz=sorted(set(map(float, frequencies_hz))),
                           amplitudes_m=sorted(set(map(float, amplitudes_m))), controls=ctrl),
                envelope="joint" if envelope is not None else "ranges only",
                planning_space=dict(lo=space.lo, hi=space.hi, radius=rad,
                                    note="each input's range over the training data and the required points "
                                         "onto [-1, 1]; a required point is covered within `radius` of a "
                                         "training sample or a planned test's trajectory"),
                runs=per_run, required_points=n_required_all, required_points_used=int(S.shape[0]),
                share_covered_by_training=float(n0 / S.shape[0]) if S.shape[0] else 1.0,
                share_covered=float(np.mean(covered)) if covered.size else 1.0,
                candidates=len(cands) + len(picks), rejected=rejected, tests=picks,
                uncovered=_describe(model, Xr[left], []) if left.any() else None)


def rig_plan(res: dict, name: str = "plan-tests") -> dict:
    """The proposal as a plan `dampnet rig --plan` reads (dampnet.rig.plans: explicit tests)."""
    return dict(name=name, excitation="sine", sample_rate_hz=SAMPLE_RATE_HZ, samples=MIN_SAMPLES,
                min_cycles=MIN_CYCLES, control={"waveform": "constant"},
                tests=[dict(test_id=p["test_id"], frequency_hz=p["frequency_hz"], amplitude_m=p["amplitude_m"],
                            control=p["control"]) for p in res["tests"]],
                about={k: v for k, v in res.items() if k != "tests"})


TABLE_COLUMNS = ("test", "frequency_hz", "amplitude_mm", "peak_velocity_m_s", "peak_acceleration_m_s2",
                 "control", "control_unit", "expected_peak_force_n", "share_covered_after", "why")


def table_rows(res: dict) -> list[dict]:
    return [dict(test=p["test_id"], frequency_hz=p["frequency_hz"], amplitude_mm=1e3 * p["amplitude_m"],
                 peak_velocity_m_s=p["peak_velocity_m_s"], peak_acceleration_m_s2=p["peak_acceleration_m_s2"],
                 control=p["control"], control_unit=res["control_unit"], expected_peak_force_n=p["peak_force_n"],
                 share_covered_after=p["share_covered_after"], why=p["why"]) for p in res["tests"]]


def csv_text(res: dict) -> str:
    import csv
    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(TABLE_COLUMNS), lineterminator="\n")
    w.writeheader()
    for r in table_rows(res):
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    return buf.getvalue()


def format_table(res: dict) -> str:
    u = res["control_unit"]
    head = (f"{'test':<5} {'f [Hz]':>7} {'A [mm]':>7} {'v pk [m/s]':>10} {'a pk [m/s^2]':>12} "
            f"{'control [' + u + ']':>12} {'F pk [N]':>9} {'covered':>8}  why")
    lines = [head]
    for r in table_rows(res):
        lines.append(f"{r['test']:<5} {r['frequency_hz']:>7.3g} {r['amplitude_mm']:>7.3g} {r['peak_velocity_m_s']:>10.3f} "
                     f"{r['peak_acceleration_m_s2']:>12.1f} {r['control']:>12.3g} {r['expected_peak_force_n']:>9.0f} "
                     f"{100 * r['share_covered_after']:>7.1f}%  {r['why']}")
    return "\n".join(lines)


def summary(res: dict) -> str:
    runs = "; ".join(f"{r['run']}: {100 * r['share_time_outside']:.1f} % outside ({r['required_points']} points)"
                     for r in res["runs"])
    lim = res["limits"]
    s = (f"required: {res['required_points']} damper-input points outside the training envelope ({runs})\n"
         f"covered by the training data already (planning space, radius {res['planning_space']['radius']:.3g}): "
         f"{100 * res['share_covered_by_training']:.1f} %; after {len(res['tests'])} of {res['budget']} "
         f"planned tests: {100 * res['share_covered']:.1f} %\n"
         f"dyno limits: stroke {1e3 * lim['max_stroke_m']:g} mm, velocity {lim['max_velocity_m_s']:g} m/s, force "
         f"{lim['max_force_n']:g} N; {res['candidates']} candidate sines within them (rejected: "
         + ", ".join(f"{v} by {k}" for k, v in res["rejected"].items()) + ")")
    if res["uncovered"]:
        s += f"\nstill uncovered: {res['uncovered']}"
    return s
