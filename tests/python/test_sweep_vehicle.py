"""`dampnet sweep` full-vehicle cells ([fullcar]): a sweep on a LocalCluster of 2 worker processes
equals dampnet.sim.full_car.runs.run cell by cell (exactly: the same runtime on the same inputs, the
metrics through the cell's JSON record, which keeps a float's every bit); random samples of the
full car's fields are numpy's draws; a cell with a bad vehicle value is an error row naming the
field; --resume reuses the finished cells; the grid drops what a test does not use; bad specs are
one-line errors (exit 2); docs/sweeps.md's [fullcar] example is a valid spec.

Short tests: a 2 -> 4 Hz bounce sweep at 1 octave/s (5 s simulated), the lane change at 100 km/h,
an ISO C road, all at a 2 ms step."""

from __future__ import annotations

import json

import numpy as np
import pytest

import needs

for _module in ("dask.distributed", "pandas", "pyarrow"):
    needs.need_module(_module)

from dampnet.cli import main  # noqa: E402
from dampnet.sweep import parse_spec, run  # noqa: E402
from dampnet.sweep.grid import expand  # noqa: E402
from dampnet.sweep.runner import session  # noqa: E402

SHORT_BSST = {"bsst_f0_hz": 2.0, "bsst_f1_hz": 4.0, "bsst_rate_oct_s": 1.0}
DT = 2e-3
WHEELS = ("fl", "fr", "rl", "rr")


@pytest.fixture(scope="module")
def client():
    with session(workers=2) as (c, info):
        assert info == {"scheduler": "local", "workers": 2}
        yield c


def api_metrics(model: str, man, damping: str, vehicle: dict) -> dict:
    """The cell computed one by one through the fullcar API: its metrics as the table's columns."""
    from dampnet.recipes.maneuvers import run as run_test   # dampnet.sim.full_car.runs.run with the test's metrics
    from dampnet.sim.dampers import load_spec

    r = run_test(load_spec(model), man, damping, vehicle)
    out = {}
    for k, v in r["metrics"].items():
        if isinstance(v, list):              # per wheel: one column each
            out.update({f"{k[:-2]}_{w}_n": x for w, x in zip(WHEELS, v)})
        else:
            out[k] = v
    out["f_static_n"] = r["f_static_n"]
    out["duration_s"] = man.road.shape[0] * man.dt
    return out


def assert_row_is(row, mine: dict, what) -> None:
    for k, v in mine.items():
        got = row[k]
        if v is None:   # a metric the run has not (a sweep that misses the wheel hop): an empty cell
            assert got is None or got != got, (what, k, got, v)
            continue
        assert (got == v) if not isinstance(v, bool) else (bool(got) is v), (what, k, got, v)


def test_fullcar_sweep_equals_fullcar_runs_one_by_one(client, tmp_path):
    from dampnet.evaluation.lookup import LookupTable
    from dampnet.sim.full_car import maneuvers

    lookup = tmp_path / "lookup.json"
    lookup.write_text(LookupTable(velocities=[-1.0, -0.1, 0.0, 0.1, 1.0], voltages=[0.0, 5.0],
                                  forces=[[-1500, -400, 0, 700, 3000], [-600, -150, 0, 200, 900]]).to_json())
    spec = {"fullcar": {"models": [str(lookup), "truth"], "tests": ["bsst", "dlc"], "damping": ["high", "skyhook"],
                        "speeds_kmh": 100.0, "dt": DT, **SHORT_BSST, "vehicle": {"k_arb_f": 30000.0}}}
    df = run(spec, client=client, out=tmp_path / "fc", progress=False)
    assert len(df) == 8 and (df["status"] == "ok").all(), df[["status", "error"]]
    assert set(df["kind"]) == {"fullcar"} and len(set(df["worker"])) == 2
    mans = {"bsst": maneuvers.bsst(DT, "heave", f0=2.0, f1=4.0, rate_oct_s=1.0), "dlc": maneuvers.dlc(DT, 100.0)}
    for _, row in df.iterrows():
        mine = api_metrics(row["model"], mans[row["test"]], row["damping"], {"k_arb_f": 30000.0})
        assert set(mine) <= set(df.columns)
        assert_row_is(row, mine, (row["model"], row["test"], row["damping"]))
    dlc = df[df["test"] == "dlc"]
    assert (dlc["speed_kmh"] == 100.0).all() and dlc["mode"].isna().all() and dlc["acc_rms_m_s2"].isna().all()
    bsst = df[df["test"] == "bsst"]
    assert bsst["speed_kmh"].isna().all() and (bsst["mode"] == "heave").all() and bsst["roll_peak_deg"].isna().all()
    assert (df["vehicle.k_arb_f"] == 30000.0).all()
    summary = json.loads((tmp_path / "fc" / "summary.json").read_text())
    assert summary["fullcar"]["objective"] == "acc_rms_m_s2"
    assert summary["fullcar"]["best"][0]["acc_rms_m_s2"] == bsst["acc_rms_m_s2"].min()
    assert (tmp_path / "fc" / "sensitivity_fullcar.png").is_file()
    rec = json.loads(next((tmp_path / "fc" / "cells").glob("*.json")).read_text())
    assert rec["kind"] == "fullcar" and rec["controller_settings"]["kind"] in ("passive", "skyhook_onoff")


def test_random_vehicle_samples_errors_and_resume(client, tmp_path):
    from dampnet.recipes import maneuvers

    spec = {"fullcar": {"models": ["linear:1500"], "tests": ["road"], "roads": ["iso:C"], "dt": DT,
                        "vehicle": {"k_t": [200000.0, -1.0]},
                        "random": {"n": 2, "seed": 3, "vehicle": {"m_s": {"normal": [2600.0, 100.0]}}}}}
    out = tmp_path / "r"
    df = run(spec, client=client, out=out, progress=False)
    assert list(df["status"]) == ["ok", "ok", "error", "error"], df[["status", "error"]]
    bad = df[df["status"] == "error"]
    assert bad["error"].str.contains("k_t").all() and bad["acc_rms_m_s2"].isna().all()
    rng = np.random.default_rng(3)
    draws = [float(rng.normal(2600.0, 100.0)) for _ in range(2)]
    ok = df[df["status"] == "ok"]
    assert list(ok["vehicle.m_s"]) == draws and (ok["speed_kmh"] == 60.0).all() and (ok["road"] == "iso:C").all()
    for _, row in ok.iterrows():
        man = maneuvers.build("road", DT, {"road": "iso:C"})
        assert_row_is(row, api_metrics("linear:1500", man, "low", {"k_t": 200000.0, "m_s": row["vehicle.m_s"]}),
                      row["vehicle.m_s"])
    again = run(spec, client=client, out=out, resume=True, progress=False)
    assert again.attrs["sweep"]["reused"] == 2 and again.attrs["sweep"]["computed"] == 2   # the errors again
    assert list(again["cell"]) == list(df["cell"])
    assert (again.loc[again["status"] == "ok", "acc_rms_m_s2"].to_numpy() == ok["acc_rms_m_s2"].to_numpy()).all()


def test_the_grid_drops_what_a_test_does_not_use():
    spec = parse_spec({"fullcar": {"models": ["linear:1500"], "tests": ["bsst", "dlc", "road"],
                                   "modes": ["heave", "pitch"], "roads": ["thesis", "iso:B"]}})
    cells = expand(spec)
    by = {}
    for c in cells:
        by.setdefault(c.params["test"], []).append(c.params)
    assert [len(by[t]) for t in ("bsst", "dlc", "road")] == [2, 1, 2]      # modes: bsst; roads: road
    assert all(p["speed_kmh"] is None and p["road"] is None for p in by["bsst"])
    assert by["dlc"][0]["speed_kmh"] == 120.0 and by["dlc"][0]["mode"] is None
    assert all(p["speed_kmh"] == 60.0 and p["bsst_f0_hz"] is None for p in by["road"])
    assert spec.sections["fullcar"].objective == "acc_rms_m_s2"
    assert parse_spec({"fullcar": {"tests": "dlc"}}).sections["fullcar"].objective == "roll_peak_deg"


def test_the_documented_fullcar_spec_is_valid(repo_root):
    text = (repo_root / "docs" / "sweeps.md").read_text()
    block = text[text.index("# Sweeps on Dask"):]
    block = block[block.index("```toml\n[fullcar]") + 8:]
    cells = expand(parse_spec(block[:block.index("```")], source="docs/sweeps.md", base=repo_root))
    assert len(cells) == 16 and {c.kind for c in cells} == {"fullcar"}


@pytest.mark.parametrize("text, fragments", [
    ("[fullcar]\ntests = ['dlc']\n[fullcar.vehicle]\nm_sprung = 2000.0\n",
     ["line 4", "fullcar.vehicle.m_sprung", "unknown key", "m_s, i_xx"]),
    ("[fullcar]\n[fullcar.vehicle]\nspeed = 30.0\n", ["line 3", "fullcar.vehicle.speed", "speeds_kmh"]),
    ("[fullcar]\ntests = ['dlc', 'slalom']\n", ["line 2", "fullcar.tests[1]", "'slalom' is not a full-vehicle test",
                                               "bsst, dlc, road"]),
    ("[fullcar]\ndamping = 'medium'\n", ["line 2", "fullcar.damping", "low, high, skyhook"]),
    ("[fullcar]\nspeeds = [100.0]\n", ["line 2", "fullcar.speeds", "unknown key", "speeds_kmh"]),
    ("[fullcar]\ndt = 0.5\n", ["line 2", "fullcar.dt", "[1e-06, 0.01] s"]),
    ("[fullcar]\n[fullcar.vehicle]\ntyre_model = 'pacejka'\n", ["fullcar.vehicle.tyre_model", "magic_formula"]),
    ("[fullcar]\n[fullcar.random]\nn = 2\nseed = 0\n[fullcar.random.vehicle]\nmass = {normal = [1, 2]}\n",
     ["line 6", "fullcar.random.vehicle.mass", "unknown key"]),
    ("[fullcar]\nobjective = 'comfort'\n", ["fullcar.objective", "roll_peak_deg"]),
    ("[fullcars]\n", ["fullcars", "unknown table", "fullcar"]),
])
def test_bad_fullcar_specs_are_one_line_errors(tmp_path, capsys, text, fragments):
    spec = tmp_path / "s.toml"
    spec.write_text(text)
    capsys.readouterr()
    rc = main(["sweep", str(spec), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("dampnet: error: ") and err.count("\n") == 1, (rc, err)
    for f in (str(spec), *fragments):
        assert f in err, (f, err)
    assert not (tmp_path / "o").exists()
