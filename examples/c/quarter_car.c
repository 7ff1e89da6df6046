/* The quarter-car loop through dampnet's C ABI (dampnet.h): the default neural
 * damper model (the generated header dn_model_default.h), on-off skyhook with a
 * 5 ms command filter, the thesis's Table 5 vehicle, RK4 at 1 ms, on a
 * deterministic two-tone road, for 3000 steps.
 *
 * examples/cpp/quarter_car.cpp and examples/python/quarter_car.py run the same
 * configuration and print the same "result" line (tests/python/test_examples.py
 * checks that they agree). Build against an installed dampnet with
 * examples/CMakeLists.txt, or by hand:
 *   cc -std=c99 -I<prefix>/include quarter_car.c <prefix>/lib/libdampnet.a -lstdc++ -lm
 */
#include <math.h>
#include <stdio.h>

#include <dampnet/dampnet.h>
#include <dn_model_default.h> /* installed beside dampnet/; `dampnet train` writes model.h */

#define N_STEPS 3000
#define DT_S 0.001
static const double kPi = 3.14159265358979323846;

/* The road at time t [s]: two raised-cosine tones, 3 cm peak to peak at 1.2 Hz and
 * 6 mm at 9 Hz (the body's and the wheel's resonances are at 0.7 Hz and 12 Hz).
 * It starts at rest (z = 0, dz/dt = 0), which is where dn_loop_reset puts the road. */
static void road(double t, double* z, double* rate) {
  const double a1 = 0.015, w1 = 2 * kPi * 1.2, a2 = 0.002, w2 = 2 * kPi * 6.0;
  *z = a1 * (1 - cos(w1 * t)) + a2 * (1 - cos(w2 * t));      /* [m] */
  *rate = a1 * w1 * sin(w1 * t) + a2 * w2 * sin(w2 * t);     /* [m/s] */
}

static int fail(const char* what, int st) {
  fprintf(stderr, "quarter_car: %s: %s\n", what, dn_status_str(st));
  return 1;
}

int main(void) {
  /* Set-up (allocates): the MLP, a neural damper on its named features, the loop. */
  dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  dn_mlp* mlp = NULL;
  dn_damper* damper = NULL;
  dn_loop_model* model = NULL;
  dn_loop_data* data = NULL;
  int st = dn_mlp_create(&desc, &mlp);
  if (st != DN_OK) return fail("dn_mlp_create", st);
  /* The default model has no derived features (no feature parameters) and no terms;
   * python/dampnet/demo/controller.c shows a model that has them. */
  st = dn_damper_create_neural(mlp, dn_model_default_feature_names, DN_MODEL_DEFAULT_N_INPUTS,
                               NULL, NULL, 0, DN_PRECISION_DOUBLE, &damper);
  if (st != DN_OK) return fail("dn_damper_create_neural", st);

  dn_vehicle veh;
  dn_vehicle_default(&veh); /* Table 5: 700 kg, 40 kg, 15 kN/m, 200 kN/m; RK4, dt 1 ms */
  veh.dt = DT_S;
  /* The HIL configuration `dampnet bench` times would be: veh.damper_eval =
   * DN_EVAL_PER_STEP, veh.accel_feature = DN_ACCEL_LINEAR, DN_PRECISION_FLOAT above. */
  dn_controller ctrl;
  dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF); /* soft 5 V, hard 0 V */
  ctrl.u_tau_s = 0.005;                                /* 5 ms command filter */
  st = dn_loop_model_create(&veh, damper, &ctrl, &model); /* copies the damper */
  if (st != DN_OK) return fail("dn_loop_model_create", st);
  st = dn_loop_data_create(model, &data); /* at rest */
  if (st != DN_OK) return fail("dn_loop_data_create", st);

  /* The loop (real time: no allocation, bounded, finite). The input is the road at
   * the END of the step; the report is at its start. */
  double sum_acc2 = 0.0, max_force = 0.0;
  int n_saturated = 0, n_unconverged = 0; /* steps with these warnings */
  for (int k = 0; k < N_STEPS; ++k) {
    dn_loop_input in = {0.0, 0.0, 0.0};
    dn_loop_out out;
    road((k + 1) * DT_S, &in.z_r, &in.v_r);
    st = dn_loop_step(model, data, &in, &out);
    if (st < 0) return fail("dn_loop_step", st);
    if (st & DN_W_SATURATED) ++n_saturated;         /* an MLP input was clamped */
    if (st & DN_W_ACCEL_UNCONVERGED) ++n_unconverged; /* implicit a: best of 6 used */
    sum_acc2 += out.acc_s * out.acc_s;
    if (fabs(out.force) > max_force) max_force = fabs(out.force);
  }

  double s[DN_LOOP_STATE_SIZE];
  dn_loop_get_state(data, s); /* DN_LOOP_STATE_LIST order: t, z_s, v_s, z_us, v_us, ... */
  printf("dampnet %s, C ABI: default model, skyhook on-off, %d steps of %g s\n",
         dn_version_string(), N_STEPS, DT_S);
  printf("result t=%.12g z_s=%.12g v_s=%.12g z_us=%.12g v_us=%.12g acc_s_rms=%.12g "
         "force_max=%.12g saturated=%d unconverged=%d\n",
         s[0], s[1], s[2], s[3], s[4], sqrt(sum_acc2 / N_STEPS), max_force, n_saturated, n_unconverged);

  dn_loop_data_destroy(data);
  dn_loop_model_destroy(model);
  dn_damper_destroy(damper);
  dn_mlp_destroy(mlp);
  return 0;
}
