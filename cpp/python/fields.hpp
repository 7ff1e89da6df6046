// dict -> dn_vehicle / dn_controller for dampnet._core: every field parsed by its own type.
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

inline const EnumName kControllerKinds[] = {
    {"passive", DN_CTRL_PASSIVE},
    {"skyhook_onoff", DN_CTRL_SKYHOOK_ONOFF},
    {"skyhook_continuous", DN_CTRL_SKYHOOK_CONTINUOUS},
    {"groundhook_onoff", DN_CTRL_GROUNDHOOK_ONOFF},
    {"groundhook_continuous", DN_CTRL_GROUNDHOOK_CONTINUOUS},
    {"external", DN_CTRL_EXTERNAL}};
inline const EnumName kIntegrators[] = {{"rk4", DN_INT_RK4}, {"semi_euler", DN_INT_SEMI_EULER}};
inline const EnumName kDamperEvals[] = {{"per_stage", DN_EVAL_PER_STAGE},
                                        {"per_step", DN_EVAL_PER_STEP}};
inline const EnumName kAccelFeatures[] = {
    {"implicit", DN_ACCEL_IMPLICIT}, {"explicit", DN_ACCEL_EXPLICIT}, {"linear", DN_ACCEL_LINEAR}};

// The int fields of DN_VEHICLE_FIELDS / DN_CONTROLLER_FIELDS, each with its own names.
inline const EnumField kEnumFields[] = {
    {"kind", "dn_controller_kind", kControllerKinds, std::size(kControllerKinds)},
    {"integrator", "dn_integrator", kIntegrators, std::size(kIntegrators)},
    {"damper_eval", "dn_damper_eval", kDamperEvals, std::size(kDamperEvals)},
    {"accel_feature", "dn_accel_feature", kAccelFeatures, std::size(kAccelFeatures)}};

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
#undef DNPY_SET_FIELD_
#undef DNPY_FIELD_NAME_

}  // namespace dnpy
