// Dampers, controllers and the quarter-car loop behind the C ABI.
#include <cstddef>
#include <cmath>
#include <new>

#include "dampnet/dampnet.h"
#include "internal.hpp"

// The ABI: fields of 0.1 keep their offsets (0.2 appended v_lag, z_fric); the state
// size is the length of its list.
static_assert(offsetof(dn_damper_input, u_lag) == 4 * sizeof(dn_real), "dn_damper_input 0.1 layout");
static_assert(offsetof(dn_damper_input, temperature) == 5 * sizeof(dn_real), "dn_damper_input 0.1 layout");
static_assert(offsetof(dn_damper_input, dt) == 7 * sizeof(dn_real), "dn_damper_input 0.1 layout");
static_assert(offsetof(dn_damper_input, stage) == 8 * sizeof(dn_real), "dn_damper_input 0.1 layout");
static_assert(offsetof(dn_damper_input, v_lag) > offsetof(dn_damper_input, stage), "0.2 fields appended");
static_assert(offsetof(dn_controller, c_max) == 9 * sizeof(dn_real), "dn_controller 0.2 layout");
static_assert(offsetof(dn_controller, u_tau_s) == 10 * sizeof(dn_real), "0.3 field appended");
#define DN_STATE_COUNT_(i, name, doc) +1
static_assert(DN_LOOP_DAMPER_BASE == 0 DN_LOOP_STATE_LIST(DN_STATE_COUNT_), "the damper block follows the loop's states");
#undef DN_STATE_COUNT_

namespace {
// A loop model's controller: the caller's, or passive at u = 0 when none is given.
dn_controller controller_or_passive(const dn_controller* ctrl) noexcept {
  dn_controller c = dampnet::default_controller(DN_CTRL_PASSIVE);
  if (ctrl) c = *ctrl;
  else c.u_passive = 0;
  return c;
}

// A damper's set-up in caller memory: place, then the kind's set_* (set(Damper&) -> status).
template <class Set>
int damper_init(void* mem, size_t bytes, dn_damper** out, Set set) noexcept {
  dn_damper* d = nullptr;
  int st = dn_storage::place(mem, bytes, out, &d);
  if (st != DN_OK) return st;
  st = set(d->d);
  if (st == DN_OK) *out = d;
  return st;
}
}  // namespace

extern "C" {

size_t dn_storage_align(void) {
  constexpr size_t a = alignof(dn_mlp) > alignof(dn_damper) ? alignof(dn_mlp) : alignof(dn_damper);
  constexpr size_t b = alignof(dn_loop_model) > alignof(dn_loop_data) ? alignof(dn_loop_model) : alignof(dn_loop_data);
  static_assert((a > b ? a : b) <= DN_STORAGE_ALIGN, "raise DN_STORAGE_ALIGN");
  return a > b ? a : b;
}

size_t dn_damper_size(void) { return sizeof(dn_damper); }

int dn_damper_init_linear(double c, void* mem, size_t bytes, dn_damper** out) {
  return damper_init(mem, bytes, out, [&](dampnet::Damper& d) noexcept { return d.set_linear(c); });
}

int dn_damper_init_parametric(const dn_parametric_params* p, void* mem, size_t bytes, dn_damper** out) {
  return damper_init(mem, bytes, out, [&](dampnet::Damper& d) noexcept { return d.set_parametric(p); });
}

int dn_damper_init_table(const double* velocities, int n_v, const double* controls, int n_u,
                         const double* forces, void* mem, size_t bytes, dn_damper** out) {
  return damper_init(mem, bytes, out, [&](dampnet::Damper& d) noexcept {
    return d.set_table(velocities, n_v, controls, n_u, forces);
  });
}

int dn_damper_init_neural(const dn_mlp* mlp, const char* const* features, int n_features,
                          const char* const* param_names, const double* param_values, int n_params,
                          int precision, void* mem, size_t bytes, dn_damper** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!mlp) return DN_E_NULL;
  return damper_init(mem, bytes, out, [&](dampnet::Damper& d) noexcept {
    d.md = mlp->md;
    d.mf = mlp->mf;
    return d.set_neural_features(features, n_features, param_names, param_values, n_params, precision);
  });
}

int dn_damper_init_callback(dn_damper_fn fn, void* user, void* mem, size_t bytes, dn_damper** out) {
  return damper_init(mem, bytes, out, [&](dampnet::Damper& d) noexcept { return d.set_callback(fn, user); });
}

int dn_damper_create_linear(double c, dn_damper** out) {
  return dn_storage::create(out, [&](void* m, size_t b, dn_damper** o) noexcept {
    return dn_damper_init_linear(c, m, b, o);
  });
}

int dn_damper_create_parametric(const dn_parametric_params* p, dn_damper** out) {
  return dn_storage::create(out, [&](void* m, size_t b, dn_damper** o) noexcept {
    return dn_damper_init_parametric(p, m, b, o);
  });
}

int dn_damper_create_table(const double* velocities, int n_v, const double* controls, int n_u,
                           const double* forces, dn_damper** out) {
  return dn_storage::create(out, [&](void* m, size_t b, dn_damper** o) noexcept {
    return dn_damper_init_table(velocities, n_v, controls, n_u, forces, m, b, o);
  });
}

int dn_damper_create_neural(const dn_mlp* mlp, const char* const* features, int n_features,
                            const char* const* param_names, const double* param_values,
                            int n_params, int precision, dn_damper** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!mlp) return DN_E_NULL;
  return dn_storage::create(out, [&](void* m, size_t b, dn_damper** o) noexcept {
    return dn_damper_init_neural(mlp, features, n_features, param_names, param_values, n_params,
                                 precision, m, b, o);
  });
}

int dn_damper_create_callback(dn_damper_fn fn, void* user, dn_damper** out) {
  return dn_storage::create(out, [&](void* m, size_t b, dn_damper** o) noexcept {
    return dn_damper_init_callback(fn, user, m, b, o);
  });
}

int dn_damper_add_term(dn_damper* d, const char* kind, const double* params, int n_params) {
  if (!d || !kind) return DN_E_NULL;
  return d->d.add_term(kind, params, n_params);
}

void dn_damper_destroy(dn_damper* d) { dn_storage::destroy(d); }

int dn_damper_kind_of(const dn_damper* d) { return d ? d->d.kind : DN_E_NULL; }

int dn_damper_force(const dn_damper* d, const dn_damper_input* in, dn_real* force,
                    uint32_t* clamped_mask) {
  if (!d || !in || !force) return DN_E_NULL;
  return d->d.force(*in, force, nullptr, clamped_mask);
}

int dn_damper_terms_grad(const dn_damper* d, const dn_damper_input* in, dn_real* force,
                         dn_real* grad) {
  if (!d || !in || !force) return DN_E_NULL;
  dn_real g[3] = {0, 0, 0};
  const dampnet::Damper& dm = d->d;
  int st = DN_OK;
  *force = 0;
  if (DN_CAP_TERMS > 0 && dm.n_terms > 0) {
    if (!dampnet::terms::inputs_finite(dm.terms, dm.n_terms, *in)) st = DN_E_NONFINITE_INPUT;
    else *force = dampnet::terms::sum_grad(dm.terms, dm.n_terms, *in, g);
    if (st == DN_OK && !(std::isfinite(*force) && std::isfinite(g[0]) && std::isfinite(g[1]) && std::isfinite(g[2]))) {
      st = DN_E_NONFINITE_OUTPUT;
    }
    if (st != DN_OK) {
      *force = 0;
      g[0] = g[1] = g[2] = 0;
    }
  }
  if (grad)
    for (int k = 0; k < 3; ++k) grad[k] = g[k];
  return st;
}

int dn_damper_inverse(const dn_damper* d, const dn_damper_input* in, dn_real force_demand,
                      dn_real* u, dn_real* force, int* n_evals) {
  if (n_evals) *n_evals = 0;
  if (!d || !in || !u || !force) return DN_E_NULL;
  return d->d.inverse(*in, force_demand, u, force, n_evals);
}

int dn_damper_inverse_near(const dn_damper* d, const dn_damper_input* in, dn_real force_demand, dn_real u_start,
                           dn_real* u, dn_real* force, int* n_evals) {
  if (n_evals) *n_evals = 0;
  if (!d || !in || !u || !force) return DN_E_NULL;
  return d->d.inverse_near(*in, force_demand, u_start, u, force, n_evals);
}

int dn_damper_control_range(const dn_damper* d, dn_real* u_min, dn_real* u_max) {
  if (!d || !u_min || !u_max) return DN_E_NULL;
  return d->d.control_range(u_min, u_max);
}

int dn_damper_control_monotonicity(const dn_damper* d, const dn_damper_input* at, dn_real v_min,
                                   dn_real v_max, int n_v, int n_u, dn_real tol_N,
                                   dn_monotonicity* report) {
  if (!d || !at || !report) return DN_E_NULL;
  return d->d.control_monotonicity(*at, v_min, v_max, n_v, n_u, tol_N, report);
}

void dn_vehicle_default(dn_vehicle* v) {
  if (v) *v = dampnet::default_vehicle();
}

void dn_controller_default(dn_controller* c, int kind) {
  if (c) *c = dampnet::default_controller(kind);
}

int dn_vehicle_check(const dn_vehicle* v) { return v ? dampnet::check_vehicle(*v) : int(DN_E_NULL); }

int dn_controller_check(const dn_controller* c) {
  return c ? dampnet::check_controller(*c) : int(DN_E_NULL);
}

size_t dn_loop_model_size(void) { return sizeof(dn_loop_model); }

int dn_loop_model_init(const dn_vehicle* veh, const dn_damper* damper, const dn_controller* ctrl,
                       void* mem, size_t bytes, dn_loop_model** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!veh || !damper) return DN_E_NULL;
  dn_loop_model* m = nullptr;
  int st = dn_storage::place(mem, bytes, out, &m);
  if (st != DN_OK) return st;
  st = m->m.init(*veh, damper->d, controller_or_passive(ctrl));
  if (st == DN_OK) *out = m;
  return st;
}

int dn_loop_model_init_neural(const dn_vehicle* veh, const dn_controller* ctrl,
                              const dn_mlp_folded_f* folded, const char* const* features,
                              int n_features, const char* const* param_names,
                              const double* param_values, int n_params, void* mem, size_t bytes,
                              dn_loop_model** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!veh || !folded) return DN_E_NULL;
  dn_loop_model* m = nullptr;
  int st = dn_storage::place(mem, bytes, out, &m);
  if (st != DN_OK) return st;
  dampnet::Damper& d = m->m.damper;  // built where the model keeps its damper: one copy
  st = d.mf.load_folded(folded);
  if (st == DN_OK) st = d.md.load_folded(folded);
  if (st == DN_OK)
    st = d.set_neural_features(features, n_features, param_names, param_values, n_params, DN_PRECISION_FLOAT);
  if (st == DN_OK) st = m->m.init(*veh, d, controller_or_passive(ctrl));
  if (st == DN_OK) *out = m;
  return st;
}

int dn_loop_model_create(const dn_vehicle* veh, const dn_damper* damper, const dn_controller* ctrl,
                         dn_loop_model** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!veh || !damper) return DN_E_NULL;
  return dn_storage::create(out, [&](void* m, size_t b, dn_loop_model** o) noexcept {
    return dn_loop_model_init(veh, damper, ctrl, m, b, o);
  });
}

void dn_loop_model_destroy(dn_loop_model* m) { dn_storage::destroy(m); }

size_t dn_loop_data_size(void) { return sizeof(dn_loop_data); }

int dn_loop_data_init(const dn_loop_model* m, void* mem, size_t bytes, dn_loop_data** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!m) return DN_E_NULL;
  dn_loop_data* d = nullptr;
  const int st = dn_storage::place(mem, bytes, out, &d);
  if (st != DN_OK) return st;
  dampnet::reset(m->m, d->d);
  *out = d;
  return DN_OK;
}

int dn_loop_data_create(const dn_loop_model* m, dn_loop_data** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!m) return DN_E_NULL;
  return dn_storage::create(out, [&](void* mem, size_t b, dn_loop_data** o) noexcept {
    return dn_loop_data_init(m, mem, b, o);
  });
}

void dn_loop_data_destroy(dn_loop_data* d) { dn_storage::destroy(d); }

int dn_loop_reset(const dn_loop_model* m, dn_loop_data* d) {
  if (!m || !d) return DN_E_NULL;
  dampnet::reset(m->m, d->d);
  return DN_OK;
}

int dn_loop_state_size(void) { return DN_LOOP_STATE_SIZE; }

int dn_loop_get_state(const dn_loop_data* d, dn_real* state) {
  if (!d || !state) return DN_E_NULL;
  for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i) state[i] = d->d.s[i];
  return DN_OK;
}

int dn_loop_set_state(dn_loop_data* d, const dn_real* state) {
  if (!d || !state) return DN_E_NULL;
  for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i)
    if (!std::isfinite(state[i])) return DN_E_NONFINITE_INPUT;
  for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i) d->d.s[i] = state[i];
  return DN_OK;
}

int64_t dn_loop_damper_evals(const dn_loop_data* d) { return d ? d->d.n_evals : int64_t(DN_E_NULL); }

int dn_loop_step(const dn_loop_model* m, dn_loop_data* d, const dn_loop_input* in,
                 dn_loop_out* out) {
  if (!m || !d || !in) return DN_E_NULL;
  return dampnet::step(m->m, d->d, *in, out);
}

int dn_loop_forward(const dn_loop_model* m, const dn_loop_data* d, const dn_loop_input* in,
                    dn_loop_out* out) {
  if (!m || !d || !in) return DN_E_NULL;
  return dampnet::forward(m->m, d->d, *in, out);
}

}  // extern "C"
