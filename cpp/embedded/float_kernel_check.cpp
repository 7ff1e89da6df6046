// Compiled (not linked) by cpp/embedded/CMakeLists.txt with -Wdouble-promotion -Werror: the
// float kernel's forward passes, as the C ABI and StaticMlp instantiate them, promote no float
// to double (on a single-precision FPU every double operation is a software routine).
#include "dampnet/mlp.hpp"

extern "C" int dn_check_float_forward(const dampnet::Mlp<float>* m, const float* x, float* y) {
  float g = 0.f;
  int st = m->forward(x, y, nullptr);
  st |= m->forward_grad(x, y, 1, &g, nullptr);
  return st;
}

extern "C" int dn_check_float_static(const dampnet::StaticMlp<float, 3, 30>* m, const float* x, float* y) {
  float g = 0.f;
  int st = m->forward(x, y, nullptr);
  st |= m->forward_grad(x, y, 1, &g, nullptr);
  return st;
}
