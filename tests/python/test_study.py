"""The chapter 5 study: stable keys, text tables, plots (short roads, linear dampers, for speed)."""

from __future__ import annotations

import json

import pytest

from dampnet.roads import impulse, sine_sweep, thesis_rough_road
from dampnet.study import DamperSpec, jsonable, run_study, text_tables, write_plots

KEYS = {"schema", "models", "truth", "settings", "impulse", "sine_sweep", "rough_road", "skyhook", "errors"}


def test_study_structure_and_tables(tmp_path):
    a = DamperSpec("soft", "linear", 800.0, u_range=(0.0, 5.0))
    b = DamperSpec("stiff", "linear", 3000.0, u_range=(0.0, 5.0))
    res = run_study([a, b], None, dt=2e-3, sweep=sine_sweep(rate_oct_s=1.0, post_s=2.0),
                    pulse=impulse(total_s=2.0), rough=thesis_rough_road(base_length_m=30.0),
                    keep_runs=True)
    d = json.loads(json.dumps(jsonable(res), default=float))
    assert set(d) == KEYS
    assert set(d["sine_sweep"]) == {"low", "high"}
    assert set(d["rough_road"]) == {"10_low", "10_high", "20_low", "20_high"}
    assert set(d["skyhook"]) == {f"{v}_{c}" for v in (10, 20) for c in ("skyhook", "passive_low", "passive_high")}
    for model in ("soft", "stiff"):
        assert d["sine_sweep"]["low"][model]["transmissibility_peak"] > 1.0
    # A linear damper ignores the control: both levels give the same numbers; stiffer damping lowers
    # the sweep's resonance peak.
    assert d["rough_road"]["10_low"]["soft"]["acc_rms_m_s2"] == pytest.approx(
        d["rough_road"]["10_high"]["soft"]["acc_rms_m_s2"])
    assert d["sine_sweep"]["low"]["stiff"]["transmissibility_peak"] < \
        d["sine_sweep"]["low"]["soft"]["transmissibility_peak"]
    txt = text_tables(res)
    assert "Table 6" in txt and "Table 7" in txt and "Skyhook" in txt
    pngs = write_plots(res, tmp_path)
    assert any("transmissibility" in p.name for p in pngs) and all(p.stat().st_size > 1000 for p in pngs)
