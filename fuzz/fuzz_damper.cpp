// libFuzzer harness (b): damper creation of every kind (linear, parametric, table,
// neural with arbitrary feature and parameter names and values, callback) plus
// arbitrary physics terms, then dn_damper_force on arbitrary inputs.
// Asserted (abort otherwise): *out is NULL exactly when creation fails; the kind is
// the one created; a force call returns a status >= 0 with a finite force, or an
// error with the force set to 0 (dampnet.h); a neural clamped mask has no bit
// beyond the model's inputs.
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider f(data, size);
  dn_fuzz::DamperBuf buf;
  if (buf.create(f, /*allow_callback=*/true) != DN_OK) return 0;
  const int n_calls = f.ConsumeIntegralInRange<int>(1, 16);
  const int n_in = buf.mlp ? dn_mlp_n_inputs(buf.mlp) : 0;
  for (int k = 0; k < n_calls; ++k) {
    const dn_damper_input in = dn_fuzz::damper_input(f);
    double force = NAN;
    uint32_t mask = 0xFFFFFFFFu;
    const int st = dn_damper_force(buf.damper, &in, &force, f.ConsumeBool() ? &mask : nullptr);
    if (st >= 0) {
      dn_fuzz::check_finite(force, "non-finite force with a success status", "dn_damper_force", st);
    } else {
      if (st != DN_E_NONFINITE_INPUT && st != DN_E_NONFINITE_OUTPUT)
        dn_fuzz::fail("unexpected error", "dn_damper_force", st);
      if (force != 0.0) dn_fuzz::fail("force not set to 0 on an error", "dn_damper_force", st);
    }
    if (mask != 0xFFFFFFFFu && n_in > 0 && (mask >> n_in) != 0)
      dn_fuzz::fail("mask bit beyond the inputs", "dn_damper_force", st);
  }
  double force;
  const dn_damper_input zero{};
  if (dn_damper_force(buf.damper, nullptr, &force, nullptr) != DN_E_NULL ||
      dn_damper_force(buf.damper, &zero, nullptr, nullptr) != DN_E_NULL ||
      dn_damper_force(nullptr, &zero, &force, nullptr) != DN_E_NULL)
    dn_fuzz::fail("NULL argument not refused", "dn_damper_force", 0);
  return 0;
}
