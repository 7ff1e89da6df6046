// Compiled (not linked) by cpp/embedded/CMakeLists.txt with -Wdouble-promotion -Werror in a
// DN_LOOP_FLOAT build: the loop's step, report, reset and set-up and the damper models promote
// no float to double (on a single-precision FPU every double operation is a software routine).
#include "dampnet/loop.hpp"

#if !DN_LOOP_FLOAT
#error "float_loop_check.cpp is for DN_LOOP_FLOAT builds"
#endif

extern "C" int dn_check_float_loop(dampnet::LoopModel* m, dampnet::LoopData* d, const dn_loop_input* in,
                                   dn_loop_out* out, const dn_vehicle* v, const dampnet::Damper* damper,
                                   const dn_controller* c) {
  int st = m->init(*v, *damper, *c);
  dampnet::reset(*m, *d);
  st |= dampnet::forward(*m, *d, *in, out);
  st |= dampnet::step(*m, *d, *in, out);
  return st;
}

extern "C" int dn_check_float_damper(const dampnet::Damper* damper, const dn_damper_input* in, float* f) {
  float g = 0.f;
  int st = damper->force(*in, f);
  st |= damper->force_da(*in, f, &g);
  return st;
}
