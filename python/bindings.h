// The parts of the _totalgrad extension module (python/module.cc), each
// registering its functions and classes on the module. Records cross into
// Python as JSON text (io/record_format.h's numbers), which the package
// (python/totalgrad/) parses: one format on every path, bit for bit.
#ifndef TOTALGRAD_PYTHON_BINDINGS_H_
#define TOTALGRAD_PYTHON_BINDINGS_H_

#include <pybind11/pybind11.h>

namespace totalgrad::python {

// trial_binding.cc: _TrialRun, _scenes_json, _trial_options, _simulate_json.
void AddTrialBindings(pybind11::module_& module);
// gradient_binding.cc: _Problem (gradient estimates as numpy arrays) and
// _study_json (the error-vs-time study).
void AddGradientBindings(pybind11::module_& module);
// results_binding.cc: _Connection (a coordinator or a database file) and the
// results library's tables over it.
void AddResultsBindings(pybind11::module_& module);

}  // namespace totalgrad::python

#endif  // TOTALGRAD_PYTHON_BINDINGS_H_
