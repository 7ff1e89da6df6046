// The loop's C++ API: one RK4 step of a free quarter car against its analytic
// solution, seeded property tests (any finite or non-finite input gives a finite
// state or a documented error with the state unchanged; energy decays with no
// road), reset and state round trips, and the damper/term tables.
#include <cmath>
#include <cstring>
#include <random>

#include "check.hpp"
#include "dampnet/loop.hpp"
#include "random_model.hpp"

using namespace dampnet;

static double energy(const LoopModel& m, const double* s) {
  const dn_vehicle& v = m.veh;
  const double x = s[S_z_s] - s[S_z_us], zt = s[S_z_us] - s[S_z_r];
  return 0.5 * v.m_s * s[S_v_s] * s[S_v_s] + 0.5 * v.m_us * s[S_v_us] * s[S_v_us] +
         0.5 * v.k_s * x * x + 0.5 * v.k_t * zt * zt;
}

int main(int argc, char** argv) {
  const int n_cases = argc > 1 ? std::atoi(argv[1]) : 300;
  std::mt19937 rng(42);

  // Undamped, untyred single mass: c = 0 and a rigid road (huge k_t) is not
  // needed; instead check RK4's known local error on a free sprung-mass
  // oscillation over one step (k_t large keeps the wheel nearly fixed).
  {
    LoopModel m;
    Damper d;
    CHECK(d.set_linear(0.0) == DN_OK);
    dn_vehicle v = default_vehicle();
    CHECK(m.init(v, d, default_controller()) == DN_OK);
    LoopData ld;
    reset(m, ld);
    ld.s[S_z_s] = 0.01;
    // energy is conserved by the exact flow; RK4 loses O(h^6) per step
    const double e0 = energy(m, ld.s);
    dn_loop_input in{0, 0, 0};
    for (int k = 0; k < 10000; ++k) CHECK(step(m, ld, in, nullptr) == DN_OK);
    const double e1 = energy(m, ld.s);
    std::printf("undamped energy drift over 10 s: %.3g (relative)\n", (e0 - e1) / e0);
    CHECK(std::fabs(e0 - e1) / e0 < 1e-4);
    CHECK(std::fabs(ld.s[S_t] - 10.0) < 1e-9);
  }

  // Damped, no road: energy never increases (passive dampers only dissipate).
  {
    LoopModel m;
    Damper d;
    dn_parametric_params p{400, 3500, 1800, 40, 5, 0.01};
    CHECK(d.set_parametric(&p) == DN_OK);
    CHECK(m.init(default_vehicle(), d, default_controller(DN_CTRL_SKYHOOK_ONOFF)) == DN_OK);
    LoopData ld;
    reset(m, ld);
    ld.s[S_z_s] = 0.05;
    ld.s[S_v_us] = -1.0;
    double e = energy(m, ld.s);
    dn_loop_input in{0, 0, 0};
    int rises = 0;
    for (int k = 0; k < 5000; ++k) {
      CHECK(step(m, ld, in, nullptr) >= 0);
      const double e1 = energy(m, ld.s);
      if (e1 > e * (1 + 1e-9) + 1e-12) ++rises;
      e = e1;
    }
    CHECK(rises == 0);
    CHECK(e < 1e-3);
  }

  // Property test: random vehicles, dampers and inputs (some absurd).
  RandomModel rm(3, 30, 0, DN_ACT_SIGMOID, 7);
  Damper neural;
  CHECK(neural.md.load(&rm.desc) == DN_OK);
  CHECK(neural.mf.load(&rm.desc) == DN_OK);
  const char* feats[] = {"velocity", "acceleration", "voltage"};
  CHECK(neural.set_neural_features(feats, 3, nullptr, nullptr, 0, DN_PRECISION_FLOAT) == DN_OK);
  CHECK(neural.out_bound_f > 0.0f && neural.out_bound_f == neural.mf.out_bound());  // (the inverse's rounding scale)
  const double gas[] = {-150, 3000, 0, 0};
  CHECK(neural.add_term("position_poly", gas, 4) == DN_OK);
  std::uniform_real_distribution<double> u01(0, 1);
  const double weird[] = {NAN, INFINITY, -INFINITY, 1e308, -1e308, 0.0, 1e-310};
  int errors = 0, ok = 0;
  for (int c = 0; c < n_cases; ++c) {
    dn_vehicle v = default_vehicle();
    v.m_s = 100 + 1000 * u01(rng);
    v.m_us = 10 + 80 * u01(rng);
    v.dt = 1e-4 + 4e-3 * u01(rng);
    v.integrator = c % 2;
    v.damper_eval = (c / 2) % 2;
    LoopModel m;
    dn_controller ctrl = default_controller(c % 6);
    ctrl.u_tau_s = c % 3 == 0 ? 0.0 : 0.02 * u01(rng);  // with and without the command filter
    CHECK(m.init(v, neural, ctrl) == DN_OK);
    LoopData ld;
    reset(m, ld);
    for (int k = 0; k < 200; ++k) {
      dn_loop_input in{0.05 * std::sin(0.1 * k), 0.0, 5 * u01(rng)};
      if (k % 37 == 5) in.z_r = weird[(k / 37 + c) % 7];
      if (k % 41 == 7) in.u = weird[(k / 41 + c) % 7];
      double before[DN_LOOP_STATE_SIZE];
      std::memcpy(before, ld.s, sizeof before);
      dn_loop_out out;
      const int st = step(m, ld, in, &out);
      if (st < 0) {
        ++errors;
        CHECK(std::memcmp(before, ld.s, sizeof before) == 0);
        // the caller's NaN/Inf is an input error; finite inputs that overflow (1e308) diverge
        const bool bad_input = !std::isfinite(in.z_r) || !std::isfinite(in.v_r) ||
                               (ctrl.kind == DN_CTRL_EXTERNAL && !std::isfinite(in.u));
        CHECK(st == (bad_input ? DN_E_NONFINITE_INPUT : DN_E_DIVERGED));
      } else {
        ++ok;
        for (double x : ld.s) CHECK(std::isfinite(x));
        CHECK(std::isfinite(out.force) && std::isfinite(out.u) && std::isfinite(out.a));
        CHECK(out.u >= ctrl.u_min && out.u <= ctrl.u_max);
      }
    }
  }
  std::printf("property test: %d steps ok, %d refused\n", ok, errors);

  // Invalid models.
  {
    LoopModel m;
    Damper d;
    CHECK(d.set_linear(1000) == DN_OK);
    dn_vehicle v = default_vehicle();
    v.m_s = -1;
    CHECK(m.init(v, d, default_controller()) == DN_E_PARAM);
    v = default_vehicle();
    v.dt = NAN;
    CHECK(m.init(v, d, default_controller()) == DN_E_NONFINITE_PARAM);
    v = default_vehicle();
    v.dt = -1e-3;
    CHECK(m.init(v, d, default_controller()) == DN_E_PARAM);
    for (double tiny : {1e-320, 4.9e-324, 1e-12}) {  // absurd steps: refused, not run
      v.dt = tiny;
      CHECK(m.init(v, d, default_controller()) == DN_E_PARAM);
    }
    v.dt = 1e-9;
    CHECK(m.init(v, d, default_controller()) == DN_OK);
    dn_controller c = default_controller(DN_CTRL_SKYHOOK_CONTINUOUS);
    c.c_max = c.c_min;
    CHECK(m.init(default_vehicle(), d, c) == DN_E_PARAM);
    CHECK(d.add_term("bump_stop", gas, 4) == DN_E_SIZE);
    CHECK(d.add_term("nope", gas, 4) == DN_E_UNKNOWN_NAME);
  }

  // The term and feature tables: names, counts.
  CHECK(terms::kind_of("position_poly") == DN_TERM_POSITION_POLY);
  CHECK(terms::kind_of("bump_stop") == DN_TERM_BUMP_STOP);
  CHECK(features::id_of("voltage_lag") == DN_FEAT_VOLTAGE_LAG);
  CHECK(features::id_of("speed") == -1);
  TEST_MAIN_RETURN();
}
