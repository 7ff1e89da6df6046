// The quarter-car loop with dampnet's C++ headers: the same configuration as
// examples/c/quarter_car.c (default neural damper, on-off skyhook with a 5 ms command
// filter, Table 5 vehicle, RK4 at 1 ms, the two-tone road, 3000 steps), run by
// dampnet::step from loop.hpp, and then the compile-time-sized kernel StaticMlp on the
// last step's features: what a controller that evaluates the model itself would do.
//
// Build against an installed dampnet with examples/CMakeLists.txt, or by hand (the loop
// and the kernel are header-only; the library provides dn_status_str):
//   c++ -std=c++17 -O2 -I<prefix>/include quarter_car.cpp <prefix>/lib/libdampnet.a
#include <cmath>
#include <cstdio>

#include <dampnet/loop.hpp>  // LoopModel, LoopData, step; includes damper.hpp and mlp.hpp
#include <dampnet/mlp.hpp>   // StaticMlp
#include <dn_model_default.h>

namespace {

constexpr int kSteps = 3000;
constexpr double kDt = 0.001;  // [s]
constexpr double kPi = 3.14159265358979323846;

// The road at time t [s] (as in quarter_car.c): 3 cm peak to peak at 1.2 Hz and 6 mm
// at 9 Hz, raised cosines starting at rest. z [m], rate [m/s].
void road(double t, double& z, double& rate) {
  const double a1 = 0.015, w1 = 2 * kPi * 1.2, a2 = 0.002, w2 = 2 * kPi * 6.0;
  z = a1 * (1 - std::cos(w1 * t)) + a2 * (1 - std::cos(w2 * t));
  rate = a1 * w1 * std::sin(w1 * t) + a2 * w2 * std::sin(w2 * t);
}

int fail(const char* what, int st) {
  std::fprintf(stderr, "quarter_car: %s: %s\n", what, dn_status_str(st));
  return 1;
}

}  // namespace

int main() {
  const dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;

  // Set-up: a neural damper (its MLP in double and float, as the C ABI's dn_mlp holds
  // it), then the loop model (validates, copies the damper) and one loop state.
  dampnet::Damper damper;
  int st = damper.md.load(&desc);
  if (st == DN_OK) st = damper.mf.load(&desc);
  if (st == DN_OK)
    st = damper.set_neural_features(dn_model_default_feature_names, DN_MODEL_DEFAULT_N_INPUTS,
                                    nullptr, nullptr, 0, DN_PRECISION_DOUBLE);
  if (st != DN_OK) return fail("neural damper", st);
  dn_vehicle veh = dampnet::default_vehicle();  // Table 5, RK4 per stage, implicit a
  veh.dt = kDt;
  dn_controller ctrl = dampnet::default_controller(DN_CTRL_SKYHOOK_ONOFF);
  ctrl.u_tau_s = 0.005;  // 5 ms command filter
  // LoopModel holds the damper and its MLPs by value (tens of kB): keep it off the stack
  // of a real-time thread; a static is fine here.
  static dampnet::LoopModel model;
  st = model.init(veh, damper, ctrl);
  if (st != DN_OK) return fail("LoopModel::init", st);
  dampnet::LoopData data;
  dampnet::reset(model, data);

  // The loop: input = the road at the end of the step, report at its start.
  double sum_acc2 = 0.0, max_force = 0.0;
  int n_saturated = 0, n_unconverged = 0;  // steps with these warnings
  dn_loop_out out{};
  for (int k = 0; k < kSteps; ++k) {
    dn_loop_input in{0.0, 0.0, 0.0};
    road((k + 1) * kDt, in.z_r, in.v_r);
    st = dampnet::step(model, data, in, &out);
    if (st < 0) return fail("step", st);
    if (st & DN_W_SATURATED) ++n_saturated;          // an MLP input was clamped
    if (st & DN_W_ACCEL_UNCONVERGED) ++n_unconverged;  // implicit a: best of 6 used
    sum_acc2 += out.acc_s * out.acc_s;
    max_force = std::fmax(max_force, std::fabs(out.force));
  }
  const double* s = data.s;  // indices: dampnet::S_t, S_z_s, ... (DN_LOOP_STATE_LIST)
  std::printf("dampnet C++ headers: default model, skyhook on-off, %d steps of %g s\n", kSteps, kDt);
  std::printf("result t=%.12g z_s=%.12g v_s=%.12g z_us=%.12g v_us=%.12g acc_s_rms=%.12g "
              "force_max=%.12g saturated=%d unconverged=%d\n",
              s[dampnet::S_t], s[dampnet::S_z_s], s[dampnet::S_v_s], s[dampnet::S_z_us],
              s[dampnet::S_v_us], std::sqrt(sum_acc2 / kSteps), max_force, n_saturated, n_unconverged);

  // StaticMlp: sizes from the generated header, storage of exactly that size, the same
  // forward as the loop's damper. Evaluated on the last step's features (velocity [m/s],
  // acceleration [m/s^2], voltage [V]), it gives that step's force.
  dampnet::StaticMlp<double, DN_MODEL_DEFAULT_N_INPUTS, DN_MODEL_DEFAULT_N_HIDDEN1,
                     DN_MODEL_DEFAULT_N_HIDDEN2> kernel;
  dampnet::StaticMlp<float, DN_MODEL_DEFAULT_N_INPUTS, DN_MODEL_DEFAULT_N_HIDDEN1,
                     DN_MODEL_DEFAULT_N_HIDDEN2> kernel_f;  // the HIL choice: float
  if ((st = kernel.load(&desc)) != DN_OK || (st = kernel_f.load(&desc)) != DN_OK)
    return fail("StaticMlp::load", st);
  double force = 0.0;
  float xf[DN_MODEL_DEFAULT_N_INPUTS], force_f = 0.0f;
  for (int i = 0; i < DN_MODEL_DEFAULT_N_INPUTS; ++i) xf[i] = static_cast<float>(out.features[i]);
  const int st_d = kernel.forward(out.features, &force);
  const int st_f = kernel_f.forward(xf, &force_f);
  if (st_d < 0 || st_f < 0) return fail("StaticMlp::forward", st_d < 0 ? st_d : st_f);
  std::printf("StaticMlp on the last step's features: %.9g N (double), %.9g N (float); "
              "the loop's force %.9g N\n", force, static_cast<double>(force_f), out.force);
  // The same weights and the same forward template as the loop's damper: equal to
  // rounding (the float kernel to about 1e-5 of the force range).
  const double range = 1.0 / DN_MODEL_DEFAULT_OUT_GAIN * 2.0;  // force range [N]
  if (std::fabs(force - out.force) > 1e-9 * range || std::fabs(force_f - out.force) > 1e-4 * range) {
    std::fprintf(stderr, "quarter_car: StaticMlp disagrees with the loop's damper\n");
    return 1;
  }
  return 0;
}
