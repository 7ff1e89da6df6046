// No heap allocation in forward: every allocation entry point is counted while
// a million forward calls run (alloc_counter.hpp: interposed in the plain build, the
// sanitizer's allocation hook under ASan; pytest runs both builds).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <random>
#include <vector>

#include "check.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/mlp.hpp"
#include "random_model.hpp"

#include "alloc_counter.hpp"

int main() {
  RandomModel rm(3, 30, 0, DN_ACT_SIGMOID, 1);
  RandomModel rm2(4, 16, 16, DN_ACT_TANH, 2);
  dn_mlp* cm = nullptr;
  CHECK(dn_mlp_create(&rm.desc, &cm) == DN_OK);
  auto* md = new dampnet::Mlp<double>;
  auto* sf = new dampnet::StaticMlp<float, 4, 16, 16>;
  CHECK(md->load(&rm.desc) == DN_OK);
  CHECK(sf->load(&rm2.desc) == DN_OK);

  // The counter sees every allocation entry point (else this test could not fail).
  CHECK(dn_alloc_counter_self_test(false) == 0);

  double x[3] = {0.1, -0.2, 0.3}, y = 0, acc = 0;
  float xf[4] = {0.1f, 0.2f, 0.3f, 0.4f}, yf = 0, ycf = 0;
  g_counting = true;
  for (int k = 0; k < 1000000; ++k) {
    x[0] = 1e-6 * k;
    md->forward(x, &y);
    acc += y;
    sf->forward(xf, &yf);
    dn_mlp_forward(cm, x, &y, nullptr);
    dn_mlp_forward_f(cm, xf, &ycf, nullptr);
  }
  g_counting = false;
  std::printf("allocations during 4e6 forward calls: %ld (checksum %g)\n", g_allocs, acc);
  CHECK(g_allocs == 0);

  // The damper's inverse (dn_damper_inverse, dn_damper_inverse_near): its bracket, Newton and
  // bisection steps, float and double, reachable, unreachable and non-finite demands.
  const char* names[3] = {"velocity", "acceleration", "voltage"};
  dn_damper* dd = nullptr;
  dn_damper* dfl = nullptr;
  CHECK(dn_damper_create_neural(cm, names, 3, nullptr, nullptr, 0, DN_PRECISION_DOUBLE, &dd) == DN_OK);
  CHECK(dn_damper_create_neural(cm, names, 3, nullptr, nullptr, 0, DN_PRECISION_FLOAT, &dfl) == DN_OK);
  dn_damper_input in{};
  int n_bad = 0;
  g_counting = true;
  for (int k = 0; k < 200000; ++k) {
    in.v = 1e-5 * (k % 1000) - 0.005;
    in.a = 1e-3 * (k % 77);
    in.u = 0;
    dn_real f_mid = 0, u = 0, f = 0;
    in.u = 0.5;
    dn_damper_force(dd, &in, &f_mid, nullptr);
    const dn_real demand = (k % 5 == 0) ? 1e9 : (k % 7 == 0 ? std::nan("") : f_mid);
    const int st = dn_damper_inverse((k & 1) ? dd : dfl, &in, demand, &u, &f, nullptr);
    if (!std::isfinite(u) || !std::isfinite(f) || (st < 0 && st != DN_E_NONFINITE_INPUT)) ++n_bad;
    acc += u;
    // and from a start (dn_damper_inverse_near): its warm Newton steps, a start at a limit
    const dn_real start = (k % 3 == 0) ? 0.0 : 0.45 + 1e-4 * (k % 100);
    const int st_near = dn_damper_inverse_near((k & 2) ? dd : dfl, &in, demand, start, &u, &f, nullptr);
    if (!std::isfinite(u) || !std::isfinite(f) || (st_near < 0 && st_near != DN_E_NONFINITE_INPUT)) ++n_bad;
    acc += u;
  }
  g_counting = false;
  std::printf("allocations during 2e5 inverse calls: %ld (non-finite or failed: %d)\n", g_allocs, n_bad);
  CHECK(g_allocs == 0);
  CHECK(n_bad == 0);

  // The quarter car's step with the force-tracking laws (each step's inverse), float and double.
  for (int kind = DN_CTRL_SKYHOOK_FORCE; kind <= DN_CTRL_CLIPPED_OPTIMAL; ++kind) {
    for (dn_damper* dmp : {dd, dfl}) {
      dn_vehicle veh;
      dn_vehicle_default(&veh);
      dn_controller ctrl;
      dn_controller_default(&ctrl, kind);
      ctrl.k_travel = -13000, ctrl.k_vs = 1400, ctrl.k_tyre = 500, ctrl.k_vus = -200;
      dn_loop_model* lm = nullptr;
      dn_loop_data* ld = nullptr;
      CHECK(dn_loop_model_create(&veh, dmp, &ctrl, &lm) == DN_OK);
      CHECK(dn_loop_data_create(lm, &ld) == DN_OK);
      g_counting = true;
      int n_fail = 0;
      for (int k = 0; k < 20000; ++k) {
        const double t = 1e-3 * k;
        dn_loop_input li = {0.01 * std::sin(9.0 * t), 0.09 * std::cos(9.0 * t), 0.0};
        dn_loop_out out;
        // a random model may run the car away (DN_E_DIVERGED): start again from rest
        const int st = dn_loop_step(lm, ld, &li, &out);
        if (st >= 0 && !std::isfinite(out.u)) ++n_fail;
        if (st < 0) dn_loop_reset(lm, ld);
      }
      g_counting = false;
      std::printf("allocations during 2e4 steps of law %d: %ld (failed: %d)\n", kind, g_allocs, n_fail);
      CHECK(g_allocs == 0);
      CHECK(n_fail == 0);
      dn_loop_data_destroy(ld);
      dn_loop_model_destroy(lm);
    }
  }
  dn_damper_destroy(dd);
  dn_damper_destroy(dfl);
  dn_mlp_destroy(cm);
  delete md;
  delete sf;
  TEST_MAIN_RETURN();
}
