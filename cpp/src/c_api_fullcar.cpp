// The full vehicle behind the C ABI (dn_fullcar_*; the model is cpp/include/dampnet/fullcar.hpp).
#include <cmath>
#include <new>

#include "dampnet/dampnet.h"
#include "internal.hpp"

#if !DN_LOOP_FLOAT  // the full vehicle is built with double only (dampnet.h)
extern "C" {

void dn_fullcar_default(dn_fullcar_params* p) {
  if (p) *p = dampnet::default_fullcar();
}

int dn_fullcar_check(const dn_fullcar_params* p) {
  return p ? dampnet::check_fullcar(*p) : int(DN_E_NULL);
}

int dn_fullcar_model_create(const dn_fullcar_params* p, const dn_damper* const* dampers,
                            const dn_controller* ctrls, const double* path_x, const double* path_y,
                            int n_path, dn_fullcar_model** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!p || !dampers) return DN_E_NULL;
  const dampnet::Damper* d[DN_FULLCAR_CORNERS];
  for (int i = 0; i < DN_FULLCAR_CORNERS; ++i) {
    if (!dampers[i]) return DN_E_NULL;
    d[i] = &dampers[i]->d;
  }
  dn_fullcar_model* m = new (std::nothrow) dn_fullcar_model;
  if (!m) return DN_E_ALLOC;
  const int st = m->m.init(*p, d, ctrls, path_x, path_y, n_path);
  if (st != DN_OK) {
    delete m;
    return st;
  }
  *out = m;
  return DN_OK;
}

void dn_fullcar_model_destroy(dn_fullcar_model* m) { delete m; }

int dn_fullcar_data_create(const dn_fullcar_model* m, dn_fullcar_data** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!m) return DN_E_NULL;
  dn_fullcar_data* d = new (std::nothrow) dn_fullcar_data;
  if (!d) return DN_E_ALLOC;
  dampnet::reset(m->m, d->d);
  *out = d;
  return DN_OK;
}

void dn_fullcar_data_destroy(dn_fullcar_data* d) { delete d; }

int dn_fullcar_reset(const dn_fullcar_model* m, dn_fullcar_data* d) {
  if (!m || !d) return DN_E_NULL;
  dampnet::reset(m->m, d->d);
  return DN_OK;
}

int dn_fullcar_state_size(void) { return DN_FULLCAR_STATE_SIZE; }

int dn_fullcar_get_state(const dn_fullcar_data* d, double* state) {
  if (!d || !state) return DN_E_NULL;
  for (int i = 0; i < DN_FULLCAR_STATE_SIZE; ++i) state[i] = d->d.s[i];
  return DN_OK;
}

int dn_fullcar_set_state(dn_fullcar_data* d, const double* state) {
  if (!d || !state) return DN_E_NULL;
  for (int i = 0; i < DN_FULLCAR_STATE_SIZE; ++i)
    if (!std::isfinite(state[i])) return DN_E_NONFINITE_INPUT;
  for (int i = 0; i < DN_FULLCAR_STATE_SIZE; ++i) d->d.s[i] = state[i];
  return DN_OK;
}

int64_t dn_fullcar_damper_evals(const dn_fullcar_data* d) {
  return d ? d->d.n_evals : int64_t(DN_E_NULL);
}

int dn_fullcar_step(const dn_fullcar_model* m, dn_fullcar_data* d, const dn_fullcar_input* in,
                    dn_fullcar_out* out) {
  if (!m || !d || !in) return DN_E_NULL;
  return dampnet::step(m->m, d->d, *in, out);
}

int dn_fullcar_forward(const dn_fullcar_model* m, const dn_fullcar_data* d,
                       const dn_fullcar_input* in, dn_fullcar_out* out) {
  if (!m || !d || !in) return DN_E_NULL;
  return dampnet::forward(m->m, d->d, *in, out);
}

}  // extern "C"
#endif  // !DN_LOOP_FLOAT
