"""The compile-time options of a microcontroller build, on the host (no cross toolchain needed):
a program and the library's sources the firmware links, built with the cortex-m4 preset's
definitions (dampnet.export.mcu.target_defines: DN_LOOP_FLOAT 1, DN_DAMPER_KINDS neural only,
DN_ACCEL_FEATURES linear and explicit, DN_DAMPER_EVALS per step, DN_DOUBLE_KERNEL 0, the small
kernel, DN_SMALL_CODE) and compiled with -Wdouble-promotion -Werror.

* The float loop (the quarter car of tests/python/test_embedded.py: per-step evaluation, the
  linearised acceleration feature, on-off skyhook with a 5 ms command filter, the default model
  built in place from its folded floats by dn_loop_model_init_neural) over 2 s of the thesis rough road equals the host's
  double loop (dampnet._core) within 1e-4 of each state's peak.
* A kind left out is refused at set-up (DN_E_PARAM); so is a force-tracking law (DN_CONTROLLER_KINDS:
  the presets leave them out, keeping the damper's inverse out of flash), and a vehicle asking for the implicit
  solve or per-stage evaluation, and the default vehicle then asks for the linear scheme and
  one evaluation per step.
* Hard inputs: a NaN or infinite road gives DN_E_NONFINITE_INPUT; a huge road (1e30-3e38 m)
  steps with every value finite or, where float overflows, gives DN_E_DIVERGED; the state is
  unchanged on every error."""

from __future__ import annotations

import subprocess

import numpy as np

from cbuild import ROOT, compile_program
from dampnet import _core
import firmware_lab as emb  # bench/firmware_lab.py (the conftest puts bench/ on the path)
from dampnet.modeldir import load_model

PROGRAM = r"""
#include <cmath>
#include <cstdio>
#include <type_traits>
#include "dampnet/loop.hpp"
#include "dn_model_default.h"
#include "internal.hpp"  // the C ABI's handles: the loop model dn_loop_model_init_neural builds
using namespace dampnet;
alignas(DN_STORAGE_ALIGN) static unsigned char storage[sizeof(dn_loop_model)];
static LoopData data;
int main() {
  static_assert(std::is_same<real, float>::value, "DN_LOOP_FLOAT makes the loop float");
  Damper other;
  int user = 0;
  auto fn = [](void*, const dn_damper_input*) -> dn_real { return 0; };
  std::printf("linear %d callback %d\n", other.set_linear(1000.0), other.set_callback(fn, &user));
  dn_vehicle v = default_vehicle();
  std::printf("default_accel %d\n", v.accel_feature);
  dn_vehicle implicit = v;
  implicit.accel_feature = DN_ACCEL_IMPLICIT;
  std::printf("implicit %d\n", check_vehicle(implicit));
  std::printf("default_eval %d\n", v.damper_eval);
  dn_vehicle per_stage = v;
  per_stage.damper_eval = DN_EVAL_PER_STAGE;
  std::printf("per_stage %d\n", check_vehicle(per_stage));
  std::printf("force_law %d onoff %d\n", check_controller(default_controller(DN_CTRL_SKYHOOK_FORCE)),
              check_controller(default_controller(DN_CTRL_SKYHOOK_ONOFF)));
  const dn_mlp_folded_f folded = DN_MODEL_DEFAULT_FOLDED_INIT;
  v.damper_eval = DN_EVAL_PER_STEP;
  v.accel_feature = DN_ACCEL_LINEAR;
  dn_controller c = default_controller(DN_CTRL_SKYHOOK_ONOFF);
  c.u_tau_s = 0.005f;
  dn_loop_model* handle = nullptr;
  const int st = dn_loop_model_init_neural(&v, &c, &folded, dn_model_default_feature_names, DN_MODEL_DEFAULT_N_INPUTS,
                                           nullptr, nullptr, 0, storage, sizeof storage, &handle);
  std::printf("setup %d\n", st);
  if (st != DN_OK) return 1;
  const LoopModel& model = handle->m;
  reset(model, data);
  double z, zdot;
  int k = 0, errors = 0;
  while (std::scanf("%lf %lf", &z, &zdot) == 2) {
    const dn_loop_input in = {static_cast<float>(z), static_cast<float>(zdot), 0.0f};
    dn_loop_out out;
    if (step(model, data, in, &out) < 0) ++errors;
    if (++k % 100 == 0) {
      std::printf("s %d", k);
      for (float x : data.s) std::printf(" %.9g", static_cast<double>(x));
      std::printf("\n");
    }
  }
  std::printf("errors %d\n", errors);
  // hard inputs to the float loop: a NaN or infinite road is refused; a huge one either steps with
  // every value finite or fails (DN_E_DIVERGED) leaving the state as it was
  const float hard[][2] = {{NAN, 0.0f}, {0.0f, INFINITY}, {1e30f, 0.0f}, {0.0f, 1e38f}, {3e38f, -3e38f}};
  for (const auto& h : hard) {
    const LoopData before = data;
    dn_loop_out out{};
    const int st = step(model, data, dn_loop_input{h[0], h[1], 0.0f}, &out);
    bool same = true, finite = std::isfinite(out.force) && std::isfinite(out.a) && std::isfinite(out.acc_s);
    for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i) {
      same = same && data.s[i] == before.s[i];
      finite = finite && std::isfinite(data.s[i]);
    }
    std::printf("hard %d %d %d\n", st, int(same), int(finite));
  }
  return 0;
}
"""

# the cortex-m4 preset's definitions, as dampnet.export.mcu gives them to its cross builds
DEFINES = ["-DDN_STATIC"] + [f"-D{d}" for d in emb.target_defines("cortex-m4", emb.DEFAULT_CAPS)]


def test_the_float_loop_build_on_the_host(tmp_path):
    src = tmp_path / "float_loop.cpp"
    src.write_text(PROGRAM)
    # with the library's sources the firmware links (its set-up is dn_loop_model_init_neural's)
    lib = [ROOT / "cpp" / "src" / f for f in ("c_api_common.cpp", "c_api_mlp.cpp", "c_api_loop.cpp")]
    exe = compile_program([src, *lib], tmp_path / "float_loop", cxx=True,
                          include_dirs=[ROOT / "cpp" / "include", ROOT / "cpp" / "src", ROOT / "export"],
                          extra=[*DEFINES, "-Wdouble-promotion"])
    model = load_model(ROOT / "export" / "dn_model_default.json")
    road = emb.make_vectors(model, n_x=8, seconds=2.0).road
    stdin = "\n".join(f"{z!r} {v!r}" for z, v in road.tolist())
    proc = subprocess.run([str(exe)], input=stdin, capture_output=True, text=True, timeout=120, check=True)
    lines = proc.stdout.splitlines()
    head = dict(line.split(" ", 1) for line in lines if not line.startswith(("s ", "hard ")))
    # kinds and schemes left out: refused at set-up; the default vehicle asks for "linear"
    linear, _, callback = head["linear"].split()
    assert int(linear) == int(callback) == int(head["implicit"]) == int(head["per_stage"]) == _core.DN_E_PARAM
    assert int(head["default_accel"]) == _core.ACCEL_FEATURES["linear"][0]
    assert int(head["default_eval"]) == _core.DAMPER_EVALS["per_step"][0]
    # the force-tracking laws are left out (DN_CONTROLLER_KINDS): refused; the others kept
    force_law, _, onoff = head["force_law"].split()
    assert int(force_law) == _core.DN_E_PARAM and int(onoff) == 0
    assert int(head["setup"]) == 0 and int(head["errors"]) == 0
    hard = [tuple(map(int, line.split()[1:])) for line in lines if line.startswith("hard ")]
    assert len(hard) == 5 and all(finite for _, _, finite in hard)
    assert [(st, same) for st, same, _ in hard[:2]] == [(_core.DN_E_NONFINITE_INPUT, 1)] * 2
    assert all(same for st, same, _ in hard if st < 0)  # the state unchanged on every error
    assert all(st >= 0 or st == _core.DN_E_DIVERGED for st, _, _ in hard[2:])
    assert any(st == _core.DN_E_DIVERGED for st, _, _ in hard[2:])  # 3e38 m overflows float
    fw = np.array([[float(x) for x in line.split()[2:]] for line in lines if line.startswith("s ")])
    from dampnet.sim.vehicle import Controller

    states, _, _ = emb.host_loop(model, road, controller=Controller(kind="skyhook_onoff", u_tau_s=0.005))  # PROGRAM's
    host = np.array([s for _, s in states])
    assert fw.shape == host.shape == (20, len(_core.STATE_NAMES))
    idx = [_core.STATE_NAMES.index(n) for n in ("z_s", "v_s", "z_us", "v_us", "u_cmd")]
    peak = np.abs(host[:, idx]).max(axis=0)
    err = np.abs(fw[:, idx] - host[:, idx]).max(axis=0)
    print("float loop vs host double loop, error / peak (z_s, v_s, z_us, v_us, u_cmd):", err / peak)
    assert np.all(peak > 0) and np.all(err <= 1e-4 * peak), err / peak
    assert peak[0] > 1e-3  # the road moved the car


def test_a_firmware_running_a_force_law_links_it():
    """DN_CONTROLLER_KINDS: the presets' laws (CMakePresets.json's list, mcu's DEFAULT_CONTROLLER_KINDS)
    leave out the force-tracking ones; a firmware whose law tracks a force gets it added (its
    inverse linked), one whose law is already in keeps the default mask. Cost: 0.01 s."""
    import json

    from dampnet.export import mcu

    preset = json.loads((ROOT / "CMakePresets.json").read_text())["configurePresets"][0]["cacheVariables"]
    assert tuple(preset["DAMPNET_CONTROLLER_KINDS"].split(";")) == mcu.DEFAULT_CONTROLLER_KINDS
    mask = lambda defs: int(next(d for d in defs if d.startswith("DN_CONTROLLER_KINDS=")).split("=")[1])  # noqa: E731
    default = mask(mcu.target_defines("cortex-m4", emb.DEFAULT_CAPS))
    assert all(not (default >> _core.CONTROLLER_KINDS[k][0]) & 1
               for k in ("skyhook_force", "groundhook_force", "hybrid_force", "clipped_optimal"))
    assert mask(mcu.target_defines("cortex-m4", emb.DEFAULT_CAPS, controllers=mcu.controller_kinds("skyhook_onoff"))) \
        == default
    with_law = mask(mcu.target_defines("cortex-m4", emb.DEFAULT_CAPS, controllers=mcu.controller_kinds("clipped_optimal")))
    assert with_law == default | (1 << _core.CONTROLLER_KINDS["clipped_optimal"][0])
