// No heap allocation in the loop's step: every allocation entry point is counted
// (alloc_counter.hpp) while many steps run with every damper kind and controller
// (neural float and double with terms, parametric, table, linear; RK4 per stage/per
// step and semi-implicit Euler; for the dampers reading the acceleration every
// accel_feature mode), through the C ABI. pytest runs it plain and under ASan.
#include <cmath>
#include <cstdlib>
#include <new>
#include <vector>

#include "check.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/loop.hpp"
#include "dn_model_default.h"
#include "random_model.hpp"

#include "alloc_counter.hpp"

int main() {
  using namespace dampnet;
  // the default (trained) model on velocity, acceleration, voltage; and a random
  // one on the lagged control, displacement, temperature and the motion-derived
  // velocity_lag and friction_state (a random network
  // is not dissipative, so it does not get the acceleration input here)
  dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  dn_mlp* mlp_default = nullptr;
  CHECK(dn_mlp_create(&desc, &mlp_default) == DN_OK);
  RandomModel rm(6, 30, 0, DN_ACT_TANH, 3);
  rm.desc.out_offset = -200.0;
  rm.desc.out_gain = 2.0 / 400.0;
  dn_mlp* mlp = nullptr;
  CHECK(dn_mlp_create(&rm.desc, &mlp) == DN_OK);
  const char* feats[] = {"velocity",    "voltage_lag",  "displacement",
                         "temperature", "velocity_lag", "friction_state"};
  const char* pn[] = {"control_lag_tau_s", "velocity_lag_tau_s", "friction_presliding_m"};
  const double pv[] = {0.03, 0.004, 5e-4};
  const double gas[] = {-150.0, 3000.0, 1e4, 0.0}, bump[] = {0.05, 2e6, 1.5};
  dn_parametric_params par{400, 3500, 1800, 40, 5, 0.01};
  const double tv[] = {-1, -0.2, 0, 0.2, 1}, tu[] = {0, 5};
  const double tf[] = {-3000, -900, 0, 1000, 3500, -800, -300, 0, 400, 1200};

  std::vector<dn_damper*> dampers(6, nullptr);
  CHECK(dn_damper_create_neural(mlp_default, dn_model_default_feature_names, 3, nullptr, nullptr,
                                0, DN_PRECISION_FLOAT, &dampers[0]) == DN_OK);
  CHECK(dn_damper_create_neural(mlp, feats, 6, pn, pv, 3, DN_PRECISION_DOUBLE, &dampers[1]) == DN_OK);
  CHECK(dn_damper_create_neural(mlp_default, dn_model_default_feature_names, 3, nullptr, nullptr,
                                0, DN_PRECISION_DOUBLE, &dampers[5]) == DN_OK);
  CHECK(dn_damper_create_parametric(&par, &dampers[2]) == DN_OK);
  CHECK(dn_damper_create_table(tv, 5, tu, 2, tf, &dampers[3]) == DN_OK);
  CHECK(dn_damper_create_linear(1500, &dampers[4]) == DN_OK);
  for (int i : {0, 1, 5}) CHECK(dn_damper_add_term(dampers[i], "position_poly", gas, 4) == DN_OK);
  // a stiff bump stop only where the damper dissipates (the trained model): held over
  // a step (DN_EVAL_PER_STEP) a stiff position force is explicit and can pump energy
  for (int i : {0, 5}) CHECK(dn_damper_add_term(dampers[i], "bump_stop", bump, 3) == DN_OK);

  // The counter sees every allocation entry point (else this test could not fail).
  CHECK(dn_alloc_counter_self_test(true) == 0);

  long steps = 0;
  int first_fail[4] = {0, 0, 0, 0};
  double checksum = 0;
  const int integrators[3][2] = {{DN_INT_RK4, DN_EVAL_PER_STAGE},
                                 {DN_INT_RK4, DN_EVAL_PER_STEP},
                                 {DN_INT_SEMI_EULER, DN_EVAL_PER_STAGE}};
  // every accel_feature mode for the dampers that read the acceleration (the default
  // model's): the implicit solve, the linearised HIL scheme and the explicit one
  const int kSteps = 12000;  // per case: 180 cases, 2.16e6 steps
  const int accel_modes[3] = {DN_ACCEL_IMPLICIT, DN_ACCEL_LINEAR, DN_ACCEL_EXPLICIT};
  long accel_steps[3] = {0, 0, 0};
  for (dn_damper*& dp : dampers) {
    const bool reads_a = dp == dampers[0] || dp == dampers[5];
    for (int am = 0; am < (reads_a ? 3 : 1); ++am)
    for (auto& ig : integrators) {
      for (int kind = DN_CTRL_PASSIVE; kind <= DN_CTRL_EXTERNAL; ++kind) {
        dn_vehicle veh;
        dn_vehicle_default(&veh);
        veh.integrator = ig[0];
        veh.damper_eval = ig[1];
        veh.accel_feature = accel_modes[am];
        if (reads_a) accel_steps[am] += kSteps;
        dn_controller ctrl;
        dn_controller_default(&ctrl, kind);
        ctrl.u_tau_s = ig[1] == DN_EVAL_PER_STEP ? 0.005 : 0.0;  // the command filter's path too
        dn_loop_model* m = nullptr;
        dn_loop_data* d = nullptr;
        CHECK(dn_loop_model_create(&veh, dp, &ctrl, &m) == DN_OK);
        CHECK(dn_loop_data_create(m, &d) == DN_OK);
        g_counting = true;
        for (int k = 1; k <= kSteps; ++k) {
          const double t = k * 1e-3;
          dn_loop_input in{0.03 * std::sin(9.0 * t) + 0.005 * std::sin(70.0 * t),
                           0.27 * std::cos(9.0 * t) + 0.35 * std::cos(70.0 * t),
                           2.5 + 2.5 * std::sin(3.0 * t)};
          dn_loop_out out;
          const int st = dn_loop_step(m, d, &in, &out);
          if (st < 0) {  // also fail on an error: none expected here
            ++g_allocs;
            if (!first_fail[0]) {
              first_fail[0] = 1;
              first_fail[1] = dn_damper_kind_of(dp) * 1000 + (int)(&dp - dampers.data()) * 100 +
                              ig[0] * 20 + ig[1] * 10 + kind;
              first_fail[2] = k;
              first_fail[3] = st;
            }
          }
          checksum += out.force;
          ++steps;
        }
        g_counting = false;
        dn_loop_data_destroy(d);
        dn_loop_model_destroy(m);
      }
    }
  }
  std::printf("allocations (or errors) during %ld loop steps: %ld (checksum %g)\n", steps, g_allocs,
              checksum);
  if (first_fail[0])
    std::printf("first error: case %d (kind*1000 + damper*100 + integrator*20 + eval*10 + law), "
                "step %d, status %d\n", first_fail[1], first_fail[2], first_fail[3]);
  std::printf("steps per accel_feature mode (implicit, linear, explicit): %ld %ld %ld\n",
              accel_steps[0], accel_steps[1], accel_steps[2]);
  CHECK(g_allocs == 0);
  CHECK(accel_steps[0] > 0 && accel_steps[1] == accel_steps[0] && accel_steps[2] == accel_steps[0]);
  CHECK(std::isfinite(checksum));
  for (dn_damper* dp : dampers) dn_damper_destroy(dp);
  dn_mlp_destroy(mlp);
  dn_mlp_destroy(mlp_default);
  TEST_MAIN_RETURN();
}
