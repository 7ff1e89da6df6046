// Dampers, controllers and the quarter-car loop behind the C ABI.
#include <cstddef>
#include <new>

#include "dampnet/dampnet.h"
#include "internal.hpp"

// The ABI: fields of 0.1 keep their offsets (0.2 appended v_lag, z_fric); the state
// size is the length of its list.
static_assert(offsetof(dn_damper_input, u_lag) == 4 * sizeof(double), "dn_damper_input 0.1 layout");
static_assert(offsetof(dn_damper_input, temperature) == 5 * sizeof(double), "dn_damper_input 0.1 layout");
static_assert(offsetof(dn_damper_input, dt) == 7 * sizeof(double), "dn_damper_input 0.1 layout");
static_assert(offsetof(dn_damper_input, stage) == 8 * sizeof(double), "dn_damper_input 0.1 layout");
static_assert(offsetof(dn_damper_input, v_lag) > offsetof(dn_damper_input, stage), "0.2 fields appended");
static_assert(offsetof(dn_controller, c_max) == 9 * sizeof(double), "dn_controller 0.2 layout");
static_assert(offsetof(dn_controller, u_tau_s) == 10 * sizeof(double), "0.3 field appended");
#define DN_STATE_COUNT_(i, name, doc) +1
static_assert(DN_LOOP_STATE_SIZE == 0 DN_LOOP_STATE_LIST(DN_STATE_COUNT_), "DN_LOOP_STATE_SIZE");
#undef DN_STATE_COUNT_

namespace {
template <class T>
int make(T** out) {
  if (!out) return DN_E_NULL;
  *out = new (std::nothrow) T;
  return *out ? int(DN_OK) : int(DN_E_ALLOC);
}
template <class T>
int finish(T** out, int st) {
  if (st != DN_OK) {
    delete *out;
    *out = nullptr;
  }
  return st;
}
}  // namespace

extern "C" {

int dn_damper_create_linear(double c, dn_damper** out) {
  int st = make(out);
  if (st != DN_OK) return st;
  return finish(out, (*out)->d.set_linear(c));
}

int dn_damper_create_parametric(const dn_parametric_params* p, dn_damper** out) {
  int st = make(out);
  if (st != DN_OK) return st;
  return finish(out, (*out)->d.set_parametric(p));
}

int dn_damper_create_table(const double* velocities, int n_v, const double* controls, int n_u,
                           const double* forces, dn_damper** out) {
  int st = make(out);
  if (st != DN_OK) return st;
  return finish(out, (*out)->d.set_table(velocities, n_v, controls, n_u, forces));
}

int dn_damper_create_neural(const dn_mlp* mlp, const char* const* features, int n_features,
                            const char* const* param_names, const double* param_values,
                            int n_params, int precision, dn_damper** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!mlp) return DN_E_NULL;
  int st = make(out);
  if (st != DN_OK) return st;
  (*out)->d.md = mlp->md;
  (*out)->d.mf = mlp->mf;
  return finish(out, (*out)->d.set_neural_features(features, n_features, param_names,
                                                   param_values, n_params, precision));
}

int dn_damper_create_callback(dn_damper_fn fn, void* user, dn_damper** out) {
  int st = make(out);
  if (st != DN_OK) return st;
  return finish(out, (*out)->d.set_callback(fn, user));
}

int dn_damper_add_term(dn_damper* d, const char* kind, const double* params, int n_params) {
  if (!d || !kind) return DN_E_NULL;
  return d->d.add_term(kind, params, n_params);
}

void dn_damper_destroy(dn_damper* d) { delete d; }

int dn_damper_kind_of(const dn_damper* d) { return d ? d->d.kind : DN_E_NULL; }

int dn_damper_force(const dn_damper* d, const dn_damper_input* in, double* force,
                    uint32_t* clamped_mask) {
  if (!d || !in || !force) return DN_E_NULL;
  return d->d.force(*in, force, nullptr, clamped_mask);
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

int dn_loop_model_create(const dn_vehicle* veh, const dn_damper* damper, const dn_controller* ctrl,
                         dn_loop_model** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!veh || !damper) return DN_E_NULL;
  int st = make(out);
  if (st != DN_OK) return st;
  dn_controller c = dampnet::default_controller(DN_CTRL_PASSIVE);
  if (ctrl) c = *ctrl;
  else c.u_passive = 0.0;
  return finish(out, (*out)->m.init(*veh, damper->d, c));
}

void dn_loop_model_destroy(dn_loop_model* m) { delete m; }

int dn_loop_data_create(const dn_loop_model* m, dn_loop_data** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!m) return DN_E_NULL;
  int st = make(out);
  if (st != DN_OK) return st;
  dampnet::reset(m->m, (*out)->d);
  return DN_OK;
}

void dn_loop_data_destroy(dn_loop_data* d) { delete d; }

int dn_loop_reset(const dn_loop_model* m, dn_loop_data* d) {
  if (!m || !d) return DN_E_NULL;
  dampnet::reset(m->m, d->d);
  return DN_OK;
}

int dn_loop_state_size(void) { return DN_LOOP_STATE_SIZE; }

int dn_loop_get_state(const dn_loop_data* d, double* state) {
  if (!d || !state) return DN_E_NULL;
  for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i) state[i] = d->d.s[i];
  return DN_OK;
}

int dn_loop_set_state(dn_loop_data* d, const double* state) {
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
