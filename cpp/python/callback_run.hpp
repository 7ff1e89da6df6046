// Where the Python exception of a callback damper goes: the run (simulate, step, forces...)
// that called it, on the calling thread. The C runtime calls the damper's function through a
// C pointer and cannot carry a Python exception, so the trampoline records the first one in
// the innermost CallbackRun of its thread (the C loop calls the damper on the thread that
// runs it) and returns NaN; the run then re-raises it. Per run and per thread, not per damper:
// a damper shared by loops in several threads must not hand one loop's error to another.
#pragma once

#include <pybind11/pybind11.h>

namespace dnpy {

namespace py = pybind11;

class CallbackRun {
 public:
  // Construct and destroy with the GIL held (the recorded exception is a Python object).
  CallbackRun() : prev_(current_) { current_ = this; }
  ~CallbackRun() { current_ = prev_; }
  CallbackRun(const CallbackRun&) = delete;
  CallbackRun& operator=(const CallbackRun&) = delete;

  static CallbackRun* current() { return current_; }
  bool failed() const { return static_cast<bool>(error_); }
  // Record the Python error now set (the first one wins); clears it. GIL held.
  void record_current_error() {
    PyObject *type, *value, *trace;
    PyErr_Fetch(&type, &value, &trace);
    PyErr_NormalizeException(&type, &value, &trace);
    if (value && trace) PyException_SetTraceback(value, trace);  // keep where it was raised
    py::object exc = py::reinterpret_steal<py::object>(value);
    Py_XDECREF(type);
    Py_XDECREF(trace);
    if (!error_ && exc) error_ = std::move(exc);
  }
  // Raise what a callback raised during this run, if anything. GIL held.
  void raise_pending() {
    if (!error_) return;
    py::object e = std::move(error_);
    error_ = py::object();
    PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(e.ptr())), e.ptr());
    throw py::error_already_set();
  }

 private:
  py::object error_;
  CallbackRun* prev_;
  static inline thread_local CallbackRun* current_ = nullptr;
};

}  // namespace dnpy
