/* The recipe's example feature (dn_xmacro.h's recipe applied to a copy of the tree) through the C ABI's two vehicle
 * hosts: the quarter-car loop (dn_loop_*) and the full car (dn_fullcar_*), with a small neural
 * damper on {"velocity", "displacement_lag"} (recipe_model.h: RECIPE_*, which the test writes into
 * build/tests-recipe/ from its numpy weights). tests/python/test_state_recipe.py
 * builds it with the copy's C ABI sources and headers, and compares what it prints
 * with a numpy reference.
 *
 *   recipe_hosts loop N      the quarter car (RK4, per-stage evaluations, double MLP, passive)
 *                            over N steps of the road read from stdin ("z_r v_r" per line: the
 *                            road at each step's end); per step k the report at its start and
 *                            the damper state block's x_lag after it:
 *                              "r k x v force n_features f0 f1 x_lag_after last_of_state"
 *   recipe_hosts fullcar N   the full car (4 corners the same damper), road per corner from stdin
 *                            ("z0 v0 z1 v1 z2 v2 z3 v3" per line); per step and corner i:
 *                              "c k i x v force x_lag_after last_of_corner_block"
 *   recipe_hosts fwloop N    the quarter car in the Cortex-M firmware's configuration (float MLP,
 *                            one evaluation per step, linearised acceleration feature, on-off
 *                            skyhook through a 5 ms command filter) over the road from stdin,
 *                            printing the state every 100 steps as the firmware does:
 *                              "s k state[0..DN_LOOP_STATE_SIZE-1] force"
 * First line of every mode: "layout DN_N_FEATURES DN_DAMPER_STATE_SIZE DN_DS_X_LAG
 * DN_LOOP_DAMPER_BASE DN_LOOP_STATE_SIZE dn_loop_state_size() DN_FULLCAR_STATE_SIZE
 * dn_fullcar_state_size() DN_FULLCAR_CORNER_BASE DN_FULLCAR_CORNER_SIZE DN_FULLCAR_CORNER_DAMPER". */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dampnet/dampnet.h"
#include "recipe_model.h"

/* compiled against a tree the recipe was applied to: its state is in the damper's block */
enum { RECIPE_STATE_PRESENT = DN_DS_X_LAG };

static void check(const char* what, int st) {
  if (st < 0) {
    fprintf(stderr, "%s: %s (%d)\n", what, dn_status_str(st), st);
    exit(2);
  }
}

static dn_damper* make_damper(int precision) {
  const dn_mlp_desc desc = RECIPE_DESC_INIT;
  dn_mlp* mlp = NULL;
  check("dn_mlp_create", dn_mlp_create(&desc, &mlp));
  dn_damper* d = NULL;
  check("dn_damper_create_neural",
        dn_damper_create_neural(mlp, RECIPE_FEATURE_NAMES, RECIPE_N_INPUTS, RECIPE_PARAM_NAMES,
                                RECIPE_PARAM_VALUES, RECIPE_N_PARAMS, precision, &d));
  dn_mlp_destroy(mlp);
  return d;
}

static int read_reals(double* v, int n) {
  for (int i = 0; i < n; ++i)
    if (scanf("%lf", &v[i]) != 1) return 0;
  return 1;
}

static int run_loop(int n, int firmware_config) {
  dn_vehicle veh;
  dn_vehicle_default(&veh);
  dn_controller ctrl;
  dn_controller_default(&ctrl, DN_CTRL_PASSIVE);
  if (firmware_config) {
    veh.damper_eval = DN_EVAL_PER_STEP;
    veh.accel_feature = DN_ACCEL_LINEAR;
    dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
    ctrl.u_tau_s = 0.005;
  }
  dn_damper* damper = make_damper(firmware_config ? DN_PRECISION_FLOAT : DN_PRECISION_DOUBLE);
  dn_loop_model* m = NULL;
  check("dn_loop_model_create", dn_loop_model_create(&veh, damper, &ctrl, &m));
  dn_damper_destroy(damper);
  dn_loop_data* d = NULL;
  check("dn_loop_data_create", dn_loop_data_create(m, &d));
  dn_real s[DN_LOOP_STATE_SIZE];
  dn_loop_out out;
  memset(&out, 0, sizeof out);
  for (int k = 0; k < n; ++k) {
    double zv[2];
    if (!read_reals(zv, 2)) {
      fprintf(stderr, "road: line %d missing\n", k);
      return 2;
    }
    const dn_loop_input in = {zv[0], zv[1], 0.0};
    check("dn_loop_step", dn_loop_step(m, d, &in, &out));
    check("dn_loop_get_state", dn_loop_get_state(d, s));
    if (!firmware_config) {
      printf("r %d %.17g %.17g %.17g %d %.17g %.17g %.17g %.17g\n", k, (double)out.x, (double)out.v,
             (double)out.force, out.n_features, (double)out.features[0], (double)out.features[1],
             (double)s[DN_LOOP_DAMPER_BASE + DN_DS_X_LAG], (double)s[DN_LOOP_STATE_SIZE - 1]);
    } else if ((k + 1) % 100 == 0 || k + 1 == n) {
      printf("s %d", k + 1);
      for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i) printf(" %.17g", (double)s[i]);
      printf(" %.17g\n", (double)out.force);
    }
  }
  dn_loop_data_destroy(d);
  dn_loop_model_destroy(m);
  return 0;
}

static int run_fullcar(int n) {
  dn_fullcar_params p;
  dn_fullcar_default(&p);
  dn_damper* damper = make_damper(DN_PRECISION_DOUBLE);
  const dn_damper* dampers[DN_FULLCAR_CORNERS] = {damper, damper, damper, damper};
  dn_fullcar_model* m = NULL;
  check("dn_fullcar_model_create", dn_fullcar_model_create(&p, dampers, NULL, NULL, NULL, 0, &m));
  dn_damper_destroy(damper);
  dn_fullcar_data* d = NULL;
  check("dn_fullcar_data_create", dn_fullcar_data_create(m, &d));
  double s[DN_FULLCAR_STATE_SIZE];
  dn_fullcar_out out;
  for (int k = 0; k < n; ++k) {
    double zv[2 * DN_FULLCAR_CORNERS];
    if (!read_reals(zv, 2 * DN_FULLCAR_CORNERS)) {
      fprintf(stderr, "road: line %d missing\n", k);
      return 2;
    }
    dn_fullcar_input in;
    memset(&in, 0, sizeof in);
    for (int i = 0; i < DN_FULLCAR_CORNERS; ++i) in.z_r[i] = zv[2 * i], in.v_r[i] = zv[2 * i + 1];
    check("dn_fullcar_step", dn_fullcar_step(m, d, &in, &out));
    check("dn_fullcar_get_state", dn_fullcar_get_state(d, s));
    for (int i = 0; i < DN_FULLCAR_CORNERS; ++i) {
      const int block = DN_FULLCAR_CORNER_BASE + i * DN_FULLCAR_CORNER_SIZE;
      printf("c %d %d %.17g %.17g %.17g %.17g %.17g\n", k, i, out.x[i], out.v[i], out.force[i],
             s[block + DN_FULLCAR_CORNER_DAMPER + DN_DS_X_LAG], s[block + DN_FULLCAR_CORNER_SIZE - 1]);
    }
  }
  dn_fullcar_data_destroy(d);
  dn_fullcar_model_destroy(m);
  return 0;
}

int main(int argc, char** argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s loop|fullcar|fwloop N < road\n", argv[0]);
    return 2;
  }
  const int n = atoi(argv[2]);
  printf("layout %d %d %d %d %d %d %d %d %d %d %d\n", (int)DN_N_FEATURES, (int)DN_DAMPER_STATE_SIZE,
         (int)DN_DS_X_LAG, DN_LOOP_DAMPER_BASE, (int)DN_LOOP_STATE_SIZE, dn_loop_state_size(),
         (int)DN_FULLCAR_STATE_SIZE, dn_fullcar_state_size(), DN_FULLCAR_CORNER_BASE,
         (int)DN_FULLCAR_CORNER_SIZE, DN_FULLCAR_CORNER_DAMPER);
  if (strcmp(argv[1], "loop") == 0) return run_loop(n, 0);
  if (strcmp(argv[1], "fwloop") == 0) return run_loop(n, 1);
  if (strcmp(argv[1], "fullcar") == 0) return run_fullcar(n);
  fprintf(stderr, "unknown mode %s\n", argv[1]);
  return 2;
}
