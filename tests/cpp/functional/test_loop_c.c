/* A plain C99 program running the quarter-car loop over a road through the C ABI:
 * a hybrid neural damper (the default model's generated header, plus a gas term)
 * with skyhook control, and the parametric and table dampers; checks statuses,
 * refusals and finiteness. With a file argument (lines "z_r v_r") it runs that
 * road with the model given by the remaining arguments and prints one line per
 * sample (state and report) for the Python front-door test. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dampnet/dampnet.h"
#include "dn_model_default.h"

#include "expect.h"

#define k_features dn_model_default_feature_names

static dn_damper* make_damper(const char* which) {
  dn_damper* d = NULL;
  if (strcmp(which, "parametric") == 0) {
    dn_parametric_params p = {400.0, 3500.0, 1800.0, 40.0, 5.0, 0.0};
    EXPECT(dn_damper_create_parametric(&p, &d) == DN_OK);
  } else if (strcmp(which, "table") == 0) {
    const double v[5] = {-1.0, -0.2, 0.0, 0.2, 1.0};
    const double u[2] = {0.0, 5.0};
    const double f[10] = {-3000, -900, 0, 1000, 3500, -800, -300, 0, 400, 1200};
    EXPECT(dn_damper_create_table(v, 5, u, 2, f, &d) == DN_OK);
  } else {
    dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
    dn_mlp* mlp = NULL;
    const double gas[4] = {-150.0, 3000.0, 0.0, 0.0};
    EXPECT(dn_mlp_create(&desc, &mlp) == DN_OK);
    EXPECT(dn_damper_create_neural(mlp, k_features, 3, NULL, NULL, 0,
                                   strcmp(which, "neural_f") == 0 ? DN_PRECISION_FLOAT
                                                                  : DN_PRECISION_DOUBLE,
                                   &d) == DN_OK);
    EXPECT(dn_damper_add_term(d, "position_poly", gas, 4) == DN_OK);
    dn_mlp_destroy(mlp);
  }
  return d;
}

static double road_at(int k, double dt, double* rate) {
  double t = k * dt, w1 = 2 * 3.14159265358979 * 1.3, w2 = 2 * 3.14159265358979 * 7.1;
  *rate = 0.02 * w1 * cos(w1 * t) + 0.004 * w2 * cos(w2 * t + 1.0);
  return 0.02 * sin(w1 * t) + 0.004 * sin(w2 * t + 1.0);
}

static int run_file(int argc, char** argv) {
  FILE* f = fopen(argv[1], "r");
  const char* which = argc > 2 ? argv[2] : "neural";
  int kind = argc > 3 ? atoi(argv[3]) : DN_CTRL_SKYHOOK_ONOFF;
  dn_vehicle veh;
  dn_controller ctrl;
  dn_damper* d;
  dn_loop_model* m = NULL;
  dn_loop_data* data = NULL;
  double zr, vr, s[DN_LOOP_STATE_SIZE];
  int k = 0, st;
  if (!f) return 2;
  dn_vehicle_default(&veh);
  dn_controller_default(&ctrl, kind);
  d = make_damper(which);
  EXPECT(dn_loop_model_create(&veh, d, &ctrl, &m) == DN_OK);
  EXPECT(dn_loop_data_create(m, &data) == DN_OK);
  while (fscanf(f, "%lf %lf", &zr, &vr) == 2) {
    dn_loop_input in;
    dn_loop_out out;
    in.z_r = zr;
    in.v_r = vr;
    in.u = 0.0;
    if (k == 0) {
      dn_loop_get_state(data, s);
      s[5] = zr;
      s[6] = vr;
      dn_loop_set_state(data, s);
    } else {
      st = dn_loop_step(m, data, &in, &out);
      if (st < 0) {
        fprintf(stderr, "step %d: %s\n", k, dn_status_str(st));
        return 3;
      }
      printf("%.17g %.17g %.17g\n", out.force, out.u, out.a);
    }
    dn_loop_get_state(data, s);
    printf("S %.17g %.17g %.17g %.17g %.17g\n", s[0], s[1], s[2], s[3], s[4]);
    ++k;
  }
  fclose(f);
  dn_loop_data_destroy(data);
  dn_loop_model_destroy(m);
  dn_damper_destroy(d);
  return failures ? 1 : 0;
}

int main(int argc, char** argv) {
  static const char* const kinds[] = {"neural", "neural_f", "parametric", "table"};
  int i, k, st;
  if (argc > 1) return run_file(argc, argv);

  for (i = 0; i < 4; ++i) {
    dn_vehicle veh;
    dn_controller ctrl;
    dn_loop_model* m = NULL;
    dn_loop_data *d1 = NULL, *d2 = NULL;
    dn_damper* damper = make_damper(kinds[i]);
    double s1[DN_LOOP_STATE_SIZE], s2[DN_LOOP_STATE_SIZE], rate, max_zs = 0.0;
    dn_vehicle_default(&veh);
    dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
    EXPECT(dn_loop_model_create(&veh, damper, &ctrl, &m) == DN_OK);
    dn_damper_destroy(damper); /* the model holds its own copy */
    EXPECT(dn_loop_data_create(m, &d1) == DN_OK);
    EXPECT(dn_loop_data_create(m, &d2) == DN_OK); /* two loops on one model */
    for (k = 1; k <= 5000; ++k) {
      dn_loop_input in;
      dn_loop_out out;
      in.z_r = road_at(k, veh.dt, &rate);
      in.v_r = rate;
      in.u = 0.0;
      st = dn_loop_step(m, d1, &in, &out);
      EXPECT(st >= 0);
      EXPECT(dn_loop_step(m, d2, &in, NULL) == st);
      EXPECT(isfinite(out.force) && out.u >= 0.0 && out.u <= 5.0);
      if (i < 2) EXPECT(out.n_features == 3 && out.features[2] == out.u);
    }
    EXPECT(dn_loop_get_state(d1, s1) == DN_OK);
    EXPECT(dn_loop_get_state(d2, s2) == DN_OK);
    EXPECT(memcmp(s1, s2, sizeof s1) == 0);
    EXPECT(fabs(s1[0] - 5.0) < 1e-9);
    max_zs = fabs(s1[1]);
    EXPECT(max_zs < 0.1);
    printf("%s: t = %.3f s, z_s = %.6f m, z_us = %.6f m, damper evaluations %lld\n", kinds[i],
           s1[0], s1[1], s1[3], (long long)dn_loop_damper_evals(d1));
    /* 4 per step; the neural models read the acceleration and solve it implicitly by
     * default (dn_accel_feature): between 1 and DN_ACCEL_MAX_EVALS per stage */
    if (i < 2)
      EXPECT(dn_loop_damper_evals(d1) >= 4 * 5000 &&
             dn_loop_damper_evals(d1) <= 4 * 5000 * DN_ACCEL_MAX_EVALS);
    else
      EXPECT(dn_loop_damper_evals(d1) == 4 * 5000);
    /* reset, refusals */
    EXPECT(dn_loop_reset(m, d1) == DN_OK);
    EXPECT(dn_loop_get_state(d1, s1) == DN_OK && s1[0] == 0.0 && s1[1] == 0.0);
    {
      dn_loop_input bad = {NAN, 0.0, 0.0};
      EXPECT(dn_loop_step(m, d1, &bad, NULL) == DN_E_NONFINITE_INPUT);
      s1[2] = INFINITY;
      EXPECT(dn_loop_set_state(d1, s1) == DN_E_NONFINITE_INPUT);
    }
    dn_loop_data_destroy(d1);
    dn_loop_data_destroy(d2);
    dn_loop_model_destroy(m);
  }

  /* nonsensical vehicles and dampers are refused with a clear status */
  {
    dn_vehicle veh;
    dn_damper* d = NULL;
    dn_loop_model* m = NULL;
    dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
    dn_mlp* mlp = NULL;
    const char* const bad_names[] = {"velocity", "jerk", "voltage"};
    const char* const lag_names[] = {"velocity", "acceleration", "voltage_lag"};
    EXPECT(dn_damper_create_linear(1500.0, &d) == DN_OK);
    dn_vehicle_default(&veh);
    veh.m_s = -700.0;
    EXPECT(dn_loop_model_create(&veh, d, NULL, &m) == DN_E_PARAM && m == NULL);
    dn_vehicle_default(&veh);
    veh.dt = 0.0;
    EXPECT(dn_loop_model_create(&veh, d, NULL, &m) == DN_E_PARAM);
    veh.dt = NAN;
    EXPECT(dn_loop_model_create(&veh, d, NULL, &m) == DN_E_NONFINITE_PARAM);
    EXPECT(dn_loop_model_create(NULL, d, NULL, &m) == DN_E_NULL);
    EXPECT(dn_damper_add_term(d, "gas", NULL, 0) == DN_E_UNKNOWN_NAME);
    dn_damper_destroy(d);
    EXPECT(dn_damper_create_linear(NAN, &d) == DN_E_NONFINITE_PARAM && d == NULL);
    /* negative damping feeds energy in (issue 29: it was DN_OK and ran away to 1e18) */
    EXPECT(dn_damper_create_linear(-2000.0, &d) == DN_E_PARAM && d == NULL);
    EXPECT(dn_damper_create_linear(-1e-300, &d) == DN_E_PARAM && d == NULL);
    EXPECT(dn_damper_create_linear(0.0, &d) == DN_OK);
    dn_damper_destroy(d);
    d = NULL;
    /* a step beyond the stability limit (DN_STABLE_WDT_RK4: 20 ms for Table 5) is refused */
    EXPECT(dn_damper_create_linear(1500.0, &d) == DN_OK);
    dn_vehicle_default(&veh);
    veh.dt = 0.1;
    EXPECT(dn_loop_model_create(&veh, d, NULL, &m) == DN_E_PARAM && m == NULL);
    veh.dt = 0.02;
    EXPECT(dn_loop_model_create(&veh, d, NULL, &m) == DN_OK);
    dn_loop_model_destroy(m);
    m = NULL;
    veh.integrator = DN_INT_SEMI_EULER;
    EXPECT(dn_loop_model_create(&veh, d, NULL, &m) == DN_E_PARAM && m == NULL);
    dn_damper_destroy(d);
    d = NULL;
    EXPECT(dn_mlp_create(&desc, &mlp) == DN_OK);
    EXPECT(dn_damper_create_neural(mlp, bad_names, 3, NULL, NULL, 0, 0, &d) == DN_E_UNKNOWN_NAME);
    EXPECT(dn_damper_create_neural(mlp, bad_names, 2, NULL, NULL, 0, 0, &d) == DN_E_MISMATCH);
    EXPECT(dn_damper_create_neural(mlp, lag_names, 3, NULL, NULL, 0, 0, &d) == DN_E_PARAM);
    dn_mlp_destroy(mlp);
    EXPECT(strstr(dn_status_str(DN_E_DIVERGED), "non-finite state") != NULL);
    EXPECT(strstr(dn_status_str(DN_E_UNKNOWN_NAME), "unknown") != NULL);
  }
  if (failures) fprintf(stderr, "%d expectation(s) failed\n", failures);
  else printf("all checks passed\n");
  return failures ? 1 : 0;
}
