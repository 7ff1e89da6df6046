// dict <-> dn_vehicle / dn_controller for dampnet._core, and their validation with the field
// named (raise_if_invalid: the runtime's dn_vehicle_check / dn_controller_check, used by
// LoopModel and by check_vehicle / check_controller). Every field parsed by its own type.
// Enum fields go through their own enum's name table (a name of another enum, e.g.
// controller kind "per_step", is an error, not the other enum's value); numbers must be
// real numbers (not str, bool or None); unknown and non-string keys are refused. Errors
// are ValueError (a bad value) or TypeError (a value of the wrong type) naming the field.
#pragma once

#include <pybind11/pybind11.h>

#include <cmath>
#include <cstddef>
#include <iterator>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "dampnet/dampnet.h"

namespace dnpy {

namespace py = pybind11;

struct EnumName {
  const char* name;
  int value;
};
struct EnumField {
  const char* field;  // the dict key
  const char* type;   // the C enum, for messages
  const EnumName* names;
  std::size_t n;
};

// The name tables, expanded from dampnet.h's lists (one spelling per value, never retyped).
#define DNPY_ENUM_NAME_(id, value, name, doc) {name, value},
inline const EnumName kControllerKinds[] = {DN_CONTROLLER_KIND_LIST(DNPY_ENUM_NAME_)};
inline const EnumName kIntegrators[] = {DN_INTEGRATOR_LIST(DNPY_ENUM_NAME_)};
inline const EnumName kDamperEvals[] = {DN_DAMPER_EVAL_LIST(DNPY_ENUM_NAME_)};
inline const EnumName kAccelFeatures[] = {DN_ACCEL_FEATURE_LIST(DNPY_ENUM_NAME_)};
inline const EnumName kActivations[] = {DN_ACTIVATION_LIST(DNPY_ENUM_NAME_)};
inline const EnumName kTyreModels[] = {DN_TYRE_MODEL_LIST(DNPY_ENUM_NAME_)};
inline const EnumName kSteerModes[] = {DN_STEER_MODE_LIST(DNPY_ENUM_NAME_)};
#undef DNPY_ENUM_NAME_

// The enum fields (those of DN_VEHICLE_FIELDS / DN_CONTROLLER_FIELDS and Mlp's activation),
// each with its own names.
inline const EnumField kEnumFields[] = {
    {"kind", "dn_controller_kind", kControllerKinds, std::size(kControllerKinds)},
    {"integrator", "dn_integrator", kIntegrators, std::size(kIntegrators)},
    {"damper_eval", "dn_damper_eval", kDamperEvals, std::size(kDamperEvals)},
    {"accel_feature", "dn_accel_feature", kAccelFeatures, std::size(kAccelFeatures)},
    {"activation", "dn_activation", kActivations, std::size(kActivations)},
    {"tyre_model", "dn_tyre_model", kTyreModels, std::size(kTyreModels)},
    {"steer_mode", "dn_steer_mode", kSteerModes, std::size(kSteerModes)}};

inline const EnumField& enum_field(const char* field) {
  for (const auto& f : kEnumFields)
    if (std::string(f.field) == field) return f;
  throw std::logic_error(std::string("dampnet._core: no name table for enum field ") + field);
}

// "'rk4' (0), 'semi_euler' (1)"
inline std::string valid_names(const EnumField& f) {
  std::string s;
  for (std::size_t i = 0; i < f.n; ++i)
    s += (i ? ", '" : "'") + std::string(f.names[i].name) + "' (" + std::to_string(f.names[i].value) + ")";
  return s;
}

// A short description of a Python value for messages: its type and a bounded repr.
inline std::string describe(py::handle h) {
  std::string r;
  try {
    r = py::repr(h).cast<std::string>();
  } catch (const std::exception&) {  // a repr that raises or is not text
    PyErr_Clear();
    r = "<unprintable>";
  }
  if (r.size() > 60) r = r.substr(0, 57) + "...";
  return std::string(Py_TYPE(h.ptr())->tp_name) + " " + r;
}

// A str as UTF-8, at most 60 characters of it for a message (a lone surrogate, which
// has no UTF-8: ValueError).
inline std::string text_of(py::handle h, const std::string& where, bool shorten) {
  Py_ssize_t n = 0;
  const char* u = PyUnicode_AsUTF8AndSize(h.ptr(), &n);
  if (!u) {
    PyErr_Clear();
    throw py::value_error(where + ": not valid text (unpaired surrogate)");
  }
  std::string t(u, static_cast<std::size_t>(n));
  return shorten && t.size() > 60 ? t.substr(0, 57) + "..." : t;
}

// The text of the Python error now set (and clear it), for a message's tail.
inline std::string take_error_text() {
  py::error_already_set e;  // fetches and clears the current Python error
  std::string text = e.type().attr("__name__").cast<std::string>();
  try {
    text += ": " + py::str(e.value()).cast<std::string>();
  } catch (const std::exception&) {
    PyErr_Clear();
  }
  return text.size() > 200 ? text.substr(0, 197) + "..." : text;
}

// An enum field: one of its own names, or its integer value (an int or numpy integer).
inline int parse_enum(py::handle h, const char* what, const char* field) {
  const EnumField& f = enum_field(field);
  const std::string where = std::string(what) + " '" + field + "'";
  if (PyUnicode_Check(h.ptr())) {
    const std::string v = text_of(h, where, false);
    for (std::size_t i = 0; i < f.n; ++i)
      if (v == f.names[i].name) return f.names[i].value;
    throw py::value_error(where + ": unknown name '" + text_of(h, where, true) + "' for a " +
                          f.type + "; valid: " + valid_names(f));
  }
  if (!PyBool_Check(h.ptr()) && PyIndex_Check(h.ptr())) {
    py::object i = py::reinterpret_steal<py::object>(PyNumber_Index(h.ptr()));
    int overflow = 0;
    const long long v = i ? PyLong_AsLongLongAndOverflow(i.ptr(), &overflow) : -1;
    if (!i || (v == -1 && PyErr_Occurred())) throw py::type_error(where + ": " + take_error_text());
    for (std::size_t k = 0; k < f.n && !overflow; ++k)
      if (v == f.names[k].value) return f.names[k].value;
    throw py::value_error(where + " = " + (overflow ? describe(h) : std::to_string(v)) + " is not a " +
                          f.type + " (DN_E_PARAM); valid: " + valid_names(f));
  }
  throw py::type_error(where + ": expected a name (" + valid_names(f) + "), got " + describe(h));
}

// A real-number field: int, float or anything with __float__ except str, bytes, bool and
// None. NaN and Inf pass (the runtime refuses them with DN_E_NONFINITE_PARAM).
inline double parse_number(py::handle h, const char* what, const char* field, const char* doc) {
  const std::string where = std::string(what) + " '" + field + "' (" + doc + ")";
  PyObject* p = h.ptr();
  if (PyUnicode_Check(p) || PyBytes_Check(p) || PyByteArray_Check(p) || PyBool_Check(p) || h.is_none())
    throw py::type_error(where + ": expected a number, got " + describe(h));
  const double v = PyFloat_AsDouble(p);
  if (v == -1.0 && PyErr_Occurred()) {
    const bool overflow = PyErr_ExceptionMatches(PyExc_OverflowError);
    const std::string why = take_error_text();
    if (overflow) throw py::value_error(where + ": out of the range of a double (" + why + ")");
    throw py::type_error(where + ": expected a number, got " + describe(h) + " (" + why + ")");
  }
  return v;
}

inline std::string key_of(py::handle k, const char* what) {
  if (!PyUnicode_Check(k.ptr()))
    throw py::type_error(std::string(what) + ": parameter names are strings, got " + describe(k));
  return text_of(k, what, true);  // a longer name is unknown anyway: echoed shortened
}

// A shallow copy to iterate over: a value's __float__ may change the caller's dict.
inline py::dict dict_copy(const py::dict& d) {
  PyObject* c = PyDict_Copy(d.ptr());
  if (!c) throw py::error_already_set();
  return py::reinterpret_steal<py::dict>(c);
}

#define DNPY_FIELD_NAME_(type, name, def, doc) " " #name
#define DNPY_SET_FIELD_(type, name, def, doc)                                        \
  if (k == #name) {                                                                  \
    if constexpr (std::is_same<type, int>::value) s.name = parse_enum(kv.second, what, #name); \
    else s.name = parse_number(kv.second, what, #name, doc);                         \
    continue;                                                                        \
  }

// Each key of d into its field of the vehicle; unknown keys are refused.
inline void set_vehicle_fields(dn_vehicle& s, const py::dict& d, const char* what) {
  for (auto kv : dict_copy(d)) {
    const std::string k = key_of(kv.first, what);
    DN_VEHICLE_FIELDS(DNPY_SET_FIELD_)
    throw py::value_error(std::string(what) + ": unknown parameter '" + k +
                          "'; known:" DN_VEHICLE_FIELDS(DNPY_FIELD_NAME_));
  }
}

inline void set_controller_fields(dn_controller& s, const py::dict& d, const char* what) {
  for (auto kv : dict_copy(d)) {
    const std::string k = key_of(kv.first, what);
    DN_CONTROLLER_FIELDS(DNPY_SET_FIELD_)
    throw py::value_error(std::string(what) + ": unknown parameter '" + k +
                          "'; known:" DN_CONTROLLER_FIELDS(DNPY_FIELD_NAME_));
  }
}
inline void set_fullcar_fields(dn_fullcar_params& s, const py::dict& d, const char* what) {
  for (auto kv : dict_copy(d)) {
    const std::string k = key_of(kv.first, what);
    DN_FULLCAR_FIELDS(DNPY_SET_FIELD_)
    throw py::value_error(std::string(what) + ": unknown parameter '" + k +
                          "'; known:" DN_FULLCAR_FIELDS(DNPY_FIELD_NAME_));
  }
}
#undef DNPY_SET_FIELD_
#undef DNPY_FIELD_NAME_

// struct -> dict (LoopModel.vehicle / .controller): every field by its X-macro name.
inline py::dict vehicle_dict(const dn_vehicle& s) {
  py::dict d;
#define DNPY_GET_(type, name, def, doc) d[#name] = s.name;
  DN_VEHICLE_FIELDS(DNPY_GET_)
  return d;
}

inline py::dict controller_dict(const dn_controller& s) {
  py::dict d;
  DN_CONTROLLER_FIELDS(DNPY_GET_)
  return d;
}

inline py::dict fullcar_dict(const dn_fullcar_params& s) {
  py::dict d;
  DN_FULLCAR_FIELDS(DNPY_GET_)
#undef DNPY_GET_
  return d;
}

// A vehicle / controller dict on the runtime's defaults (a controller on its kind's).
inline dn_vehicle vehicle_from(const py::dict& d) {
  dn_vehicle v;
  dn_vehicle_default(&v);
  set_vehicle_fields(v, d, "vehicle");
  return v;
}

inline dn_controller controller_from(const py::dict& d) {
  int kind = DN_CTRL_PASSIVE;
  if (d.contains("kind")) kind = parse_enum(d["kind"], "controller", "kind");
  dn_controller c;
  dn_controller_default(&c, kind);  // the law's defaults, then the given fields
  set_controller_fields(c, d, "controller");
  return c;
}

// The runtime's own validation (dn_vehicle_check / dn_controller_check, as
// dn_loop_model_create) says only that some parameter is out of range. Name the field:
// the first given one that, put back to its default, makes both valid; else the first
// given one that alone, on the defaults, is invalid. "" if neither finds one.
// "vehicle 'dt' = 1.0 (step [s], 1e-9 <= dt <= 0.1): "
inline std::string culprit(const py::dict& vehicle, const dn_vehicle& veh, const py::dict& controller,
                           const dn_controller& ctrl) {
  dn_vehicle vdef;
  dn_vehicle_default(&vdef);
  dn_controller cdef;
  dn_controller_default(&cdef, ctrl.kind);
  auto valid = [](const dn_vehicle& v, const dn_controller& c) {
    return dn_vehicle_check(&v) >= 0 && dn_controller_check(&c) >= 0;
  };
  auto named = [](const char* what, const char* name, double value, const char* doc) {
    return std::string(what) + " '" + name + "' = " + py::str(py::float_(value)).cast<std::string>() +
           " (" + doc + "): ";
  };
  // kind sets the controller's defaults: it is never the culprit of a range error
#define DNPY_REVERT_VEHICLE_(type, name, def, doc)                         \
  if (vehicle.contains(#name)) {                                         \
    dn_vehicle trial = veh;                                              \
    trial.name = vdef.name;                                              \
    if (valid(trial, ctrl)) return named("vehicle", #name, veh.name, doc); \
  }
#define DNPY_REVERT_CONTROLLER_(type, name, def, doc)                              \
  if (controller.contains(#name) && std::string(#name) != "kind") {              \
    dn_controller trial = ctrl;                                                  \
    trial.name = cdef.name;                                                      \
    if (valid(veh, trial)) return named("controller", #name, ctrl.name, doc);    \
  }
#define DNPY_ALONE_VEHICLE_(type, name, def, doc)                               \
  if (vehicle.contains(#name)) {                                                \
    dn_vehicle trial = vdef;                                                    \
    trial.name = veh.name;                                                      \
    if (dn_vehicle_check(&trial) < 0) return named("vehicle", #name, veh.name, doc); \
  }
#define DNPY_ALONE_CONTROLLER_(type, name, def, doc)                                     \
  if (controller.contains(#name) && std::string(#name) != "kind") {                     \
    dn_controller trial = cdef;                                                         \
    trial.name = ctrl.name;                                                             \
    if (dn_controller_check(&trial) < 0) return named("controller", #name, ctrl.name, doc); \
  }
  DN_VEHICLE_FIELDS(DNPY_REVERT_VEHICLE_)
  DN_CONTROLLER_FIELDS(DNPY_REVERT_CONTROLLER_)
  DN_VEHICLE_FIELDS(DNPY_ALONE_VEHICLE_)
  DN_CONTROLLER_FIELDS(DNPY_ALONE_CONTROLLER_)
#undef DNPY_REVERT_VEHICLE_
#undef DNPY_REVERT_CONTROLLER_
#undef DNPY_ALONE_VEHICLE_
#undef DNPY_ALONE_CONTROLLER_
  return "";
}

// ValueError naming the field when the runtime refuses a vehicle with a controller.
inline void raise_if_invalid(const char* what, const py::dict& vehicle, const dn_vehicle& veh,
                             const py::dict& controller, const dn_controller& ctrl) {
  int st = dn_vehicle_check(&veh);
  if (st >= 0) st = dn_controller_check(&ctrl);
  if (st < 0)
    throw py::value_error(std::string(what) + culprit(vehicle, veh, controller, ctrl) +
                          dn_status_str(st));
}

}  // namespace dnpy
