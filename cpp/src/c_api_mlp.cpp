// The MLP behind the C ABI: an opaque handle holding float and double copies.
#include <new>

#include "dampnet/dampnet.h"
#include "dampnet/mlp.hpp"
#include "internal.hpp"

extern "C" {

size_t dn_mlp_size(void) { return sizeof(dn_mlp); }

int dn_mlp_init(const dn_mlp_desc* desc, void* mem, size_t bytes, dn_mlp** out) {
  dn_mlp* m = nullptr;
  int st = dn_storage::place(mem, bytes, out, &m);
  if (st != DN_OK) return st;
  st = m->md.load(desc);
  if (st == DN_OK) st = m->mf.load(desc);
  if (st == DN_OK) *out = m;
  return st;
}

int dn_mlp_init_folded(const dn_mlp_folded_f* folded, void* mem, size_t bytes, dn_mlp** out) {
  dn_mlp* m = nullptr;
  int st = dn_storage::place(mem, bytes, out, &m);
  if (st != DN_OK) return st;
  st = m->mf.load_folded(folded);  // validates (float) before the double copy is filled
  if (st == DN_OK) st = m->md.load_folded(folded);
  if (st == DN_OK) *out = m;
  return st;
}

int dn_mlp_create(const dn_mlp_desc* desc, dn_mlp** out) {
  return dn_storage::create(out, [&](void* mem, size_t bytes, dn_mlp** o) noexcept {
    return dn_mlp_init(desc, mem, bytes, o);
  });
}

void dn_mlp_destroy(dn_mlp* m) { dn_storage::destroy(m); }

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
