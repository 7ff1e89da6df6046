// Compiled (not linked) by cpp/embedded/CMakeLists.txt with -Wdouble-promotion -Werror: the
// float kernel's forward passes, as the C ABI and StaticMlp instantiate them, and the set-up from
// a folded float description (load_folded) promote no float to double (on a single-precision FPU
// every double operation is a software routine).
#include "dampnet/mlp.hpp"

extern "C" int dn_check_float_forward(const dampnet::Mlp<float>* m, const float* x, float* y) {
  float g = 0.f;
  int st = m->forward(x, y, nullptr);
  st |= m->forward_grad(x, y, 1, &g, nullptr);
  return st;
}

// Set-up from the folded float description: float comparisons and copies only.
extern "C" int dn_check_float_load_folded(dampnet::Mlp<float>* m, dampnet::StaticMlp<float, 3, 30>* s,
                                          const dn_mlp_folded_f* f) {
  return m->load_folded(f) | s->load_folded(f);
}

extern "C" int dn_check_float_static(const dampnet::StaticMlp<float, 3, 30>* m, const float* x, float* y) {
  float g = 0.f;
  int st = m->forward(x, y, nullptr);
  st |= m->forward_grad(x, y, 1, &g, nullptr);
  return st;
}
