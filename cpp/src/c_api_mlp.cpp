// The MLP behind the C ABI: an opaque handle holding float and double copies.
#include <new>

#include "dampnet/dampnet.h"
#include "dampnet/mlp.hpp"
#include "internal.hpp"

extern "C" {

int dn_mlp_create(const dn_mlp_desc* desc, dn_mlp** out) {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  dn_mlp* m = new (std::nothrow) dn_mlp;
  if (!m) return DN_E_ALLOC;
  int st = m->md.load(desc);
  if (st == DN_OK) st = m->mf.load(desc);
  if (st != DN_OK) {
    delete m;
    return st;
  }
  *out = m;
  return DN_OK;
}

void dn_mlp_destroy(dn_mlp* m) { delete m; }

int dn_mlp_n_inputs(const dn_mlp* m) { return m ? m->md.n_inputs() : DN_E_NULL; }

int dn_mlp_forward(const dn_mlp* m, const double* x, double* y, uint32_t* clamped_mask) {
  if (!m || !x || !y) return DN_E_NULL;
  return m->md.forward(x, y, clamped_mask);
}

int dn_mlp_forward_f(const dn_mlp* m, const float* x, float* y, uint32_t* clamped_mask) {
  if (!m || !x || !y) return DN_E_NULL;
  return m->mf.forward(x, y, clamped_mask);
}

}  // extern "C"
