// The extension module behind `import totalgrad` (python/totalgrad/).
#include <pybind11/pybind11.h>

#include "core/common/blas.h"
#include "python/bindings.h"
#include "runtime/build_info.h"

PYBIND11_MODULE(_totalgrad, module) {
  module.doc() = "totalgrad's C++ core, service client and results library (use the "
                 "`totalgrad` package, not this module)";
  // OpenBLAS loaded with this module (or with numpy): its kernels cannot be
  // chosen here as the binaries choose them; the package warns when they
  // differ (python/totalgrad/__init__.py, blas_kernels()).
  module.attr("build") = totalgrad::BuildId();
  totalgrad::python::AddTrialBindings(module);
  totalgrad::python::AddGradientBindings(module);
  totalgrad::python::AddResultsBindings(module);
}
