// The damper's parameters as both FMUs expose them: the model's feature constants (value
// references 10 + k, the header's order: names sorted) and its physics terms' parameters
// (100 + 10 i + j), their start values from the generated header "fmu_model.h", and the
// damper built from them (validated by the runtime, an invalid value named in the message with
// its FMU name from "fmu_config.h", DNFMU_TERM_PARAM_NAMES, and the runtime's range).
#pragma once

#include <cmath>
#include <cstring>

#include "dampnet/damper.hpp"
#include "dampnet/terms.hpp"
#include "fmu_common.hpp"
#include "fmu_config.h"
#include "fmu_model.h"

#ifndef FMU_MODEL_TERM_PARAMS
#define FMU_MODEL_TERM_PARAMS 1
#endif
#ifndef DNFMU_TERM_PARAM_NAMES  // the FMU's names of the terms' parameters, [term][parameter]
#define DNFMU_TERM_PARAM_NAMES {{""}}
#endif

namespace dnfmu {

class DamperParams {
 public:
  static constexpr unsigned VR_FPARAM = 10, VR_TERM = 100;
  static constexpr int kTerms = FMU_MODEL_N_TERMS;
  static constexpr int kFparams = FMU_MODEL_N_FEATURE_PARAMS;

  // The trained model's values.
  void load_defaults() noexcept {
#if FMU_MODEL_N_FEATURE_PARAMS > 0
    for (int k = 0; k < kFparams; ++k) fparam_[k] = fmu_model_feature_param_values[k];
#endif
#if FMU_MODEL_N_TERMS > 0
    for (int i = 0; i < kTerms; ++i)
      for (int j = 0; j < FMU_MODEL_TERM_PARAMS; ++j) term_[i][j] = fmu_model_term_params[i * FMU_MODEL_TERM_PARAMS + j];
#endif
  }

  // A pointer to the parameter with this value reference, or nullptr.
  double* find(unsigned vr) noexcept {
    if (vr >= VR_FPARAM && vr < VR_FPARAM + unsigned(kFparams)) return &fparam_[vr - VR_FPARAM];
#if FMU_MODEL_N_TERMS > 0
    if (vr >= VR_TERM && vr < VR_TERM + 10u * kTerms) {
      const int i = int(vr - VR_TERM) / 10, j = int(vr - VR_TERM) % 10;
      if (j < fmu_model_term_n_params[i]) return &term_[i][j];
    }
#endif
    return nullptr;
  }
  bool owns(unsigned vr) const noexcept { return const_cast<DamperParams*>(this)->find(vr) != nullptr; }

  // Into `damper` (its MLPs md, mf loaded): the model's features with these constants and its
  // terms with these parameters. On an error `damper` is unchanged and `m` says why.
  int build(dampnet::Damper& damper, Message& m) const noexcept {
    dampnet::Damper d = damper;
    d.n_terms = 0;
#if FMU_MODEL_N_FEATURE_PARAMS > 0
    int st = d.set_neural_features(fmu_model_feature_names, FMU_MODEL_N_INPUTS, fmu_model_feature_param_names, fparam_,
                                   kFparams, DN_PRECISION_DOUBLE);
    if (st == DN_E_PARAM || st == DN_E_NONFINITE_PARAM) {
      for (int k = 0; k < kFparams; ++k)
        if (!(fparam_[k] > 0) || !std::isfinite(fparam_[k]))
          return m.fail(st, "parameter %s = %.12g: must be finite and > 0", fmu_model_feature_param_names[k],
                        fparam_[k]);
    }
#else
    int st = d.set_neural_features(fmu_model_feature_names, FMU_MODEL_N_INPUTS, nullptr, nullptr, 0,
                                   DN_PRECISION_DOUBLE);
#endif
    if (st != DN_OK) return m.fail(st, "the model's features are refused: %s", status_text(st));
#if FMU_MODEL_N_TERMS > 0
    for (int i = 0; i < kTerms; ++i) {
      st = d.add_term(fmu_model_term_kinds[i], term_[i], fmu_model_term_n_params[i]);
      if (st != DN_OK) return explain_term(m, i, st);
    }
#endif
    damper = d;
    return DN_OK;
  }

 private:
#if FMU_MODEL_N_TERMS > 0
  // Why term i's parameters are refused: the first one refused on its own (the others at the
  // trained values), by its FMU name, with the runtime's doc of the kind (its ranges).
  static const char* term_doc(const char* kind) noexcept {
#define DNFMU_TERM_DOC_(id, value, name, n, text) \
  if (std::strcmp(kind, name) == 0) return text;
    DN_TERM_LIST(DNFMU_TERM_DOC_)
#undef DNFMU_TERM_DOC_
    return "";
  }
  int explain_term(Message& m, int i, int st) const noexcept {
    static constexpr const char* names[kTerms][FMU_MODEL_TERM_PARAMS] = DNFMU_TERM_PARAM_NAMES;
    const char* kind = fmu_model_term_kinds[i];
    const int n = fmu_model_term_n_params[i];
    for (int j = 0; j < n; ++j) {
      double trial[FMU_MODEL_TERM_PARAMS];
      for (int k = 0; k < n; ++k) trial[k] = k == j ? term_[i][k] : fmu_model_term_params[i * FMU_MODEL_TERM_PARAMS + k];
      dampnet::Term t;
      const int s = dampnet::terms::make(t, kind, trial, n);
      if (s != DN_OK)
        return m.fail(s, "parameter %s = %.12g is refused (term %d, %s: %s): %s", names[i][j] ? names[i][j] : "?",
                      term_[i][j], i, kind, term_doc(kind), status_text(s));
    }
    return m.fail(st, "term %d (%s): its parameters are refused together (%s): %s", i, kind, term_doc(kind),
                  status_text(st));
  }
#endif

  double fparam_[kFparams > 0 ? kFparams : 1] = {};
  double term_[kTerms > 0 ? kTerms : 1][FMU_MODEL_TERM_PARAMS] = {};
};

}  // namespace dnfmu
