"""The same road through the three front doors gives the same result: pybind11
(dampnet._core), the C ABI from a plain C program (tests/cpp/functional/test_loop_c.c), and
the C ABI from Python through cffi (the shared library of the installed package)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

import needs

from cbuild import ROOT, compile_program
from cdefs import MLP_CDEF
from dampnet import paths
from dampnet.sim.quarter_car.loop import S, QuarterCar, add_terms, damper_from_model
from dampnet.model import MlpModel
from test_loop_quarter_car import random_road

GAS = [{"kind": "position_poly", "params": [-150.0, 3000.0, 0.0, 0.0]}]
N = 3000

CDEF = MLP_CDEF + """
typedef struct dn_damper dn_damper;
typedef struct dn_loop_model dn_loop_model;
typedef struct dn_loop_data dn_loop_data;
typedef struct dn_vehicle {
  double m_s; double m_us; double k_s; double k_t; double c_t; double dt;
  int integrator; int damper_eval; double x_static; double f_static; double temperature;
  int accel_feature;
} dn_vehicle;
typedef struct dn_controller {
  int kind; double u_passive; double u_soft; double u_hard; double u_min; double u_max;
  double c_sky; double c_gnd; double c_min; double c_max; double u_tau_s;
  double alpha; double k_travel; double k_vs; double k_tyre; double k_vus;
} dn_controller;
typedef struct dn_loop_input { double z_r; double v_r; double u; } dn_loop_input;
typedef struct dn_loop_out {
  double force; double u; double x; double v; double a; double acc_s; double acc_us;
  double features[8]; int n_features; uint32_t clamped_mask;
} dn_loop_out;
int dn_mlp_create(const dn_mlp_desc* desc, dn_mlp** out);
void dn_mlp_destroy(dn_mlp* m);
int dn_damper_create_neural(const dn_mlp* mlp, const char* const* features, int n_features,
                            const char* const* param_names, const double* param_values,
                            int n_params, int precision, dn_damper** out);
int dn_damper_add_term(dn_damper* d, const char* kind, const double* params, int n_params);
void dn_damper_destroy(dn_damper* d);
void dn_vehicle_default(dn_vehicle* v);
void dn_controller_default(dn_controller* c, int kind);
int dn_loop_model_create(const dn_vehicle* veh, const dn_damper* damper,
                         const dn_controller* ctrl, dn_loop_model** out);
void dn_loop_model_destroy(dn_loop_model* m);
int dn_loop_data_create(const dn_loop_model* m, dn_loop_data** out);
void dn_loop_data_destroy(dn_loop_data* d);
int dn_loop_state_size(void);
int dn_loop_get_state(const dn_loop_data* d, double* state);
int dn_loop_set_state(dn_loop_data* d, const double* state);
int dn_loop_step(const dn_loop_model* m, dn_loop_data* d, const dn_loop_input* in, dn_loop_out* out);
const char* dn_status_str(int status);
"""


@pytest.fixture(scope="module")
def road():
    z, zd = random_road(seed=21, rms=0.015)
    t = np.arange(N) * 1e-3
    return z(t), zd(t)


@pytest.fixture(scope="module")
def model():
    return MlpModel.load(ROOT / "export" / "dn_model_default.json")


@pytest.fixture(scope="module")
def via_pybind(model, road):
    car = QuarterCar(add_terms(damper_from_model(model), GAS), {}, {"kind": "skyhook_onoff"})
    out = car.simulate(*road)
    return out["state"][:, [S["t"], S["z_s"], S["v_s"], S["z_us"], S["v_us"]]], out["force"][:-1]


def test_c_program_equals_pybind(tmp_path, road, via_pybind):
    exe = compile_program([ROOT / "tests" / "cpp" / "functional" / "test_loop_c.c"], tmp_path / "loop_c",
                          cxx=False, include_dirs=paths.include_dirs() + [ROOT / "export",
                                                                          ROOT / "tests" / "cpp" / "support"],
                          libs=[paths.shared_library()])
    assert "all checks passed" in subprocess.run([exe], capture_output=True, text=True, check=True).stdout
    road_file = tmp_path / "road.txt"
    np.savetxt(road_file, np.stack(road, axis=1), fmt="%.17g")
    out = subprocess.run([exe, road_file, "neural", "1"], capture_output=True, text=True, check=True)
    lines = out.stdout.splitlines()
    states = np.array([l.split()[1:] for l in lines if l.startswith("S ")], dtype=float)
    forces = np.array([l.split()[0] for l in lines if not l.startswith("S ")], dtype=float)
    ref_states, ref_forces = via_pybind
    np.testing.assert_allclose(states, ref_states, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(forces, ref_forces, rtol=1e-12, atol=1e-9)


def run_cffi(model, road, u_tau_s=0.0):
    """The skyhook run of via_pybind through the C ABI from Python (cffi): (states, forces)."""
    cffi = needs.need_module("cffi")
    ffi = cffi.FFI()
    ffi.cdef(CDEF)
    lib = ffi.dlopen(str(paths.shared_library()))
    keep = []

    def arr(a):
        c = ffi.new("double[]", [float(v) for v in np.ravel(a)])
        keep.append(c)
        return c

    desc = ffi.new("dn_mlp_desc*")
    desc.n_inputs, desc.n_hidden1 = model.n_inputs, model.hidden[0]
    desc.n_hidden2 = 0
    desc.activation = 0 if model.activation == "tanh" else 1
    desc.w1, desc.b1, desc.w_out = arr(model.w1), arr(model.b1), arr(model.w_out)
    desc.b_out, desc.in_offset, desc.in_gain = arr([model.b_out]), arr(model.in_offset), arr(model.in_gain)
    desc.in_ymin, desc.out_offset, desc.out_gain, desc.out_ymin = (model.in_ymin, model.out_offset,
                                                                   model.out_gain, model.out_ymin)
    desc.sat_lo, desc.sat_hi = arr(model.sat_lo), arr(model.sat_hi)

    def ok(st):
        assert st >= 0, ffi.string(lib.dn_status_str(st)).decode()

    mlp = ffi.new("dn_mlp**")
    ok(lib.dn_mlp_create(desc, mlp))
    names = [ffi.new("char[]", f.encode()) for f in model.features]
    cnames = ffi.new("const char*[]", names)
    damper = ffi.new("dn_damper**")
    ok(lib.dn_damper_create_neural(mlp[0], cnames, len(names), ffi.NULL, ffi.NULL, 0, 0, damper))
    ok(lib.dn_damper_add_term(damper[0], b"position_poly", arr(GAS[0]["params"]), 4))
    veh = ffi.new("dn_vehicle*")
    lib.dn_vehicle_default(veh)
    ctrl = ffi.new("dn_controller*")
    lib.dn_controller_default(ctrl, 1)
    ctrl.u_tau_s = u_tau_s
    m = ffi.new("dn_loop_model**")
    ok(lib.dn_loop_model_create(veh, damper[0], ctrl, m))
    d = ffi.new("dn_loop_data**")
    ok(lib.dn_loop_data_create(m[0], d))
    n_s = lib.dn_loop_state_size()
    s = ffi.new("double[]", n_s)
    z, zd = road
    lib.dn_loop_get_state(d[0], s)
    s[S["z_r"]], s[S["v_r"]] = z[0], zd[0]
    ok(lib.dn_loop_set_state(d[0], s))
    inp = ffi.new("dn_loop_input*")
    out = ffi.new("dn_loop_out*")
    states, forces = [], []
    for k in range(N):
        lib.dn_loop_get_state(d[0], s)
        states.append([s[i] for i in (S["t"], S["z_s"], S["v_s"], S["z_us"], S["v_us"])])
        if k + 1 < N:
            inp.z_r, inp.v_r, inp.u = z[k + 1], zd[k + 1], 0.0
            ok(lib.dn_loop_step(m[0], d[0], inp, out))
            forces.append(out.force)
    lib.dn_loop_data_destroy(d[0])
    lib.dn_loop_model_destroy(m[0])
    lib.dn_damper_destroy(damper[0])
    lib.dn_mlp_destroy(mlp[0])
    return np.array(states), np.array(forces)


def test_cffi_equals_pybind(model, road, via_pybind):
    states, forces = run_cffi(model, road)
    ref_states, ref_forces = via_pybind
    np.testing.assert_allclose(states, ref_states, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(forces, ref_forces, rtol=1e-12, atol=1e-9)


def test_command_filter_through_cffi_equals_pybind(model, road, via_pybind):
    """dn_controller.u_tau_s (ABI 0.3) set from C reaches the loop as from pybind, and changes the run."""
    states, forces = run_cffi(model, road, u_tau_s=0.004)
    car = QuarterCar(add_terms(damper_from_model(model), GAS), {}, {"kind": "skyhook_onoff", "u_tau_s": 0.004})
    out = car.simulate(*road)
    np.testing.assert_allclose(states, out["state"][:, [S["t"], S["z_s"], S["v_s"], S["z_us"], S["v_us"]]],
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(forces, out["force"][:-1], rtol=1e-12, atol=1e-9)
    assert np.max(np.abs(forces - via_pybind[1])) > 10.0   # the filter changes the forces [N]


def test_forward_reports_what_the_next_step_reports_without_advancing(model, road):
    """Loop.forward: the report of the step that would start now (a StepReport, like step's);
    the state is unchanged, and the step then taken reports the same values."""
    car = QuarterCar(damper_from_model(model), controller={"kind": "skyhook_onoff"})
    z, v = road
    for k in range(1, 200):
        car.step(z[k], v[k])
    before = car.state.copy()
    f = car.loop.forward(0.0)
    np.testing.assert_array_equal(car.state, before)
    s = car.step(z[200], v[200])
    assert type(f) is type(s)
    for key in ("force", "u", "x", "v", "a", "acc_s", "acc_us", "status"):
        assert f[key] == s[key], key
    np.testing.assert_array_equal(f["features"], s["features"])
