// libFuzzer harness (c): the quarter-car loop through the C ABI. A damper of any
// kind (fuzz_common.hpp), an arbitrary vehicle (masses, stiffnesses, dt, integrator,
// damper evaluation, acceleration feature), controller (every law, limits, gains,
// command filter), optionally dn_loop_set_state with an arbitrary state, then up to
// 64 steps (and dn_loop_forward calls) with arbitrary road and control inputs.
// Asserted (abort otherwise): *out NULL exactly when creation fails; set_state
// refusing a state leaves the state unchanged; a step with a status >= 0 leaves a
// finite state and reports finite values; a step with an error leaves the state
// bit for bit unchanged; dn_loop_forward never changes the state and reports
// finite values on success.
#include "fuzz_common.hpp"

namespace {

void check_out(const dn_loop_out& o, const char* call, int st) {
  const double v[] = {o.force, o.u, o.x, o.v, o.a, o.acc_s, o.acc_us};
  const char* names[] = {"force", "u", "x", "v", "a", "acc_s", "acc_us"};
  for (int i = 0; i < 7; ++i)
    if (!std::isfinite(v[i])) {
      std::fprintf(stderr, "dn_fuzz: out.%s = %g\n", names[i], v[i]);
      dn_fuzz::fail("non-finite report with a success status", call, st);
    }
  if (o.n_features < 0 || o.n_features > DN_MAX_INPUTS) dn_fuzz::fail("n_features out of range", call, st);
  for (int i = 0; i < o.n_features; ++i)
    dn_fuzz::check_finite(o.features[i], "non-finite feature with a success status", call, st);
}

double pick(FuzzedDataProvider& f, double typical) {
  if (f.ConsumeIntegralInRange<int>(0, 7) == 0) return dn_fuzz::value(f);
  return typical * f.ConsumeIntegralInRange<int>(-2000, 2000) / 1000.0;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider f(data, size);
  dn_fuzz::DamperBuf buf;
  if (buf.create(f, /*allow_callback=*/true) != DN_OK) return 0;

  dn_vehicle veh;
  dn_vehicle_default(&veh);
  if (f.ConsumeBool()) {
    veh.m_s = dn_fuzz::positive(f, 700.0);
    veh.m_us = dn_fuzz::positive(f, 40.0);
    veh.k_s = dn_fuzz::positive(f, 15000.0);
    veh.k_t = dn_fuzz::positive(f, 200000.0);
    veh.c_t = f.ConsumeBool() ? 0.0 : dn_fuzz::positive(f, 100.0);
    veh.dt = dn_fuzz::positive(f, 0.001);
    veh.x_static = f.ConsumeBool() ? 0.0 : pick(f, 0.05);
    veh.f_static = f.ConsumeBool() ? 0.0 : pick(f, 500.0);
    veh.temperature = f.ConsumeBool() ? 20.0 : pick(f, 50.0);
  }
  veh.integrator = dn_fuzz::small_int(f, 0, 1);
  veh.damper_eval = dn_fuzz::small_int(f, 0, 1);
  veh.accel_feature = dn_fuzz::small_int(f, 0, 2);

  dn_controller ctrl;
  dn_controller_default(&ctrl, dn_fuzz::small_int(f, 0, 5));
  if (f.ConsumeBool()) {
    double* fields[] = {&ctrl.u_passive, &ctrl.u_soft, &ctrl.u_hard, &ctrl.u_min, &ctrl.u_max,
                        &ctrl.c_sky,     &ctrl.c_gnd,  &ctrl.c_min,  &ctrl.c_max, &ctrl.u_tau_s};
    const int n = f.ConsumeIntegralInRange<int>(1, 10);
    for (int i = 0; i < n; ++i) *fields[f.ConsumeIntegralInRange<int>(0, 9)] = f.ConsumeBool() ? pick(f, 5.0) : dn_fuzz::value(f);
  } else if (f.ConsumeBool()) {
    ctrl.u_tau_s = dn_fuzz::positive(f, 0.005);
  }
  const bool null_ctrl = f.ConsumeIntegralInRange<int>(0, 15) == 0;

  dn_loop_model* m = nullptr;
  int st = dn_loop_model_create(&veh, buf.damper, null_ctrl ? nullptr : &ctrl, &m);
  if ((st == DN_OK) != (m != nullptr)) dn_fuzz::fail("*out NULL iff error", "dn_loop_model_create", st);
  // The loop model holds a copy: destroying the damper now must not matter.
  if (f.ConsumeBool()) {
    dn_damper_destroy(buf.damper);
    buf.damper = nullptr;
  }
  if (!m) return 0;
  dn_loop_data* d = nullptr;
  st = dn_loop_data_create(m, &d);
  if (st != DN_OK || !d) dn_fuzz::fail("data creation failed", "dn_loop_data_create", st);

  double before[DN_LOOP_STATE_SIZE], after[DN_LOOP_STATE_SIZE];
  if (f.ConsumeBool()) {  // an arbitrary state, as a replay or a test might set
    double s[DN_LOOP_STATE_SIZE];
    dn_loop_get_state(d, s);
    const double typical[DN_LOOP_STATE_SIZE] = {10, 0.1, 1, 0.1, 1, 0.05, 1, 5, 2000, 40, 1, 1, 5};
    for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i)
      if (f.ConsumeBool()) s[i] = pick(f, typical[i]);
    dn_loop_get_state(d, before);
    st = dn_loop_set_state(d, s);
    dn_loop_get_state(d, after);
    if (st == DN_OK) {
      if (std::memcmp(after, s, sizeof s) != 0) dn_fuzz::fail("state not set", "dn_loop_set_state", st);
    } else {
      if (st != DN_E_NONFINITE_INPUT) dn_fuzz::fail("unexpected error", "dn_loop_set_state", st);
      if (std::memcmp(after, before, sizeof before) != 0)
        dn_fuzz::fail("state changed by a refused set_state", "dn_loop_set_state", st);
    }
  }

  const int n_steps = f.ConsumeIntegralInRange<int>(1, 64);
  const double w = 2 * M_PI * f.ConsumeIntegralInRange<int>(1, 300) / 10.0;  // road frequency [rad/s]
  const double amp = f.ConsumeIntegralInRange<int>(0, 1000) / 10000.0;       // road amplitude [m]
  for (int k = 0; k < n_steps && f.remaining_bytes() > 0; ++k) {
    dn_loop_get_state(d, before);
    const double t = before[0] + veh.dt;
    dn_loop_input in;
    if (f.ConsumeBool()) {  // a smooth road most of the time
      in.z_r = amp * std::sin(w * t);
      in.v_r = amp * w * std::cos(w * t);
    } else {
      in.z_r = pick(f, 0.1);
      in.v_r = pick(f, 2.0);
    }
    in.u = pick(f, 5.0);
    dn_loop_out out;
    std::memset(&out, 0xFF, sizeof out);  // NaN everywhere: every field the step reports is written
    const bool fwd = f.ConsumeIntegralInRange<int>(0, 7) == 0;
    const bool want_out = f.ConsumeIntegralInRange<int>(0, 7) != 0;
    const char* call = fwd ? "dn_loop_forward" : "dn_loop_step";
    st = fwd ? dn_loop_forward(m, d, &in, want_out ? &out : nullptr)
             : dn_loop_step(m, d, &in, want_out ? &out : nullptr);
    dn_loop_get_state(d, after);
    if (st >= 0) {
      for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i)
        dn_fuzz::check_finite(after[i], "non-finite state after a successful step", call, st);
      if (want_out) check_out(out, call, st);
      if (fwd && std::memcmp(after, before, sizeof before) != 0)
        dn_fuzz::fail("dn_loop_forward changed the state", call, st);
      // a step taken leaves a state within the physical bounds (DN_PLAUSIBLE_LIST; set_state
      // may put one beyond them, and forward does not move it)
      if (!fwd && !(std::fabs(after[1] - after[3]) <= DN_PLAUSIBLE_TRAVEL_M &&
                    std::fabs(after[3] - after[5]) <= DN_PLAUSIBLE_WHEEL_ROAD_M &&
                    std::fabs(after[2] - after[4]) <= DN_PLAUSIBLE_DAMPER_SPEED_M_S))
        dn_fuzz::fail("a successful step left the physical bounds", call, st);
    } else {
      if (st != DN_E_NONFINITE_INPUT && st != DN_E_DIVERGED && st != DN_E_NONFINITE_OUTPUT)
        dn_fuzz::fail("unexpected error", call, st);
      if (std::memcmp(after, before, sizeof before) != 0)
        dn_fuzz::fail("state changed by a step that returned an error", call, st);
    }
  }
  if (dn_loop_step(m, d, nullptr, nullptr) != DN_E_NULL || dn_loop_step(nullptr, d, nullptr, nullptr) != DN_E_NULL)
    dn_fuzz::fail("NULL argument not refused", "dn_loop_step", 0);
  dn_loop_data_destroy(d);
  dn_loop_model_destroy(m);
  return 0;
}
