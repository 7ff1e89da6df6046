// The training envelope's check behind the C ABI.
#include "dampnet/dampnet.h"
#include "dampnet/envelope.hpp"
#include "internal.hpp"

extern "C" {

size_t dn_envelope_size(void) { return sizeof(dn_envelope); }

int dn_envelope_init(const dn_envelope_desc* desc, void* mem, size_t bytes, dn_envelope** out) {
  dn_envelope* e = nullptr;
  int st = dn_storage::place(mem, bytes, out, &e);
  if (st != DN_OK) return st;
  st = e->e.load(desc);
  if (st == DN_OK) *out = e;
  return st;
}

int dn_envelope_create(const dn_envelope_desc* desc, dn_envelope** out) {
  return dn_storage::create(out, [&](void* mem, size_t bytes, dn_envelope** o) noexcept {
    return dn_envelope_init(desc, mem, bytes, o);
  });
}

void dn_envelope_destroy(dn_envelope* e) { dn_storage::destroy(e); }

int dn_envelope_n_inputs(const dn_envelope* e) { return e ? e->e.n_inputs() : DN_E_NULL; }

int dn_envelope_check(const dn_envelope* e, const double* x, uint32_t* flags) {
  if (!e || !x || !flags) return DN_E_NULL;
  *flags = e->e.check(x);
  return DN_OK;
}

int dn_envelope_check_f(const dn_envelope* e, const float* x, uint32_t* flags) {
  if (!e || !x || !flags) return DN_E_NULL;
  *flags = e->e.check(x);
  return DN_OK;
}

}  // extern "C"
