// The full vehicle through the C ABI: no heap allocation in its step and forward (every
// allocation entry point counted, alloc_counter.hpp) with four 3-30-1 neural dampers and
// skyhook in every damper_eval / accel_feature mode, the driver on a lane change, and a
// Magic-Formula tyre; nonsense parameters refused with their status code; a non-finite
// step input refused with the state unchanged; a runaway reported as DN_E_DIVERGED; tyre
// loads never negative when a wheel leaves the road. pytest runs it plain and under ASan.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <new>

#include "check.hpp"
#include "dampnet/dampnet.h"
#include "dn_model_default.h"

#include "alloc_counter.hpp"

namespace {

struct Car {
  dn_fullcar_model* m = nullptr;
  dn_fullcar_data* d = nullptr;
  ~Car() {
    dn_fullcar_data_destroy(d);
    dn_fullcar_model_destroy(m);
  }
};

// An ISO-3888-like lane change: 3.5 m over 30 m, back over 25 m.
const double kPathX[] = {-100, 15, 30, 45, 70, 95, 110, 125, 400};
const double kPathY[] = {0, 0, 1.75, 3.5, 3.5, 1.75, 0, 0, 0};

int create(Car& c, const dn_fullcar_params& p, dn_damper* const* dampers, const dn_controller* ctrls) {
  const bool driver = p.steer_mode == DN_STEER_DRIVER;
  const int st = dn_fullcar_model_create(&p, dampers, ctrls, driver ? kPathX : nullptr,
                                         driver ? kPathY : nullptr, driver ? 9 : 0, &c.m);
  if (st != DN_OK) return st;
  return dn_fullcar_data_create(c.m, &c.d);
}

}  // namespace

int main() {
  dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  dn_mlp* mlp = nullptr;
  CHECK(dn_mlp_create(&desc, &mlp) == DN_OK);
  dn_damper* neural[4] = {};
  for (auto& dp : neural)
    CHECK(dn_damper_create_neural(mlp, dn_model_default_feature_names, 3, nullptr, nullptr, 0,
                                  DN_PRECISION_DOUBLE, &dp) == DN_OK);
  dn_damper* lin[4] = {};
  for (auto& dp : lin) CHECK(dn_damper_create_linear(2500.0, &dp) == DN_OK);
  dn_controller sky[4];
  for (auto& c : sky) dn_controller_default(&c, DN_CTRL_SKYHOOK_ONOFF);

  // ---- no allocation: every eval x accel mode, open loop and driver ----
  CHECK(dn_alloc_counter_self_test(true) == 0);
  const int evals[2] = {DN_EVAL_PER_STAGE, DN_EVAL_PER_STEP};
  const int accels[3] = {DN_ACCEL_IMPLICIT, DN_ACCEL_LINEAR, DN_ACCEL_EXPLICIT};
  long steps = 0, errors = 0;
  double checksum = 0;
  for (int ev : evals)
    for (int am : accels)
      for (int mode = DN_STEER_OPEN_LOOP; mode <= DN_STEER_DRIVER; ++mode) {
        dn_fullcar_params p;
        dn_fullcar_default(&p);
        p.damper_eval = ev;
        p.accel_feature = am;
        p.steer_mode = mode;
        Car car;
        CHECK(create(car, p, neural, sky) == DN_OK);
        g_counting = true;
        for (int k = 1; k <= 4000; ++k) {  // 4 s at 1 ms: the lane change and a rough road
          const double t = k * 1e-3;
          dn_fullcar_input in{};
          for (int i = 0; i < 4; ++i) {
            const double ph = 0.7 * i;
            in.z_r[i] = 0.01 * std::sin(9.0 * t + ph) + 0.003 * std::sin(70.0 * t + 2 * ph);
            in.v_r[i] = 0.09 * std::cos(9.0 * t + ph) + 0.21 * std::cos(70.0 * t + 2 * ph);
          }
          in.steer = 0.03 * std::sin(2.0 * t);
          dn_fullcar_out out;
          const int st = k % 7 ? dn_fullcar_step(car.m, car.d, &in, &out)
                               : dn_fullcar_forward(car.m, car.d, &in, &out);
          if (st < 0) ++errors;
          checksum += out.force[0] + out.a_y;
          ++steps;
        }
        g_counting = false;
        double s[DN_FULLCAR_STATE_SIZE];
        CHECK(dn_fullcar_get_state(car.d, s) == DN_OK);
        for (double x : s) CHECK(std::isfinite(x));
        if (mode == DN_STEER_DRIVER) CHECK(std::fabs(s[11] - 0.0) < 1.0);  // back in lane: Y ~ 0
      }
  std::printf("full car: allocations during %ld steps: %ld, errors %ld (checksum %g)\n", steps,
              g_allocs, errors, checksum);
  CHECK(g_allocs == 0);
  CHECK(errors == 0);
  CHECK(std::isfinite(checksum));

  // ---- nonsense parameters: each refused with its status ----
  {
    struct Bad {
      const char* what;
      void (*set)(dn_fullcar_params&);
      int status;
    };
    const Bad bad[] = {
        {"m_s = 0", [](dn_fullcar_params& p) { p.m_s = 0; }, DN_E_PARAM},
        {"m_s = NaN", [](dn_fullcar_params& p) { p.m_s = NAN; }, DN_E_NONFINITE_PARAM},
        {"i_xx < 0", [](dn_fullcar_params& p) { p.i_xx = -1; }, DN_E_PARAM},
        {"a = 0", [](dn_fullcar_params& p) { p.a = 0; }, DN_E_PARAM},
        {"t_r = -1", [](dn_fullcar_params& p) { p.t_r = -1; }, DN_E_PARAM},
        {"h_rc_f >= h_cg", [](dn_fullcar_params& p) { p.h_rc_f = p.h_cg; }, DN_E_PARAM},
        {"k_s_f < 0", [](dn_fullcar_params& p) { p.k_s_f = -1; }, DN_E_PARAM},
        {"k_arb_r < 0", [](dn_fullcar_params& p) { p.k_arb_r = -1; }, DN_E_PARAM},
        {"k_t = 0", [](dn_fullcar_params& p) { p.k_t = 0; }, DN_E_PARAM},
        {"tyre_c = 3", [](dn_fullcar_params& p) { p.tyre_c = 3; }, DN_E_PARAM},
        {"tyre_pdy2 = 1", [](dn_fullcar_params& p) { p.tyre_pdy2 = 1; }, DN_E_PARAM},
        {"speed < 0", [](dn_fullcar_params& p) { p.speed = -1; }, DN_E_PARAM},
        {"speed = Inf", [](dn_fullcar_params& p) { p.speed = INFINITY; }, DN_E_NONFINITE_PARAM},
        {"dt = 0", [](dn_fullcar_params& p) { p.dt = 0; }, DN_E_PARAM},
        {"tyre_model = 7", [](dn_fullcar_params& p) { p.tyre_model = 7; }, DN_E_PARAM},
        {"steer_mode = -1", [](dn_fullcar_params& p) { p.steer_mode = -1; }, DN_E_PARAM},
        {"accel_feature = 9", [](dn_fullcar_params& p) { p.accel_feature = 9; }, DN_E_PARAM},
        {"driver_tau_s < 0", [](dn_fullcar_params& p) { p.driver_tau_s = -0.1; }, DN_E_PARAM},
        {"driver_rate_max = 0", [](dn_fullcar_params& p) { p.driver_rate_max = 0; }, DN_E_PARAM},
        {"m_us_r subnormal", [](dn_fullcar_params& p) { p.m_us_r = 1e-320; }, DN_E_PARAM},
    };
    for (const Bad& b : bad) {
      dn_fullcar_params p;
      dn_fullcar_default(&p);
      CHECK(dn_fullcar_check(&p) == DN_OK);
      b.set(p);
      const int st = dn_fullcar_check(&p);
      if (st != b.status) std::printf("  %s: status %d, expected %d\n", b.what, st, b.status);
      CHECK(st == b.status);
      dn_fullcar_model* m = nullptr;
      CHECK(dn_fullcar_model_create(&p, lin, nullptr, nullptr, nullptr, 0, &m) == b.status);
      CHECK(m == nullptr);
    }
    dn_fullcar_params p;
    dn_fullcar_default(&p);
    dn_fullcar_model* m = nullptr;
    p.steer_mode = DN_STEER_DRIVER;  // the driver without a path
    CHECK(dn_fullcar_model_create(&p, lin, nullptr, nullptr, nullptr, 0, &m) == DN_E_PARAM);
    const double px[] = {0, 0}, py[] = {0, 1};  // not increasing
    CHECK(dn_fullcar_model_create(&p, lin, nullptr, px, py, 2, &m) == DN_E_PARAM);
    dn_damper* three[4] = {lin[0], lin[1], lin[2], nullptr};
    p.steer_mode = DN_STEER_OPEN_LOOP;
    CHECK(dn_fullcar_model_create(&p, three, nullptr, nullptr, nullptr, 0, &m) == DN_E_NULL);
    CHECK(dn_fullcar_check(nullptr) == DN_E_NULL);
    dn_controller badc = sky[0];
    badc.u_min = 6;  // > u_max
    dn_controller cs[4] = {sky[0], sky[1], badc, sky[3]};
    CHECK(dn_fullcar_model_create(&p, lin, cs, nullptr, nullptr, 0, &m) == DN_E_PARAM);
  }

  // ---- non-finite inputs: refused, state unchanged; runaway: diverged ----
  {
    dn_fullcar_params p;
    dn_fullcar_default(&p);
    Car car;
    CHECK(create(car, p, lin, nullptr) == DN_OK);
    double s0[DN_FULLCAR_STATE_SIZE], s1[DN_FULLCAR_STATE_SIZE];
    dn_fullcar_input ok{};
    CHECK(dn_fullcar_step(car.m, car.d, &ok, nullptr) >= 0);
    CHECK(dn_fullcar_get_state(car.d, s0) == DN_OK);
    for (int which = 0; which < 3; ++which) {
      dn_fullcar_input in{};
      if (which == 0) in.z_r[2] = NAN;
      if (which == 1) in.v_r[3] = INFINITY;
      if (which == 2) in.steer = NAN;
      CHECK(dn_fullcar_step(car.m, car.d, &in, nullptr) == DN_E_NONFINITE_INPUT);
      CHECK(dn_fullcar_get_state(car.d, s1) == DN_OK);
      CHECK(std::memcmp(s0, s1, sizeof s0) == 0);
    }
    double s[DN_FULLCAR_STATE_SIZE];
    std::memcpy(s, s0, sizeof s);
    s[DN_FULLCAR_STATE_SIZE - 1] = NAN;
    CHECK(dn_fullcar_set_state(car.d, s) == DN_E_NONFINITE_INPUT);
    s[DN_FULLCAR_STATE_SIZE - 1] = 20.0;
    s[2] = 1e308;  // a runaway heave velocity: the RK4 sum overflows
    CHECK(dn_fullcar_set_state(car.d, s) == DN_OK);
    int st = DN_OK;
    for (int k = 0; k < 10 && st >= 0; ++k) st = dn_fullcar_step(car.m, car.d, &ok, nullptr);
    CHECK(st == DN_E_DIVERGED);
  }

  // ---- lift-off: a 0.3 m step under the front left wheel throws the car; loads >= 0 ----
  {
    dn_fullcar_params p;
    dn_fullcar_default(&p);
    Car car;
    CHECK(create(car, p, lin, nullptr) == DN_OK);
    double min_load = 1e9;
    int airborne = 0;
    for (int k = 1; k <= 2000; ++k) {
      dn_fullcar_input in{};
      in.z_r[0] = k >= 100 && k < 140 ? 0.15 : 0.0;  // a 40 ms, 15 cm bump
      dn_fullcar_out out;
      CHECK(dn_fullcar_step(car.m, car.d, &in, &out) >= 0);
      for (double n : out.tyre_load) {
        if (n < min_load) min_load = n;
        if (n == 0.0) ++airborne;
      }
    }
    std::printf("lift-off: smallest tyre load %g N, wheel-steps airborne %d\n", min_load, airborne);
    CHECK(min_load >= 0.0);
    CHECK(airborne > 0);  // the bump does lift a wheel (else this case tests nothing)
  }

  for (auto* dp : neural) dn_damper_destroy(dp);
  for (auto* dp : lin) dn_damper_destroy(dp);
  dn_mlp_destroy(mlp);
  TEST_MAIN_RETURN();
}
