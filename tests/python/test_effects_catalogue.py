"""One effect catalogue (dampnet.effects): the rig's physics and the diagnosis's candidates are
keyed by its ids, the same physical effect has the same id on both sides, `dampnet rig
--list-effects` and the diagnosis use its words; the rig's modules and the commands import
one way (no cycle, no command reaching into another)."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet import _core
from dampnet.cli import main
from dampnet.diagnosis.catalogue import CANDIDATES, Candidate, register_candidate
from dampnet.effects import CATALOGUE, EffectInfo, additions, effect, register_effect
from dampnet.features import FEATURES
from dampnet.rig import EFFECTS, TruthParams, truth_force


def test_the_rigs_switchable_effects_are_the_catalogues():
    switchable = {k for k, e in CATALOGUE.items() if e.rig == "switchable"}
    assert set(EFFECTS) == switchable
    assert all(eff.name == key for key, eff in EFFECTS.items())


def test_an_always_on_effect_is_in_the_rigs_base_physics():
    """compressibility: always on in the rig (TruthParams.compressibility_tau_s), so not switchable
    and not refused silently: the truth force with it differs from the force without it."""
    assert [k for k, e in CATALOGUE.items() if e.rig == "always_on"] == ["compressibility"]
    dt = 2e-4
    t = np.arange(0, 1.0, dt)
    x, v = 0.0254 * np.sin(2 * np.pi * 3 * t), 0.0254 * 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * t)
    on = truth_force(x, v, np.zeros_like(t), dt=dt)
    off = truth_force(x, v, np.zeros_like(t), dt=dt, params=TruthParams(compressibility_tau_s=0.0))
    assert TruthParams().compressibility_tau_s > 0 and np.max(np.abs(on - off)) > 50.0  # N, at 0.48 m/s
    with pytest.raises(ValueError, match="always on in the rig's base physics"):
        truth_force(x, v, np.zeros_like(t), dt=dt, effects=["compressibility"])


def test_the_diagnosis_candidates_are_keyed_by_the_catalogue():
    diagnosed = {e.diagnosed_by for e in CATALOGUE.values() if e.diagnosed_by is not None}
    assert set(CANDIDATES) == diagnosed
    for cid, cand in CANDIDATES.items():
        assert CATALOGUE[cid].diagnosed_by == cid  # a candidate is its own effect's detector
        assert (cand.title, cand.physics) == (CATALOGUE[cid].title, CATALOGUE[cid].physics)
    # the same physical effect, the same id on both sides; bump_stop is found as position-dependent force
    assert set(EFFECTS) & set(CANDIDATES) == {"gas_spring", "thermal", "valve_lag", "friction"}
    assert effect("bump_stop").diagnosed_by == "gas_spring"
    assert additions("bump_stop") == additions("gas_spring")  # detected as it, added as it


@pytest.mark.parametrize("control", ["voltage", "current"])
def test_every_addition_names_known_features_and_their_parameters(control):
    for e in CATALOGUE.values():
        if e.adds is None:
            continue
        a = additions(e.id, control=control)
        assert a["features"] and all(f in FEATURES for f in a["features"]), (e.id, a)
        needed = {_core.FEATURE_PARAMS[f] for f in a["features"]} - {None}
        assert set(a["feature_params"]) == needed, (e.id, a)
        assert all(v > 0 for v in a["feature_params"].values())


def test_additions_take_the_estimates_and_convert_units():
    assert additions("valve_lag", {"tau_s": 0.0137}, "current")["feature_params"] == {"control_lag_tau_s": 0.0137}
    assert additions("friction", {"presliding_length_mm": 0.3})["feature_params"] == {
        "friction_presliding_m": pytest.approx(3e-4, rel=1e-15)}
    assert additions("compressibility", {})["feature_params"] == {"velocity_lag_tau_s": 0.002}  # default
    with pytest.raises(ValueError, match="unknown effect 'nope': expected one of .*bump_stop"):
        additions("nope")


def test_registries_refuse_ids_the_catalogue_does_not_know():
    with pytest.raises(ValueError, match="register the effect in the catalogue first"):
        register_candidate(Candidate(id="not_in_catalogue", needs="-", signature="-", columns=lambda c, t: []))
    with pytest.raises(ValueError, match="register the effect in the catalogue first"):
        register_candidate(Candidate(id="bump_stop", needs="-", signature="-", columns=lambda c, t: []))
    with pytest.raises(ValueError, match="rig must be one of"):
        register_effect(EffectInfo(id="x", title="x", physics="x", rig="sometimes", diagnosed_by=None, adds=None))
    assert "x" not in CATALOGUE and "not_in_catalogue" not in CANDIDATES


def test_rig_list_effects_prints_the_catalogues_words(capsys):
    assert main(["rig", "--list-effects"]) == 0
    out = capsys.readouterr().out
    for e in CATALOGUE.values():
        assert f"{e.id}: {e.title}" in out
        # an effect no candidate knows (mount_hysteresis, campaign_warming) has no recipe to add
        assert (f"dampnet train --add {e.id}:" in " ".join(out.split())) == (e.adds is not None)
    assert "always on in the rig's base physics" in out
    assert "switch on with `dampnet rig --effects valve_lag`" in out


def test_rig_without_out_is_a_one_line_error(capsys):
    assert main(["rig"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and err.count("\n") == 1 and "--list-effects" in err


def _graph():
    import grimp

    return grimp.build_graph("dampnet")


def test_rig_truth_and_effects_do_not_import_each_other():
    g = _graph()
    assert not g.direct_import_exists(importer="dampnet.rig.effects", imported="dampnet.rig.truth")
    assert g.find_shortest_chain(importer="dampnet.rig.effects", imported="dampnet.rig.truth") is None
    assert g.direct_import_exists(importer="dampnet.rig.truth", imported="dampnet.rig.effects")


def test_commands_share_only_common_helpers():
    """No command imports another command's names; shared helpers live in commands.common and
    commands.training_options (simulate/study: the sim engineer's, checked by pyproject's contract)."""
    g = _graph()
    shared = {"dampnet.commands.common", "dampnet.commands.training_options"}
    mine = ["bench", "compare", "compare_algorithms", "demo", "diagnose", "evaluate", "info", "iri", "rig", "train"]
    for name in mine:
        importer = f"dampnet.commands.{name}"
        imported = {m for m in g.find_modules_directly_imported_by(importer) if m.startswith("dampnet.commands.")}
        assert imported <= shared, (importer, imported - shared)
