/* The steps whose executed code the footprint tool measures (python -m dampnet.latency.footprint
 * --dynamic): one configuration of dampnet bench's (bench/bench_mlp.cpp: the default 3-30-1
 * model as neural dampers reading velocity, acceleration and voltage, on-off skyhook, the same
 * roads), set up and settled over 2000 steps, then N steps inside dn_fp_measured(), the one
 * function callgrind collects in (--toggle-collect=dn_fp_measured).
 *
 * Usage: footprint_steps CONFIG [N]   (N default 10; CONFIG one of the names printed by
 * `footprint_steps --list`, dampnet bench's case names). Prints "BASE <address>": where
 * libdampnet is loaded. Exit status 0, or 1 on any error (a step's error included).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dampnet/dampnet.h"
#include "dn_model_default.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct {
  const char* name;
  int fullcar;    /* 1 the full vehicle, 0 the quarter car */
  int eval;       /* dn_damper_eval; -1: the default */
  int precision;  /* dn_precision */
  int shared;     /* full car: the four corners given one damper object */
  int accel;      /* dn_accel_feature; -1: the default */
} Config;

static const Config kConfigs[] = {
    {"fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel", 1, DN_EVAL_PER_STEP, DN_PRECISION_FLOAT, 1, DN_ACCEL_LINEAR},
    {"fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel_four_calls", 1, DN_EVAL_PER_STEP, DN_PRECISION_FLOAT, 0, DN_ACCEL_LINEAR},
    {"fullcar_step_rk4_per_step_eval_neural_double_skyhook_linear_accel", 1, DN_EVAL_PER_STEP, DN_PRECISION_DOUBLE, 1, DN_ACCEL_LINEAR},
    {"fullcar_step_rk4_neural_float_skyhook_linear_accel", 1, DN_EVAL_PER_STAGE, DN_PRECISION_FLOAT, 1, DN_ACCEL_LINEAR},
    {"fullcar_step_rk4_neural_float_skyhook_linear_accel_four_calls", 1, DN_EVAL_PER_STAGE, DN_PRECISION_FLOAT, 0, DN_ACCEL_LINEAR},
    {"loop_step_rk4_per_step_eval_neural_float_skyhook_linear_accel", 0, DN_EVAL_PER_STEP, DN_PRECISION_FLOAT, 1, DN_ACCEL_LINEAR},
    {"loop_step_rk4_neural_float_skyhook", 0, -1, DN_PRECISION_FLOAT, 1, -1},
};
#define N_CONFIGS ((int)(sizeof kConfigs / sizeof kConfigs[0]))

static dn_fullcar_input fullcar_road(long k) {
  dn_fullcar_input in;
  const double t = (double)((k & 4095) + 1) * 1e-3, w1 = 2 * M_PI * 1.3, w2 = 2 * M_PI * 11.0;
  for (int c = 0; c < 4; ++c) {
    const double ph = 0.9 * c;
    in.z_r[c] = 0.015 * sin(w1 * t + ph) + 0.005 * sin(w2 * t + 2 * ph);
    in.v_r[c] = 0.015 * w1 * cos(w1 * t + ph) + 0.005 * w2 * cos(w2 * t + 2 * ph);
    in.u[c] = 0.0;
  }
  in.steer = 0.03 * sin(2 * M_PI * 0.5 * t);
  return in;
}

static dn_loop_input loop_road(long k, double dt) {
  const double t = (double)((k & 4095) + 1) * dt, w1 = 2 * M_PI * 1.3, w2 = 2 * M_PI * 11.0;
  dn_loop_input in = {0.015 * sin(w1 * t) + 0.005 * sin(w2 * t),
                      0.015 * w1 * cos(w1 * t) + 0.005 * w2 * cos(w2 * t), 0.0};
  return in;
}

/* The measured steps (inputs precomputed: only the steps run in here). */
__attribute__((noinline)) int dn_fp_measured(dn_fullcar_model* fm, dn_fullcar_data* fd,
                                             const dn_fullcar_input* fin, dn_loop_model* lm,
                                             dn_loop_data* ld, const dn_loop_input* lin, int n) {
  int errors = 0;
  for (int k = 0; k < n; ++k)
    errors += (fm ? dn_fullcar_step(fm, fd, &fin[k], NULL) : dn_loop_step(lm, ld, &lin[k], NULL)) < 0;
  return errors;
}

int main(int argc, char** argv) {
  if (argc > 1 && strcmp(argv[1], "--list") == 0) {
    for (int i = 0; i < N_CONFIGS; ++i) printf("%s\n", kConfigs[i].name);
    return 0;
  }
  const Config* cfg = NULL;
  for (int i = 0; argc > 1 && i < N_CONFIGS; ++i)
    if (strcmp(argv[1], kConfigs[i].name) == 0) cfg = &kConfigs[i];
  if (!cfg) {
    fprintf(stderr, "usage: %s CONFIG [N] (CONFIG: see --list)\n", argv[0]);
    return 1;
  }
  const int n = argc > 2 ? atoi(argv[2]) : 10;
  if (n < 1 || n > 100000) return 1;
  const dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  dn_mlp* mlp = NULL;
  if (dn_mlp_create(&desc, &mlp)) return 1;
  const char* const feats[3] = {"velocity", "acceleration", "voltage"};
  dn_damper* own[4] = {NULL, NULL, NULL, NULL};
  for (int c = 0; c < (cfg->shared ? 1 : 4); ++c)
    if (dn_damper_create_neural(mlp, feats, 3, NULL, NULL, 0, cfg->precision, &own[c])) return 1;
  dn_controller ctrl;
  dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
  dn_fullcar_model* fm = NULL;
  dn_fullcar_data* fd = NULL;
  dn_loop_model* lm = NULL;
  dn_loop_data* ld = NULL;
  dn_fullcar_input* fin = calloc((size_t)n, sizeof *fin);
  dn_loop_input* lin = calloc((size_t)n, sizeof *lin);
  if (!fin || !lin) return 1;
  int errors = 0;
  if (cfg->fullcar) {
    dn_damper* corners[4];
    dn_controller ctrls[4];
    for (int c = 0; c < 4; ++c) corners[c] = own[cfg->shared ? 0 : c], ctrls[c] = ctrl;
    dn_fullcar_params fp;
    dn_fullcar_default(&fp);
    fp.damper_eval = cfg->eval;
    fp.accel_feature = cfg->accel;
    if (dn_fullcar_model_create(&fp, (const dn_damper* const*)corners, ctrls, NULL, NULL, 0, &fm) || dn_fullcar_data_create(fm, &fd))
      return 1;
    for (long k = 0; k < 2000; ++k) {
      const dn_fullcar_input in = fullcar_road(k);
      errors += dn_fullcar_step(fm, fd, &in, NULL) < 0;
    }
    for (int k = 0; k < n; ++k) fin[k] = fullcar_road(2000 + k);
  } else {
    dn_vehicle veh;
    dn_vehicle_default(&veh);
    if (cfg->eval >= 0) veh.damper_eval = cfg->eval;
    if (cfg->accel >= 0) veh.accel_feature = cfg->accel;
    if (dn_loop_model_create(&veh, own[0], &ctrl, &lm) || dn_loop_data_create(lm, &ld)) return 1;
    for (long k = 0; k < 2000; ++k) {
      const dn_loop_input in = loop_road(k, veh.dt);
      errors += dn_loop_step(lm, ld, &in, NULL) < 0;
    }
    for (int k = 0; k < n; ++k) lin[k] = loop_road(2000 + k, veh.dt);
  }
  Dl_info info;
  if (!dladdr((void*)&dn_fullcar_step, &info)) return 1;
  printf("BASE %p\n", info.dli_fbase);
  errors += dn_fp_measured(fm, fd, fin, lm, ld, lin, n);
  if (errors) fprintf(stderr, "footprint_steps: %d steps returned an error\n", errors);
  dn_fullcar_data_destroy(fd);
  dn_fullcar_model_destroy(fm);
  dn_loop_data_destroy(ld);
  dn_loop_model_destroy(lm);
  for (int c = 0; c < 4; ++c) dn_damper_destroy(own[c]);
  dn_mlp_destroy(mlp);
  free(fin);
  free(lin);
  return errors ? 1 : 0;
}
