// Definitions of the C ABI's opaque handles, shared by the C ABI sources.
#pragma once

#include <cstddef>
#include <cstdint>
#include <new>

#include "dampnet/damper.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/envelope.hpp"
#if !DN_LOOP_FLOAT
#include "dampnet/fullcar.hpp"
#endif
#include "dampnet/loop.hpp"
#include "dampnet/mlp.hpp"

struct dn_mlp {
  dampnet::MlpDouble md;  // Mlp<double> unless DN_DOUBLE_KERNEL is 0
  dampnet::Mlp<float> mf;
};

struct dn_envelope {
  dampnet::Envelope e;
};

struct dn_damper {
  dampnet::Damper d;
};

struct dn_loop_model {
  dampnet::LoopModel m;
};

struct dn_loop_data {
  dampnet::LoopData d;
};

#if !DN_LOOP_FLOAT  // the full vehicle is built with double only
struct dn_fullcar_model {
  dampnet::FullCarModel m;
};

struct dn_fullcar_data {
  dampnet::FullCarData d;
};
#endif

// Caller-provided storage (dn_*_size / dn_*_init) and the heap (dn_*_create / _destroy):
// every create is its init on memory from operator new, so both do the same set-up.
namespace dn_storage {

// Check caller memory for an H and construct an empty H in it (*out stays NULL until the
// caller's set-up succeeded).
template <class H>
inline int place(void* mem, size_t bytes, H** out, H** obj) noexcept {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  if (!mem) return DN_E_NULL;
  if (bytes < sizeof(H)) return DN_E_SIZE;
  if (reinterpret_cast<uintptr_t>(mem) % alignof(H) != 0) return DN_E_PARAM;
  *obj = ::new (mem) H;
  return DN_OK;
}

// create(out, init): init(mem, bytes, out) on heap memory, freed again when init fails.
template <class H, class Init>
inline int create(H** out, Init init) noexcept {
  if (!out) return DN_E_NULL;
  *out = nullptr;
  void* mem = ::operator new(sizeof(H), std::align_val_t(alignof(H)), std::nothrow);
  if (!mem) return DN_E_ALLOC;
  const int st = init(mem, sizeof(H), out);
  if (st != DN_OK) ::operator delete(mem, std::align_val_t(alignof(H)));
  return st;
}

template <class H>
inline void destroy(H* h) noexcept {
  if (!h) return;
  h->~H();
  ::operator delete(h, std::align_val_t(alignof(H)));
}

}  // namespace dn_storage
