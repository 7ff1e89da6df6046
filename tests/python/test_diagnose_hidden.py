"""Issue 6: hidden effects in rig data are found, added, and no longer flagged.

Shared plan: 5 frequencies x 8 voltages at 1 kHz (2.25 V held out by training), default
model (velocity, acceleration, voltage) trained with LM on every 4th sample, at most 120 epochs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from dampnet.rig.effects import Effect

from dampnet.rig import generate
from dampnet.effects import additions
from dampnet.diagnosis.run import diagnose
from dampnet.evaluation.metrics import evaluate_predictions
from dampnet.predict import predict_force
from dampnet.training.pipeline import train_dataset

PLAN = {"name": "diag", "frequencies_hz": [0.25, 0.5, 1.0, 2.0, 3.0], "amplitudes_m": [0.0254],
        "voltages_v": [0.0, 0.5, 1.0, 1.5, 2.25, 3.0, 4.0, 5.0], "sample_rate_hz": 1000.0,
        "samples": 2000, "min_cycles": 2}
# The training this file was built on: without the control prior (the default since issue 33). With
# the prior the thermal case's model is already at 0.0089-0.010 held out (0.043 without), and adding
# temperature, the remedy, makes it worse (0.0147 at the default epochs, seed 0: the temperature input
# is as free between the tests' temperatures as the control was between levels); issue 33's note.
TRAIN = {"decimate": 4, "max_epochs": 120, "control_prior": 0.0}
N_SUR = 29


def _holdout_nrmse(m, split):
    tests = split.holdout.tests
    return evaluate_predictions(tests, [predict_force(m, t) for t in tests])["overall"]["nrmse"]


def _cand(d, effect):
    return next(c for c in d["candidates"] if c["effect"] == effect)


def _run(effects, add):
    ds = generate(PLAN, effects=effects, seed=1)
    m, _, split = train_dataset(ds, **TRAIN)
    d = diagnose(m, ds, n_surrogates=N_SUR)
    out = {"ds": ds, "model": m, "d": d, "before": _holdout_nrmse(m, split)}
    if add:
        a = additions(add, _cand(d, add)["parameters"], control="voltage")
        m2, _, split2 = train_dataset(ds, features=list(m.features) + a["features"],
                                      feature_params=a["feature_params"], **TRAIN)
        out.update(model2=m2, after=_holdout_nrmse(m2, split2), d2=diagnose(m2, ds, n_surrogates=N_SUR))
    return out


CASES = {"gas_spring": "gas_spring", "bump_stop": "gas_spring", "thermal": "thermal", "valve_lag": "valve_lag"}


@pytest.fixture(scope="module", params=sorted(CASES))
def hidden(request):
    return request.param, CASES[request.param], _run([request.param], CASES[request.param])


def test_hidden_effect_found_added_and_gone(hidden):
    effect, family, r = hidden
    top = r["d"]["candidates"][0]
    assert top["effect"] == family and top["significant"], r["d"]["candidates"][:2]
    assert r["d"]["verdict"] == family
    assert r["d"]["finding"]["kind"] == "known_effect" and r["d"]["finding"]["effects"][0] == family, r["d"]["finding"]
    # a position-dependent force the same at every control is not an MR pre-yield loop (issue 53)
    assert not _cand(r["d"], "mr_hysteresis")["significant"], _cand(r["d"], "mr_hysteresis")
    fall = 1 - r["after"] / r["before"]
    print(f"{effect}: held-out NRMSE {r['before']:.5f} -> {r['after']:.5f} ({-100 * fall:+.0f} %)")
    # valve_lag measured 25 % (0.0152 -> 0.0114; rig seeds 2 and 3: 53 %, 33 %) with the zero-phase
    # acceleration; 37 % (0.0158 -> 0.0100) with the thesis's 20 ms moving average, the default until
    # issue 49's item 17 (seeds 2, 3: 54 %, 37 %); the bound was 40 % with the rest points at 0 N
    assert fall >= (0.2 if effect == "valve_lag" else 0.33), (r["before"], r["after"])
    assert not _cand(r["d2"], family)["significant"], _cand(r["d2"], family)


def test_parameters_are_physical(hidden):
    effect, family, r = hidden
    p = _cand(r["d"], family)["parameters"]
    if effect == "valve_lag":
        assert 0.005 < p["tau_s"] < 0.04          # rig: 40 ms / 3
    if effect == "gas_spring":
        assert p["force_at_full_compression_n"] < 0 < p["force_at_full_extension_n"]
    if effect == "thermal":
        assert p["force_change_percent_per_k"] < 0  # hotter oil, less force


def test_nothing_missing_nothing_significant():
    r = _run([], None)
    assert r["d"]["verdict"] is None
    assert not any(c["significant"] for c in r["d"]["candidates"])
    # issue 35: and the catalogue-independent test finds nothing above the noise floor either
    f, left = r["d"]["finding"], r["d"]["leftover"]["before_effects"]
    assert f["kind"] == "nothing_left" and not left["significant"], (f, left)
    # and the sentence claims "nothing above the noise floor" only for a noise-like residual (a
    # 120-epoch model sits at about 5.7x here: capacity, said to be not testable apart from an
    # unrecorded difference)
    from dampnet.diagnosis.verdict import NOISE_LIKE_MAX

    noise_like = left["model_residual_vs_noise"] <= NOISE_LIKE_MAX
    assert ("nothing above the noise floor" in f["sentence"]) == noise_like, (left["model_residual_vs_noise"], f)
    assert left["noise_floor_rms_n"] == pytest.approx(4.45, rel=0.01)    # the rig's load cell
    assert not any(a["detected"] for a in r["d"]["artefacts"]), r["d"]["artefacts"]


def test_two_effects_top_two():
    r = _run(["gas_spring", "valve_lag"], None)
    top2 = {c["effect"] for c in r["d"]["candidates"][:2]}
    assert top2 == {"gas_spring", "valve_lag"}


@dataclass
class _PlainCoulomb(Effect):
    """Plain Coulomb seal friction, F = F_c tanh(v / v_s): a function of velocity alone."""

    name = "plain_coulomb_test"
    force_n: float = 150.0
    v_smooth_m_s: float = 0.003

    def force(self, ctx):
        return self.force_n * np.tanh(ctx.v / self.v_smooth_m_s)


def test_effect_the_inputs_already_explain_is_not_flagged():
    r = _run([_PlainCoulomb()], None)
    assert r["d"]["verdict"] is None, [(c["effect"], c["score"]) for c in r["d"]["candidates"][:3]]
    assert not any(c["significant"] for c in r["d"]["candidates"])


def test_stick_slip_friction_is_found():
    """The rig's LuGre seal friction (breakaway 110 N, sliding 40 N, bristle stiffness 1e6 N/m:
    about 0.1 mm of pre-sliding travel) depends on the travel since the last reversal, which a
    (velocity, acceleration, voltage) model cannot see: the diagnosis must rank friction first,
    flag it significant, and estimate a pre-sliding travel and force of the rig's order.
    (The plain Coulomb friction above, a function of velocity alone, must not be flagged.)
    Measured, seeds 1-3: pre-sliding 0.106-0.123 mm, force 55-57 N."""
    r = _run(["friction"], None)
    top = r["d"]["candidates"][0]
    assert top["effect"] == "friction" and top["significant"], r["d"]["candidates"][:3]
    assert r["d"]["verdict"] == "friction" and r["d"]["finding"]["kind"] == "known_effect", r["d"]["finding"]
    assert not _cand(r["d"], "mr_hysteresis")["significant"], _cand(r["d"], "mr_hysteresis")  # issue 53
    p = top["parameters"]
    assert 0.05 < p["presliding_length_mm"] < 0.25, p
    assert 40.0 / 2 < p["friction_force_n"] < 110.0, p
