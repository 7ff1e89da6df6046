// The damper model as an FMI 2.0 FMU (co-simulation and model exchange): dampnet's runtime (header-only damper and
// MLP kernel) evaluating the model of the generated header "fmu_model.h" (prefix fmu_model),
// behind the FMI 2 C API. Built by dampnet.fmu (python/dampnet/fmu.py), which writes the
// header and modelDescription.xml and compiles this file into binaries/linux64/.
//
// Variables (value references; modelDescription.xml says the same):
//   0 x [m]   1 v [m/s]   2 a [m/s2]   3 u [control unit]   4 temperature [degC]   inputs
//   5 force [N]                                                                    output (Real)
//   6 status (a dampnet status code)   7 clamped_mask (bit i: input i clamped)    outputs (Integer)
// The force is a function of the inputs at the same instant (direct feedthrough): it is
// evaluated whenever an output is read. The model has no state (features derived with a state,
// e.g. voltage_lag, are refused at export), so fmi2DoStep only advances the time, and as a
// model-exchange FMU it has no continuous states and no event indicators.
//
// No exceptions, RTTI or operator new: the binary depends on libc and libm only.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <new>

#include "dampnet/damper.hpp"
#include "fmi2Functions.h"
#include "fmu_model.h"

namespace {

enum Vr { VR_X, VR_V, VR_A, VR_U, VR_TEMP, VR_FORCE, VR_STATUS, VR_MASK, VR_N };

struct Instance {
  dampnet::Damper damper;
  fmi2CallbackFunctions cb;
  char name[128];
  double in[5];  // x, v, a, u, temperature
  double time;
  bool logging;
};

void log_error(Instance* s, const char* msg) {
  if (s && s->cb.logger) s->cb.logger(s->cb.componentEnvironment, s->name, fmi2Error, "error", "%s", msg);
}

// A dampnet status in words (the library's status text is not in this binary: no library).
void log_status(Instance* s, const char* where, int st) {
  char msg[160];
  std::snprintf(msg, sizeof msg, "%s: dampnet status %d (%s)", where, st,
                st == DN_E_NONFINITE_INPUT ? "an input is NaN or infinite"
                : st == DN_E_NONFINITE_OUTPUT ? "the force overflowed"
                : st == DN_E_PARAM ? "a model parameter is out of range"
                : st == DN_E_UNKNOWN_NAME ? "a feature, term or parameter name is unknown"
                : "see dampnet.h");
  log_error(s, msg);
}

// The force and its status / mask at the current inputs.
int evaluate(const Instance* s, double* force, uint32_t* mask) {
  dn_damper_input d{};
  d.x = s->in[VR_X];
  d.v = s->in[VR_V];
  d.a = s->in[VR_A];
  d.u = s->in[VR_U];
  d.u_lag = s->in[VR_U];
  d.temperature = s->in[VR_TEMP];
  d.t = s->time;
  d.dt = 0.0;
  d.stage = 0;
  d.v_lag = s->in[VR_V];
  d.z_fric = 0.0;
  return s->damper.force(d, force, nullptr, mask);
}

}  // namespace

extern "C" {

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t, const fmi2String[]) {
  if (!c) return fmi2Error;
  static_cast<Instance*>(c)->logging = on;
  return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String, const fmi2CallbackFunctions* cb,
                              fmi2Boolean, fmi2Boolean logging) {
  if (!cb || !cb->allocateMemory || !cb->freeMemory) return nullptr;
  auto fail = [&](const char* msg) -> fmi2Component {
    if (cb->logger) cb->logger(cb->componentEnvironment, name ? name : "", fmi2Error, "error", "%s", msg);
    return nullptr;
  };
  if (type != fmi2CoSimulation && type != fmi2ModelExchange)
    return fail("unknown fmi2Type (expected fmi2ModelExchange or fmi2CoSimulation)");
  if (!guid || std::strcmp(guid, FMU_MODEL_ID) != 0)
    return fail("GUID mismatch: the modelDescription.xml is not this binary's (expected the model id " FMU_MODEL_ID ")");
  void* mem = cb->allocateMemory(1, sizeof(Instance));
  if (!mem) return fail("out of memory");
  Instance* s = new (mem) Instance();
  s->cb = *cb;
  std::snprintf(s->name, sizeof s->name, "%s", name ? name : "");
  s->logging = logging;
  s->in[VR_TEMP] = 20.0;
  dampnet::Mlp<double> md;
  dampnet::Mlp<float> mf;
  const dn_mlp_desc desc = FMU_MODEL_DESC_INIT;
  int st = md.load(&desc);
  if (st == DN_OK) st = mf.load(&desc);
  if (st == DN_OK) {
    s->damper.md = md;
    s->damper.mf = mf;
#if FMU_MODEL_N_FEATURE_PARAMS > 0
    st = s->damper.set_neural_features(fmu_model_feature_names, FMU_MODEL_N_INPUTS, fmu_model_feature_param_names,
                                       fmu_model_feature_param_values, FMU_MODEL_N_FEATURE_PARAMS, DN_PRECISION_DOUBLE);
#else
    st = s->damper.set_neural_features(fmu_model_feature_names, FMU_MODEL_N_INPUTS, nullptr, nullptr, 0,
                                       DN_PRECISION_DOUBLE);
#endif
  }
#if FMU_MODEL_N_TERMS > 0
  for (int k = 0; k < FMU_MODEL_N_TERMS && st == DN_OK; ++k)
    st = s->damper.add_term(fmu_model_term_kinds[k], fmu_model_term_params + k * FMU_MODEL_TERM_PARAMS,
                            fmu_model_term_n_params[k]);
#endif
  if (st != DN_OK) {
    log_status(s, "fmi2Instantiate", st);
    s->~Instance();
    cb->freeMemory(mem);
    return nullptr;
  }
  return s;
}

void fmi2FreeInstance(fmi2Component c) {
  if (!c) return;
  Instance* s = static_cast<Instance*>(c);
  const fmi2CallbackFreeMemory free_memory = s->cb.freeMemory;
  s->~Instance();
  free_memory(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean, fmi2Real, fmi2Real start, fmi2Boolean, fmi2Real) {
  if (!c) return fmi2Error;
  static_cast<Instance*>(c)->time = start;
  return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2Terminate(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2Reset(fmi2Component c) {
  if (!c) return fmi2Error;
  Instance* s = static_cast<Instance*>(c);
  for (double& x : s->in) x = 0.0;
  s->in[VR_TEMP] = 20.0;
  s->time = 0.0;
  return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
  if (!c || (n && (!vr || !value))) return fmi2Error;
  Instance* s = static_cast<Instance*>(c);
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] < VR_FORCE) {
      value[i] = s->in[vr[i]];
    } else if (vr[i] == VR_FORCE) {
      double f = 0.0;
      uint32_t mask = 0;
      const int st = evaluate(s, &f, &mask);
      if (st < 0) {
        log_status(s, "fmi2GetReal force", st);
        return fmi2Error;
      }
      value[i] = f;
    } else {
      log_error(s, "fmi2GetReal: no Real variable with this value reference");
      return fmi2Error;
    }
  }
  return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
  if (!c || (n && (!vr || !value))) return fmi2Error;
  Instance* s = static_cast<Instance*>(c);
  for (size_t i = 0; i < n; ++i) {
    double f = 0.0;
    uint32_t mask = 0;
    const int st = evaluate(s, &f, &mask);
    if (vr[i] == VR_STATUS) value[i] = st;
    else if (vr[i] == VR_MASK) value[i] = static_cast<fmi2Integer>(mask);
    else {
      log_error(s, "fmi2GetInteger: no Integer variable with this value reference");
      return fmi2Error;
    }
  }
  return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference[], size_t n, fmi2Boolean[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference[], size_t n, fmi2String[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
  if (!c || (n && (!vr || !value))) return fmi2Error;
  Instance* s = static_cast<Instance*>(c);
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] >= VR_FORCE) {
      log_error(s, "fmi2SetReal: only the inputs x, v, a, u, temperature can be set");
      return fmi2Error;
    }
    s->in[vr[i]] = value[i];
  }
  return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference[], size_t n, const fmi2Integer[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference[], size_t n, const fmi2Boolean[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference[], size_t n, const fmi2String[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}

// FMU states are not supported (canGetAndSetFMUstate="false").
fmi2Status fmi2GetFMUstate(fmi2Component, fmi2FMUstate*) { return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component, fmi2FMUstate) { return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component, fmi2FMUstate*) { return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component, fmi2FMUstate, size_t*) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component, fmi2FMUstate, fmi2Byte[], size_t) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component, const fmi2Byte[], size_t, fmi2FMUstate*) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component, const fmi2ValueReference[], size_t, const fmi2ValueReference[],
                                        size_t, const fmi2Real[], fmi2Real[]) {
  return fmi2Error;
}

// Co-simulation.
fmi2Status fmi2SetRealInputDerivatives(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[],
                                       const fmi2Real[]) {
  return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[],
                                        fmi2Real[]) {
  return fmi2Error;
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean) {
  if (!c) return fmi2Error;
  Instance* s = static_cast<Instance*>(c);
  if (!(h > 0) || !std::isfinite(t + h)) {
    log_error(s, "fmi2DoStep: the communication step must be a finite step > 0 s");
    return fmi2Error;
  }
  s->time = t + h;
  return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component, const fmi2StatusKind, fmi2Status*) { return fmi2Discard; }
fmi2Status fmi2GetRealStatus(fmi2Component, const fmi2StatusKind, fmi2Real*) { return fmi2Discard; }
fmi2Status fmi2GetIntegerStatus(fmi2Component, const fmi2StatusKind, fmi2Integer*) { return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component, const fmi2StatusKind, fmi2Boolean*) { return fmi2Discard; }
fmi2Status fmi2GetStringStatus(fmi2Component, const fmi2StatusKind, fmi2String*) { return fmi2Discard; }

// Model exchange: no continuous states, no event indicators, no events of its own.
fmi2Status fmi2EnterEventMode(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* info) {
  if (!c || !info) return fmi2Error;
  info->newDiscreteStatesNeeded = fmi2False;
  info->terminateSimulation = fmi2False;
  info->nominalsOfContinuousStatesChanged = fmi2False;
  info->valuesOfContinuousStatesChanged = fmi2False;
  info->nextEventTimeDefined = fmi2False;
  info->nextEventTime = 0.0;
  return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean, fmi2Boolean* enter_event, fmi2Boolean* terminate) {
  if (!c || !enter_event || !terminate) return fmi2Error;
  *enter_event = fmi2False;
  *terminate = fmi2False;
  return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
  if (!c) return fmi2Error;
  static_cast<Instance*>(c)->time = t;
  return fmi2OK;
}
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real[], size_t nx) { return c && nx == 0 ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real[], size_t nx) { return c && nx == 0 ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real[], size_t ni) { return c && ni == 0 ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real[], size_t nx) { return c && nx == 0 ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real[], size_t nx) {
  return c && nx == 0 ? fmi2OK : fmi2Error;
}

}  // extern "C"
