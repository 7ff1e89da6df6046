"""Coverage of a run: how much of it a neural damper model spent outside its training data, and
the verdict "extrapolated".

Given a model, its envelope (dampnet.envelope; None: per-input ranges only) and the damper
inputs of each step of a run (`quarter_car_inputs`: the loop's recorded features, the inputs
before saturation; `fullcar_inputs`: each corner's, from the full vehicle's report and state
by the runtime's feature registry), `coverage` reports:

  inputs[f]        per input: the training range [lo, hi] (feature units), the share of steps
                   and of time below / above it, and the worst excursion beyond it in units of
                   the range's width (0.5: half a training range beyond the nearest limit)
  outside_ranges   the share of steps / time with any input outside its range
  joint            (with an envelope) the share of steps / time farther than the threshold from
                   every stored training sample (scaled space), the largest and 95th-percentile
                   distance
  runtime_flag     (with an envelope) what the runtime's bounded-time check (dampnet.envelope.grid,
                   the FMU's envelope_flags) says of the same steps: its share of steps / time
                   flagged, and the share of steps where it agrees with `outside` below
  outside          the envelope's share: outside any range OR (with an envelope) outside the joint
                   envelope; `mostly` names the inputs that put the run outside, by the share of
                   outside time each dominates (the input with the largest scaled difference to
                   the nearest training sample; without an envelope, the largest excursion)
  extrapolated     outside.share_time > EXTRAPOLATED_SHARE, or the worst excursion beyond a
                   training range > EXCURSION_LIMIT_RANGES however brief (`extrapolated_by` says
                   which rule); and `verdict`, the sentence the commands print

Time: each step counts its own duration (steps of one run have equal dt, so the shares of
steps and of time agree unless a run's steps differ; both are reported).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from dampnet.envelope.samples import Envelope

#: a run with more than this share of its time outside the envelope is "extrapolated"
#: (5 %: the impulse's pulse is 50 ms of a ~3 s run, about 2 %; a run that leaves the data for
#: more than one step in twenty spends a visible part of its metrics on the model's guesses)
EXTRAPOLATED_SHARE = 0.05
#: ... or when an input went more than this many widths of its training range beyond it, however
#: briefly: there the MLP's input is clamped to its limit (the runtime's saturation), so its force
#: is the force at the limit, not a guess near data. Without this rule the quarter-car impulse at
#: high damping (a 5 s run, 50 ms pulse) was "within" at 4.6 % outside with an acceleration 18
#: ranges beyond the training range (a quick-plan model).
EXCURSION_LIMIT_RANGES = 1.0


def step_durations(n: int, t: np.ndarray | None, dt: float | None = None) -> np.ndarray:
    """Each of n steps' duration [s]: the differences of t [n] (the last step as long as the one
    before), else dt, else 1 (shares of time are then shares of steps)."""
    if t is not None and len(t) == n and n > 1:
        t = np.asarray(t, dtype=np.float64)
        d = np.diff(t)
        return np.append(d, d[-1])
    return np.full(n, float(dt) if dt else 1.0)


def _share(mask: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    n = mask.size
    if n == 0:
        return 0.0, 0.0
    return float(np.count_nonzero(mask) / n), float(np.sum(w[mask]) / np.sum(w))


def outside_steps(model, X: np.ndarray, envelope: Envelope | None = None) -> np.ndarray:
    """The steps (rows of X [n, n_inputs], feature units) outside `model`'s envelope: an input
    outside its training range or not finite, or (with an envelope) farther than its threshold
    from every stored training sample; `coverage`'s "outside", step by step."""
    X = np.asarray(X, dtype=np.float64)
    out = np.any((X < model.sat_lo) | (X > model.sat_hi) | ~np.isfinite(X), axis=1)
    if envelope is not None:
        out |= envelope.far(X)
    return out


def outside_shares(model, X: np.ndarray, envelope: Envelope | None = None, t: np.ndarray | None = None,
                   dt: float | None = None) -> dict[str, float]:
    """`coverage(model, X, envelope, t=t, dt=dt)["outside"]`'s share_steps and share_time, without
    the nearest training sample of every step (the k-d tree stops at the threshold: several times
    faster when most steps are outside)."""
    X = np.asarray(X, dtype=np.float64)
    s_steps, s_time = _share(outside_steps(model, X, envelope), step_durations(X.shape[0], t, dt))
    return dict(share_steps=s_steps, share_time=s_time)


def coverage(model, X: np.ndarray, envelope: Envelope | None = None, t: np.ndarray | None = None,
             dt: float | None = None, note: str | None = None,
             durations: np.ndarray | None = None) -> dict[str, Any]:
    """Coverage of inputs X [n, n_inputs] (feature units, one row per step; several corners'
    rows stacked are several steps) against `model`'s training ranges (sat_lo/sat_hi) and, with
    an envelope, its joint envelope. t [n] (s) or dt (s): each step's time; see the module doc;
    durations [n] (s): each row's duration, given (stacked runs), instead of t's differences."""
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != model.n_inputs:
        raise ValueError(f"coverage: expected inputs [n, {model.n_inputs}] ({', '.join(model.features)}), "
                         f"got shape {X.shape}")
    n = X.shape[0]
    w = step_durations(n, t, dt) if durations is None else np.asarray(durations, dtype=np.float64)
    if w.shape != (n,):
        raise ValueError(f"coverage: durations of shape {w.shape}, expected ({n},)")
    lo, hi = model.sat_lo, model.sat_hi
    width = np.where(hi > lo, hi - lo, 1.0)
    below = X < lo
    above = X > hi
    nonfinite = ~np.isfinite(X)
    exc = np.maximum(np.maximum(lo - X, X - hi), 0.0) / width
    exc[nonfinite] = np.inf
    inputs = {}
    for i, f in enumerate(model.features):
        out_i = below[:, i] | above[:, i] | nonfinite[:, i]
        s_steps, s_time = _share(out_i, w)
        k = int(np.argmax(exc[:, i])) if n else 0
        inputs[f] = dict(unit=model.units[i], train_lo=float(lo[i]), train_hi=float(hi[i]),
                         share_steps_outside=s_steps, share_time_outside=s_time,
                         share_steps_below=_share(below[:, i], w)[0], share_steps_above=_share(above[:, i], w)[0],
                         worst_excursion_ranges=float(exc[k, i]) if n else 0.0,
                         worst_value=float(X[k, i]) if n and exc[k, i] > 0 else None,
                         run_min=float(np.nanmin(X[:, i])) if n else None,
                         run_max=float(np.nanmax(X[:, i])) if n else None)
    out_range = np.any(below | above | nonfinite, axis=1)
    s_steps, s_time = _share(out_range, w)
    res: dict[str, Any] = dict(model_id=model.model_id(), features=list(model.features), steps=int(n),
                               duration_s=float(np.sum(w)) if (t is not None or dt or durations is not None)
                               else None,
                               inputs=inputs,
                               outside_ranges=dict(share_steps=s_steps, share_time=s_time))
    # who dominates each step: the largest range excursion, or the largest scaled gap to the data
    dominant_score = exc.copy()
    outside = out_range
    if envelope is not None:
        if list(envelope.features) != list(model.features):
            raise ValueError(f"envelope features {envelope.features} differ from the model's {model.features}")
        d, idx = envelope.nearest(X)
        far = d > envelope.threshold
        js, jt = _share(far, w)
        finite = d[np.isfinite(d)]
        res["joint"] = dict(share_steps_outside=js, share_time_outside=jt, threshold=envelope.threshold,
                            distance_max=float(np.max(d)) if n else 0.0,
                            distance_p95=float(np.percentile(finite, 95)) if finite.size else None,
                            unit="scaled input space (1 = half an input's training range)")
        outside = out_range | far
        res["runtime_flag"] = _runtime_flag(envelope, X, w, outside)
        ok = idx >= 0
        gap = np.full(X.shape, np.inf)
        gap[ok] = np.abs(envelope.scale(X[ok]) - envelope.points[idx[ok]])
        dominant_score = np.where(np.isfinite(gap), gap, np.inf)
        res["envelope"] = "joint"
    else:
        res["joint"] = None
        res["runtime_flag"] = None
        res["envelope"] = "ranges only"
    res["envelope_note"] = note or ("joint envelope" if envelope is not None
                                    else "no envelope file beside the model: per-input training ranges only")
    s_steps, s_time = _share(outside, w)
    mostly = {}
    if outside.any():
        dom = np.argmax(np.nan_to_num(dominant_score[outside], posinf=1e300), axis=1)
        wo = w[outside]
        for i, f in enumerate(model.features):
            share = float(np.sum(wo[dom == i]) / np.sum(wo))
            if share >= 0.005:
                mostly[f] = share
        mostly = dict(sorted(mostly.items(), key=lambda kv: -kv[1]))
    worst_i = int(np.argmax(np.nan_to_num(exc, posinf=1e300).max(axis=0))) if n else 0
    worst_k = int(np.argmax(np.nan_to_num(exc[:, worst_i], posinf=1e300))) if n else 0
    res["outside"] = dict(share_steps=s_steps, share_time=s_time, mostly=mostly,
                          measure="ranges and joint envelope" if envelope is not None else "ranges")
    res["worst_excursion"] = dict(input=model.features[worst_i], ranges=float(exc[worst_k, worst_i]) if n else 0.0,
                                  value=float(X[worst_k, worst_i]) if n else None, unit=model.units[worst_i],
                                  step=worst_k, t_s=float(t[worst_k]) if t is not None and len(t) == n and n
                                  else None)
    res["threshold_share"] = EXTRAPOLATED_SHARE
    res["excursion_limit_ranges"] = EXCURSION_LIMIT_RANGES
    by = [r for r, hit in (("share", s_time > EXTRAPOLATED_SHARE),
                           ("excursion", res["worst_excursion"]["ranges"] > EXCURSION_LIMIT_RANGES)) if hit]
    res["extrapolated_by"] = by
    res["extrapolated"] = bool(by)
    res["verdict"] = verdict(res)
    return res


def _runtime_flag(envelope: Envelope, X: np.ndarray, w: np.ndarray, outside: np.ndarray) -> dict[str, Any]:
    """The runtime check's flags of the steps X against the offline measure's `outside`."""
    from dampnet import _core
    from dampnet.envelope.grid import runtime_flags

    flags = runtime_flags(envelope, X)
    flagged = flags != 0
    s_steps, s_time = _share(flagged, w)
    return dict(share_steps_outside=s_steps, share_time_outside=s_time,
                share_steps_outside_joint_only=_share(flags == _core.ENV_OUTSIDE_JOINT, w)[0],
                agreement_steps=float(np.mean(flagged == outside)) if flags.size else 1.0,
                check="dn_envelope_check: per-input ranges and 32 x 32 cells per pair of inputs")


def verdict(cov: Mapping[str, Any]) -> str:
    """The run's verdict in words, from a `coverage` result."""
    o = cov["outside"]
    pct = 100 * o["share_time"]
    what = "its training data" if cov.get("joint") is not None else "its training ranges (no joint envelope)"
    w = cov["worst_excursion"]
    worst = (f"; worst excursion {w['ranges']:.2f} training ranges beyond, in {w['input']} ({w['value']:.4g} "
             f"{w['unit']})" if w["ranges"] > 0 else "")
    mostly = ", ".join(f"{f} ({100 * s:.0f} %)" for f, s in o["mostly"].items())
    if cov["extrapolated"]:
        why = ("" if "share" in cov.get("extrapolated_by", ["share"]) else
               f" (under {100 * cov['threshold_share']:g} %, but more than {cov['excursion_limit_ranges']:g} "
               "training range beyond a limit, where the model's input is clamped)")
        return (f"extrapolated: the model was outside {what} for {pct:.1f} % of the run{why}, mostly in "
                f"{mostly}{worst}")
    if o["share_time"] > 0:
        return (f"mostly within the training data: outside {what} for {pct:.1f} % of the run (at most "
                f"{100 * cov['threshold_share']:g} %: not extrapolated), mostly in {mostly}{worst}")
    return f"within the training data: never outside {what}"


def quarter_car_inputs(model, arrays: Mapping[str, np.ndarray]) -> np.ndarray:
    """The damper inputs of each step of a quarter-car run (dampnet.sim.quarter_car.runs arrays: the loop's
    recorded `features`, a neural damper's inputs before saturation, in the model's order)."""
    f = np.asarray(arrays["features"], dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != model.n_inputs:
        raise ValueError(f"the run's features have shape {f.shape}; expected [n, {model.n_inputs}]")
    return f


def fullcar_inputs(model, arrays: Mapping[str, np.ndarray]) -> list[np.ndarray]:
    """Each corner's damper inputs [n, n_inputs] of a full-vehicle run (FullCar.simulate's
    arrays), one array per corner (FL, FR, RL, RR): each feature's dn_damper_input field
    (dampnet.features registry) from the report's [n, 4] columns (x, v, a, u) or the state's
    per-corner columns (<field>_fl, ...: the lags, the friction state, the temperature)."""
    from dampnet import _core
    from dampnet.features import feature

    names = list(_core.FULLCAR_STATE_NAMES)
    state = np.asarray(arrays["state"])
    corners = ("fl", "fr", "rl", "rr")
    out = []
    for c, corner in enumerate(corners):
        cols = []
        for f in model.features:
            fld = feature(f).field
            if fld in arrays and np.ndim(arrays[fld]) == 2:
                cols.append(np.asarray(arrays[fld])[:, c])
            elif f"{fld}_{corner}" in names:
                cols.append(state[:, names.index(f"{fld}_{corner}")])
            else:
                raise ValueError(f"coverage: the full vehicle records no {fld!r} for feature {f!r}")
        out.append(np.stack(cols, axis=1).astype(np.float64))
    return out


def summary_line(name: str, cov: Mapping[str, Any]) -> str:
    """One line for the CLI: the model's name, the shares and the verdict."""
    o, r = cov["outside"], cov["outside_ranges"]
    j = cov.get("joint")
    parts = [f"outside the training ranges {100 * r['share_time']:.1f} % of the time"]
    if j is not None:
        parts.append(f"outside the joint envelope {100 * j['share_time_outside']:.1f} %")
        rt = cov.get("runtime_flag")
        if rt is not None:
            parts.append(f"runtime flag {100 * rt['share_time_outside']:.1f} % (agrees on "
                         f"{100 * rt['agreement_steps']:.1f} % of steps)")
    else:
        parts.append(f"no joint envelope ({cov.get('envelope_note') or 'no envelope file beside the model'})")
    return f"coverage of {name}: " + ", ".join(parts) + f" -> {cov['verdict']}"


def strip(cov: Mapping[str, Any]) -> dict[str, Any]:
    """A coverage result for a table cell: the shares and the verdict, without the per-input detail."""
    j = cov.get("joint")
    return dict(share_time_outside=cov["outside"]["share_time"],
                share_time_outside_ranges=cov["outside_ranges"]["share_time"],
                share_time_outside_joint=None if j is None else j["share_time_outside"],
                share_time_runtime_flag=None if cov.get("runtime_flag") is None
                else cov["runtime_flag"]["share_time_outside"],
                worst_excursion=cov["worst_excursion"], mostly=cov["outside"]["mostly"],
                extrapolated=cov["extrapolated"], envelope=cov["envelope"])
