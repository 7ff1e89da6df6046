"""bench/real_data.py (issue 53 item 1) and its peer models (bench/peers): the table is written
from a small slice of the real UTFSM data; the modified Bouc-Wen model behaves as Spencer, Dyke,
Sain and Carlson (1997) describe it and its fit recovers known parameters; the GRU beats the
lookup table on the virtual rig. Each test states its cost (2 shared cores, loaded)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dampnet.data.real import UTFSM, shared_data_dir
from peers import bouc_wen as bw


def _need_real_data():
    """The real data are not the project's (../shared/data, never copied in): where they are absent
    (a clone elsewhere), the test says so by name, as tests/python/test_data_real.py does; the
    script's own refusal then is the test below, which needs no data."""
    d = shared_data_dir() / UTFSM
    if not d.is_dir():
        pytest.skip(f"real data not present: {d} is missing (the shared data folder, or set DAMPNET_SHARED_DATA)")


def test_real_data_quick_writes_the_table(tmp_path):
    """Cost: about 20 s. The script on the UTFSM slice (5 Hz and 3 Hz tests, 0.5 A held out):
    every model's row with finite errors, the split stated, both files written; the lookup table
    and dampnet are scored on the same held-out tests and samples."""
    _need_real_data()
    import real_data

    res = real_data.run(["utfsm"], quick=True, out=tmp_path, log=lambda *a: None)
    d = res["datasets"]["utfsm"]
    assert d["held_out"] == ["2mm5Hz0x5A", "5mm3Hz0x5A"] and d["n_train"] == 8
    names = [r["model"] for r in d["models"]]
    assert names[0] == "lookup table" and names[1] == "dampnet (default)"
    assert any(n.startswith("Bouc-Wen") for n in names) and any(n.startswith("GRU") for n in names)
    for r in d["models"]:
        assert [p["test_id"] for p in r["per_test"]] == d["held_out"]
        assert np.isfinite(r["rmse_n"]) and 0 < r["nrmse"] < 1, r["model"]
        assert r["parameters"] > 0 and r["train_s"] >= 0 and r["infer_us"] > 0
        assert r["at_rest"] is None         # UTFSM's MTS sines never stand still: no error at rest claimed
    assert "diagnosis" in d["models"][1]  # the loop ran its step on the default model
    saved = json.loads((tmp_path / "real_data.json").read_text())
    assert saved["datasets"]["utfsm"]["held_out"] == d["held_out"]
    md = (tmp_path / "real_data.md").read_text()
    assert "0.5 A held out" in md and "| lookup table |" in md and "Per held-out test" in md
    assert "| none at rest |" in md
    # the model beats the table on its own data? not asserted: the slice is tiny and the budgets small;
    # the full run's numbers are in bench/RESULTS.md


# -- the modified Bouc-Wen model against Spencer et al. 1997 -------------------------------------

def _sine(f=2.5, amp=0.015, dt=2e-4, seconds=1.2):
    """The paper's Fig. 5/6 test: 2.5 Hz, 1.5 cm."""
    t = np.arange(0.0, seconds, dt)
    w = 2 * np.pi * f
    return t, amp * np.sin(w * t), amp * w * np.cos(w * t), dt


def test_bouc_wen_loops_have_the_papers_shape():
    """Cost: about 2 s. With the 1997 paper's parameters on its 2.5 Hz, 1.5 cm sine: the peak force
    rises with voltage to the paper's order (about 1.5 kN at 2.25 V, a few hundred N at 0 V);
    the force-displacement loop encloses area (energy dissipated per cycle, more with voltage);
    the force-velocity loop is open at v = 0 (hysteresis) and the force saturates in velocity
    (Bingham-like: a steep pre-yield slope, a shallow post-yield one)."""
    t, x, xd, dt = _sine()
    last = t >= 0.8  # one steady cycle
    peaks, energy = [], []
    for u in (0.0, 0.75, 1.5, 2.25):
        F = bw.simulate(bw.PAPER, x, xd, np.full_like(x, u), dt, substeps=1)
        Fc = F[last] + bw.PAPER["k1"] * bw.PAPER["x0"]  # the accumulator's offset removed
        peaks.append(np.max(np.abs(Fc)))
        energy.append(np.trapezoid(F[last] * xd[last], t[last]))  # J per cycle
        if u == 2.25:
            top = np.argmax(np.where(last, x, -1))   # v = 0 after moving up
            bot = np.argmin(np.where(last, x, 1))    # v = 0 after moving down
            opening = (F[top] - F[bot]) / peaks[-1]
            vpk = np.max(xd)
            pre = last & (np.abs(xd) < 0.05 * vpk) & (xd > 0)
            post = last & (xd > 0.6 * vpk) & (np.gradient(xd) < 0)
            slope_pre = np.polyfit(xd[pre], F[pre], 1)[0]
            slope_post = np.polyfit(xd[post], F[post], 1)[0]
    assert np.all(np.diff(peaks) > 0)
    assert 1000 < peaks[-1] < 2000 and 200 < peaks[0] < 800
    assert all(e > 0 for e in energy) and np.all(np.diff(energy) > 0)
    assert opening > 0.05
    assert slope_pre > 5 * slope_post > 0


def test_bouc_wen_force_lags_a_voltage_step_by_the_filter():
    """Cost: under 1 s. At constant velocity a step of the command 0 -> 2.25 V moves the force
    with the first-order filter's time constant 1/eta (the paper's eta = 190 1/s: 5.3 ms)."""
    dt = 1e-4
    t = np.arange(0.0, 0.1, dt)
    x, xd = 0.05 * t, np.full_like(t, 0.05)
    v = np.where(t >= 0.05, 2.25, 0.0)
    F = bw.simulate(bw.PAPER, x, xd, v, dt, substeps=1, u0=0.0)
    f0, f1 = F[t < 0.05][-1], F[-1]
    assert f1 > 3 * f0 > 0
    k = np.argmax((t >= 0.05) & (F >= f0 + 0.632 * (f1 - f0)))
    assert t[k] - 0.05 == pytest.approx(1 / bw.PAPER["eta"], rel=0.3)


def test_bouc_wen_fit_recovers_known_parameters_to_their_order_of_magnitude():
    """Cost: about 2-8 s. Data simulated with parameters unlike the paper's (damping x2-3, the
    hysteresis shaped otherwise, n = 2), 3 sines x 3 voltages: the fit, started from the paper's
    values scaled to the data (`start_params`), fits the force to 2 % of its range and recovers
    the parameters that set the force's level and loop shape within a factor of 10 (measured:
    0.75-1.8x; c1b 4x). The two stiffnesses k0 (the series spring) and k1 (the accumulator) trade
    off on steady sines (k0 came out 0.03x, k1 13x): only their sum (0.7x) and the accumulator's
    force offset k1 x0 (1.0x) are identified, and checked."""
    true = dict(bw.PAPER, c0a=3 * 21.0e2, c1a=2 * 283e2, alpha_a=3 * 140e2, alpha_b=2 * 695e2, A=150.0,
                gamma=2 * 363e4, beta=363e4, k0=2 * 46.9e2)
    recs = []
    for f, amp in ((1.0, 0.01), (2.5, 0.015), (4.0, 0.005)):
        for u in (0.0, 1.0, 2.25):
            period = 1.0 / f
            dt = period / 100
            t = np.arange(0.0, 2 * period + 1e-12, dt)
            x = amp * np.sin(2 * np.pi * f * t)
            xd = amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t)
            v = np.full_like(x, u)
            recs.append(bw.Record(x, xd, v, bw.simulate(true, x, xd, v, dt, substeps=2), dt))
    res = bw.fit(recs, max_nfev=30, substeps=2)
    F = np.concatenate([r.force for r in recs])
    assert res.cost_rmse_n < 0.02 * np.ptp(F)
    for k in ("c0a", "c0b", "c1a", "c1b", "alpha_a", "alpha_b", "gamma", "beta", "A", "n"):
        ratio = res.params[k] / true[k]
        assert 0.1 < ratio < 10, (k, res.params[k], true[k])
    assert 0.5 < (res.params["k0"] + res.params["k1"]) / (true["k0"] + true["k1"]) < 2
    # the accumulator's offset k1 x0 (the force at x = 0 at rest) to 10 %
    assert res.params["k1"] * res.params["x0"] == pytest.approx(true["k1"] * true["x0"], rel=0.1)
    assert res.fixed == {"eta": bw.PAPER["eta"]}


# -- the sequence model on the virtual rig --------------------------------------------------------

def test_gru_beats_the_lookup_table_on_the_virtual_rig():
    """Cost: about 8 s. The rig's quick plan (seed 0: 0.25, 1, 3 Hz x 0, 2.25, 5 V), the 1 Hz tests
    held out at every voltage (by test: a frequency between the trained ones), every signal taken
    at 500 Hz: a GRU of 32 units over a 20-sample (40 ms) window, trained for 20 epochs of 8,000
    windows (the 300 s cap never binds, so the result does not depend on the machine's load), has
    a held-out RMSE below 0.85 x the lookup table's fitted on the same training tests (seeds 0-3:
    66-131 N against the table's 185 N). Not asserted: the 2.25 V hold-out (control interpolation
    from two levels), where this budget does not beat the table reliably (seeds 0-3: 88-133 N
    against 103 N; bench/RESULTS.md, issue 53's section)."""
    import dampnet
    from dampnet.evaluation.lookup import fit_lookup
    from peers import sequence as seq

    ds = dampnet.rig.generate("quick", seed=0)
    train = [t for t in ds.tests if t.frequency_hz != 1.0]
    test = [t for t in ds.tests if t.frequency_hz == 1.0]
    assert len(train) == 6 and len(test) == 3

    def rec(t, step=10):  # 5 kHz -> 500 Hz
        c = t.channels
        return seq.SeqRecord(c["displacement"][::step], c["velocity"][::step],
                             np.asarray(t.control, dtype=np.float64)[::step], c["force"][::step])

    peer = seq.train_gru([rec(t) for t in train], window=20, hidden=32, epochs=20, seconds=300.0,
                         max_windows=8000, threads=1, seed=0)
    lut = fit_lookup(train)
    forces = [rec(t).force for t in test]
    e_gru = np.concatenate([peer.predict(rec(t)) - f for t, f in zip(test, forces)])
    e_lut = np.concatenate([lut.predict_test(t)[::10] - f for t, f in zip(test, forces)])
    rmse_gru, rmse_lut = np.sqrt(np.mean(e_gru ** 2)), np.sqrt(np.mean(e_lut ** 2))
    assert rmse_gru < 0.85 * rmse_lut, (rmse_gru, rmse_lut)


def test_real_data_without_the_data_names_the_missing_folder(tmp_path, monkeypatch, capsys):
    """Cost: under 1 s. With the shared data elsewhere, the script exits 2 naming the folder it
    looked for (and how to point it elsewhere), before any training."""
    import real_data

    monkeypatch.setenv("DAMPNET_SHARED_DATA", str(tmp_path / "nowhere"))
    assert real_data.main(["--quick", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "nowhere" / UTFSM) in err and "DAMPNET_SHARED_DATA" in err
    assert not (tmp_path / "out").exists()
