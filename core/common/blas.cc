#include "core/common/blas.h"

#include <dlfcn.h>

namespace totalgrad {
namespace {
// Looked up at run time so that core links against any reference BLAS too;
// only OpenBLAS has these entry points.
using SetThreadsFn = void (*)(int);
using ConfigFn = char* (*)();
}  // namespace

void SetBlasThreads(int threads) {
  if (threads < 1) threads = 1;
  auto fn = reinterpret_cast<SetThreadsFn>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  if (fn != nullptr) fn(threads);
}

const char* BlasConfig() {
  auto fn = reinterpret_cast<ConfigFn>(dlsym(RTLD_DEFAULT, "openblas_get_config"));
  return fn != nullptr ? fn() : "reference BLAS";
}

}  // namespace totalgrad
