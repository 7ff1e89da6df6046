/* A bit-for-bit fingerprint of the full car and the quarter car over a grid of configurations
 * (bench/LOG.md, issue 30's "Toward 16 KB"): per configuration one line, the name and an
 * FNV-1a 64 of every state after each of 600 steps, every report (when on), every status, a
 * forward() every 50 steps and the evaluation count. Two libraries whose arithmetic is the same
 * print the same lines. Build against a library and run:
 *   cc -std=c11 -O1 -Icpp/include -Iexport bench/fullcar_bits.c -o /tmp/fullcar_bits \
 *      build/<dir>/libdampnet.so -Wl,-rpath,build/<dir> -lm && /tmp/fullcar_bits > bits.txt
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "dampnet/dampnet.h"
#include "dn_model_default.h"
#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
static uint64_t H;
static void mix(const void* p, size_t n) { const unsigned char* c = p; for (size_t i = 0; i < n; ++i) { H ^= c[i]; H *= 1099511628211ULL; } }
static dn_fullcar_input road(long k, double amp) {
  dn_fullcar_input in; const double t = (double)(k + 1) * 1e-3, w1 = 2 * M_PI * 1.3, w2 = 2 * M_PI * 11.0;
  for (int c = 0; c < 4; ++c) { const double ph = 0.9 * c;
    in.z_r[c] = amp * (0.015 * sin(w1 * t + ph) + 0.005 * sin(w2 * t + 2 * ph));
    in.v_r[c] = amp * (0.015 * w1 * cos(w1 * t + ph) + 0.005 * w2 * cos(w2 * t + 2 * ph));
    in.u[c] = 1.0 + 0.5 * sin(3 * t + c); }
  in.steer = 0.03 * sin(2 * M_PI * 0.5 * t);
  return in;
}
int main(void) {
  const dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  dn_mlp* mlp = NULL; if (dn_mlp_create(&desc, &mlp)) return 1;
  const char* featsets[3][3] = {{"velocity", "acceleration", "voltage"},
                                {"velocity_lag", "acceleration", "voltage_lag"},
                                {"friction_state", "velocity", "voltage_lag"}};
  const char* pn[3] = {"control_lag_tau_s", "velocity_lag_tau_s", "friction_presliding_m"};
  const double pv[3] = {0.004, 0.003, 0.0005};
  int ncfg = 0; const int kinds = 5; /* 0..2 neural feature sets, 3 linear, 4 parametric */
  for (int kind = 0; kind < kinds; ++kind)
  for (int prec = 0; prec < 2; ++prec) {
    if (kind >= 3 && prec) continue;
    for (int shared = 0; shared < 2; ++shared)
    for (int eval = 0; eval < 2; ++eval)
    for (int accel = 0; accel < 3; ++accel)
    for (int tyre = 0; tyre < 2; ++tyre)
    for (int steer = 0; steer < 2; ++steer)
    for (int report = 0; report < 2; ++report) {
      if (kind >= 3 && (accel || shared)) continue;
      if ((tyre || steer) && (accel != 2 || report)) continue; /* keep the grid small */
      dn_damper* own[4] = {0};
      for (int c = 0; c < (shared ? 1 : 4); ++c) {
        int st;
        if (kind < 3) st = dn_damper_create_neural(mlp, featsets[kind], 3, pn, pv, 3, prec ? DN_PRECISION_DOUBLE : DN_PRECISION_FLOAT, &own[c]);
        else if (kind == 3) st = dn_damper_create_linear(1500.0 + 100 * c, &own[c]);
        else { dn_parametric_params pp; memset(&pp, 0, sizeof pp); pp.c_min = 800; pp.c_max = 3000; pp.gamma = 1.2; pp.f0 = 50; pp.v_max = 1.5; pp.v_smooth = 0.01;
               st = dn_damper_create_parametric(&pp, &own[c]); }
        if (st) { fprintf(stderr, "damper %d %d\n", kind, st); return 1; }
      }
      dn_damper* corners[4]; dn_controller ctrls[4];
      for (int c = 0; c < 4; ++c) { corners[c] = own[shared ? 0 : c]; dn_controller_default(&ctrls[c], c == 3 ? DN_CTRL_EXTERNAL : DN_CTRL_SKYHOOK_ONOFF); }
      dn_fullcar_params fp; dn_fullcar_default(&fp);
      fp.damper_eval = eval ? DN_EVAL_PER_STEP : DN_EVAL_PER_STAGE;
      fp.accel_feature = accel;
      fp.tyre_model = tyre ? DN_TYRE_LINEAR : DN_TYRE_MAGIC_FORMULA;
      fp.steer_mode = steer ? DN_STEER_DRIVER : DN_STEER_OPEN_LOOP;
      double px[3] = {0, 50, 500}, py[3] = {0, 0.5, 3};
      dn_fullcar_model* fm = NULL; dn_fullcar_data* fd = NULL;
      int st = dn_fullcar_model_create(&fp, (const dn_damper* const*)corners, ctrls, steer ? px : NULL, steer ? py : NULL, steer ? 3 : 0, &fm);
      if (st || dn_fullcar_data_create(fm, &fd)) { fprintf(stderr, "model %d\n", st); return 1; }
      H = 1469598103934665603ULL;
      double s[512]; const int ns = dn_fullcar_state_size();
      for (long k = 0; k < 600; ++k) {
        const dn_fullcar_input in = road(k, k > 500 ? 40.0 : 1.0); /* the end: large, maybe diverging */
        dn_fullcar_out out; memset(&out, 0, sizeof out);
        const int r = dn_fullcar_step(fm, fd, &in, report ? &out : NULL);
        mix(&r, sizeof r);
        if (report) mix(&out, sizeof out);
        dn_fullcar_get_state(fd, s); mix(s, sizeof(double) * ns);
        if (k % 50 == 0) { dn_fullcar_out o2; memset(&o2, 0, sizeof o2); const int r2 = dn_fullcar_forward(fm, fd, &in, &o2); mix(&r2, sizeof r2); mix(&o2, sizeof o2); }
      }
      int64_t ne = dn_fullcar_damper_evals(fd); mix(&ne, sizeof ne);
      printf("fc k%d p%d sh%d ev%d ac%d ty%d st%d rep%d %016llx\n", kind, prec, shared, eval, accel, tyre, steer, report, (unsigned long long)H);
      ++ncfg;
      dn_fullcar_data_destroy(fd); dn_fullcar_model_destroy(fm);
      for (int c = 0; c < 4; ++c) dn_damper_destroy(own[c]);
    }
  }
  /* the quarter car */
  for (int kind = 0; kind < 3; ++kind)
  for (int eval = 0; eval < 2; ++eval)
  for (int accel = 0; accel < 3; ++accel) {
    dn_damper* d = NULL;
    if (dn_damper_create_neural(mlp, featsets[kind], 3, pn, pv, 3, DN_PRECISION_FLOAT, &d)) return 1;
    dn_controller ctrl; dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
    dn_vehicle veh; dn_vehicle_default(&veh);
    veh.damper_eval = eval ? DN_EVAL_PER_STEP : DN_EVAL_PER_STAGE; veh.accel_feature = accel;
    dn_loop_model* lm = NULL; dn_loop_data* ld = NULL;
    if (dn_loop_model_create(&veh, d, &ctrl, &lm) || dn_loop_data_create(lm, &ld)) return 1;
    H = 1469598103934665603ULL;
    for (long k = 0; k < 600; ++k) {
      const dn_fullcar_input fi = road(k, 1.0);
      dn_loop_input in = {fi.z_r[0], fi.v_r[0], 0.0};
      dn_loop_out out; memset(&out, 0, sizeof out);
      const int r = dn_loop_step(lm, ld, &in, &out); mix(&r, sizeof r); mix(&out, sizeof out);
      double s[64]; dn_loop_get_state(ld, s); mix(s, sizeof(double) * dn_loop_state_size());
    }
    printf("loop k%d ev%d ac%d %016llx\n", kind, eval, accel, (unsigned long long)H); ++ncfg;
    dn_loop_data_destroy(ld); dn_loop_model_destroy(lm); dn_damper_destroy(d);
  }
  fprintf(stderr, "%d configurations\n", ncfg);
  dn_mlp_destroy(mlp);
  return 0;
}
