// dampnet._core.StepReport: a hand-built CPython type (PyType_FromSpec), not a pybind11
// class. Why: Loop.step returns one per step, and Python code steps the loop at real-time
// rates; a plain CPython object holding the C struct (no pybind11 instance registry,
// pymalloc) costs a few tens of ns to create where a pybind11 instance cost ~150 (and a
// dict more). Attributes are native getters; the mapping methods are pybind11 functions
// set on the type. Every key is expanded from DN_LOOP_OUT_LIST (see step_report.hpp).
#include "step_report.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <cstdint>
#include <iterator>
#include <string>
#include <utility>

#include "arrays.hpp"
#include "common.hpp"

namespace dnpy {

namespace {

// dn_loop_out's scalar quantities (kNumOutQuantities), then the three other keys.
#define DNPY_OUT_NAME_(name, doc) #name,
const char* const kStepKeys[] = {DN_LOOP_OUT_LIST(DNPY_OUT_NAME_) "features", "clamped_mask", "status"};
#undef DNPY_OUT_NAME_
#define DNPY_OUT_DOC_(name, doc) doc,
const char* const kStepDocs[] = {
    DN_LOOP_OUT_LIST(DNPY_OUT_DOC_)
    "a neural damper's inputs before saturation, in its features' order [feature units]; "
    "empty for other dampers",
    "neural: bit i set when input i was clamped or replaced [-]",
    "the step's status: DN_OK, or an OR of DN_W_* warnings [-]"};
#undef DNPY_OUT_DOC_
constexpr std::size_t kFeatures = kNumOutQuantities, kClampedMask = kNumOutQuantities + 1,
                      kStatus = kNumOutQuantities + 2;
static_assert(std::size(kStepKeys) == kNumOutQuantities + 3, "every key has a getter");
static_assert(std::size(kStepDocs) == std::size(kStepKeys), "every key has a doc");

py::array_t<double> features_of(const dn_loop_out& o) {
  py::array_t<double> f(o.n_features);
  for (int i = 0; i < o.n_features; ++i) f.mutable_data()[i] = o.features[i];
  return f;
}

// The value under key number i (kStepKeys).
py::object value_at(const StepReport& r, std::size_t i) {
  if (i < kNumOutQuantities) return py::float_(r.o.*kOutQuantities[i]);
  if (i == kFeatures) return features_of(r.o);
  if (i == kClampedMask) return py::int_(r.o.clamped_mask);
  return py::int_(r.status);
}

// The index of a key, or -1.
std::ptrdiff_t key_index(const std::string& key) {
  for (std::size_t i = 0; i < std::size(kStepKeys); ++i)
    if (key == kStepKeys[i]) return static_cast<std::ptrdiff_t>(i);
  return -1;
}

struct StepReportObject {
  PyObject_HEAD
  StepReport r;
};
PyTypeObject* g_step_report_type = nullptr;

const StepReport& report_of(py::handle h) {
  if (!g_step_report_type || !PyObject_TypeCheck(h.ptr(), g_step_report_type))
    throw py::type_error("expected a StepReport");
  return reinterpret_cast<StepReportObject*>(h.ptr())->r;
}

PyObject* step_report_attr(PyObject* self, void* closure) {
  try {
    const auto i = static_cast<std::size_t>(reinterpret_cast<std::intptr_t>(closure));
    return value_at(reinterpret_cast<StepReportObject*>(self)->r, i).release().ptr();
  } catch (py::error_already_set& e) {
    e.restore();
  } catch (const std::exception& e) {
    PyErr_SetString(PyExc_RuntimeError, e.what());
  }
  return nullptr;
}

void step_report_dealloc(PyObject* self) {
  PyTypeObject* tp = Py_TYPE(self);
  PyObject_Free(self);
  Py_DECREF(tp);  // heap type: every instance holds a reference to it
}

}  // namespace

py::object new_step_report(StepReport** r) {
  auto* obj = PyObject_New(StepReportObject, g_step_report_type);
  if (!obj) throw py::error_already_set();
  py::object owner = py::reinterpret_steal<py::object>(reinterpret_cast<PyObject*>(obj));
  *r = &obj->r;
  return owner;
}

py::dict step_output_fields() {
  py::dict d;
  for (std::size_t i = 0; i < std::size(kStepKeys); ++i) d[kStepKeys[i]] = kStepDocs[i];
  return d;
}

py::dict step_report_dict(const dn_loop_out& o, int status) {
  const StepReport r{o, status};
  py::dict d;
  for (std::size_t i = 0; i < std::size(kStepKeys); ++i) d[kStepKeys[i]] = value_at(r, i);
  return d;
}

void bind_step_report(py::module_& mod) {
  static PyGetSetDef getset[std::size(kStepKeys) + 1] = {};
  for (std::size_t i = 0; i < std::size(kStepKeys); ++i)
    getset[i] = {kStepKeys[i], &step_report_attr, nullptr, nullptr,
                 reinterpret_cast<void*>(static_cast<std::intptr_t>(i))};
  static const char* doc =
      "A step's report (Loop.step): read-only attributes, and a read-only mapping with the "
      "same keys (r['force'], r.keys(), dict(r)); to_dict() gives a plain dict.";
  static PyType_Slot slots[] = {{Py_tp_dealloc, reinterpret_cast<void*>(&step_report_dealloc)},
                                {Py_tp_getset, getset},
                                {Py_tp_doc, const_cast<char*>(doc)},
                                {0, nullptr}};
  unsigned flags = Py_TPFLAGS_DEFAULT;
#ifdef Py_TPFLAGS_DISALLOW_INSTANTIATION
  flags |= Py_TPFLAGS_DISALLOW_INSTANTIATION;
#endif
  static PyType_Spec spec = {"dampnet._core.StepReport", int(sizeof(StepReportObject)), 0, flags,
                             slots};
  py::object tp = py::reinterpret_steal<py::object>(PyType_FromSpec(&spec));
  if (!tp) throw py::error_already_set();
  g_step_report_type = reinterpret_cast<PyTypeObject*>(tp.ptr());
  auto keys = [] {
    py::list k;
    for (const char* name : kStepKeys) k.append(name);
    return k;
  };
  auto index_of = [](py::handle key) -> std::size_t {  // KeyError for anything else
    if (py::isinstance<py::str>(key)) {
      const std::ptrdiff_t i = key_index(key.cast<std::string>());
      if (i >= 0) return static_cast<std::size_t>(i);
      throw py::key_error(key.cast<std::string>());
    }
    throw py::key_error(py::repr(key).cast<std::string>());
  };
  auto method = [&](const char* name, py::cpp_function f) {  // bound like a method
    py::object m = py::reinterpret_steal<py::object>(PyInstanceMethod_New(f.ptr()));
    if (!m) throw py::error_already_set();
    tp.attr(name) = m;
  };
  method("__getitem__", py::cpp_function([index_of](py::handle self, py::handle key) {
           const StepReport& r = report_of(self);
           return value_at(r, index_of(key));
         }));
  method("get", py::cpp_function([](py::handle self, py::handle key, py::object dflt) -> py::object {
           const StepReport& r = report_of(self);
           if (py::isinstance<py::str>(key)) {
             const std::ptrdiff_t i = key_index(key.cast<std::string>());
             if (i >= 0) return value_at(r, static_cast<std::size_t>(i));
           }
           return dflt;
         }, py::arg("self"), py::arg("key"), py::arg("default") = py::none()));
  method("__contains__", py::cpp_function([](py::handle, py::handle key) {
           return py::isinstance<py::str>(key) && key_index(key.cast<std::string>()) >= 0;
         }));
  method("__len__", py::cpp_function([](py::handle) { return std::size(kStepKeys); }));
  method("__iter__", py::cpp_function([keys](py::handle) { return keys().attr("__iter__")(); }));
  method("keys", py::cpp_function([keys](py::handle) { return keys(); }));
  method("values", py::cpp_function([](py::handle self) {
           const StepReport& r = report_of(self);
           py::list v;
           for (std::size_t i = 0; i < std::size(kStepKeys); ++i) v.append(value_at(r, i));
           return v;
         }));
  method("items", py::cpp_function([](py::handle self) {
           const StepReport& r = report_of(self);
           py::list v;
           for (std::size_t i = 0; i < std::size(kStepKeys); ++i)
             v.append(py::make_tuple(kStepKeys[i], value_at(r, i)));
           return v;
         }));
  method("to_dict", py::cpp_function([](py::handle self) {
           const StepReport& r = report_of(self);
           return step_report_dict(r.o, r.status);
         }));
  method("__repr__", py::cpp_function([](py::handle self) {
           const StepReport& r = report_of(self);
           std::string s = "StepReport(";
           for (std::size_t i = 0; i < kNumOutQuantities; ++i)
             s += std::string(kStepKeys[i]) + "=" + py::repr(value_at(r, i)).cast<std::string>() + ", ";
           return s + "status=" + std::to_string(r.status) + ")";
         }));
  mod.attr("StepReport") = tp;
  py::module_::import("collections.abc").attr("Mapping").attr("register")(tp);
  tp.release();  // the module keeps the type alive for g_step_report_type
}

}  // namespace dnpy
