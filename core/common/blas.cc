#include "core/common/blas.h"

#include <dlfcn.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace totalgrad {
namespace {
// Looked up at run time so that core links against any reference BLAS too;
// only OpenBLAS has these entry points.
using SetThreadsFn = void (*)(int);
using ConfigFn = char* (*)();

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// OpenBLAS core names (lower case) whose kernels use AVX-512.
bool IsAvx512Core(const std::string& name) {
  return name == "skylakex" || name == "cooperlake" || name == "sapphirerapids";
}

bool CpuHasSkylakeXFeatures() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
         __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
         __builtin_cpu_supports("avx512vl");
#else
  return false;
#endif
}

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

std::string BlasCoreName() {
  auto fn = reinterpret_cast<ConfigFn>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  if (fn == nullptr) return "unknown";
  const char* name = fn();
  return name != nullptr ? name : "unknown";
}

std::string WantedBlasCore(const char* setting) {
  if (dlsym(RTLD_DEFAULT, "openblas_get_corename") == nullptr) return "";
  const std::string loaded = Lower(BlasCoreName());
  const std::string mode = setting == nullptr ? "" : setting;
  if (mode == "env") return "";
  if (mode.empty() || mode == "auto") {
    if (IsAvx512Core(loaded) || !CpuHasSkylakeXFeatures()) return "";
    return "SkylakeX";
  }
  return Lower(mode) == loaded ? "" : mode;
}

void SelectBlasKernels(char** argv) {
  constexpr char kMarker[] = "TOTALGRAD_BLAS_REEXECUTED";
  if (std::getenv(kMarker) != nullptr) return;
  const std::string core = WantedBlasCore(std::getenv("TOTALGRAD_BLAS_CORE"));
  if (core.empty()) return;
  if (setenv("OPENBLAS_CORETYPE", core.c_str(), 1) != 0 || setenv(kMarker, "1", 1) != 0) return;
  // Through the real path, not /proc/self/exe, so that the process keeps its
  // name (ps, pkill, systemd and Slurm see "totalgrad-worker", not "exe").
  char path[4096];
  const ssize_t length = readlink("/proc/self/exe", path, sizeof(path) - 1);
  if (length <= 0) return;
  path[length] = '\0';
  std::fflush(nullptr);
  execv(path, argv);
  // Only reached when the exec failed: carry on with the kernels already
  // loaded (the variables now describe nothing that took effect).
  const int error = errno;
  std::fprintf(stderr, "totalgrad: note: could not re-execute with OPENBLAS_CORETYPE=%s (%s); "
               "using OpenBLAS's %s kernels\n", core.c_str(), std::strerror(error),
               BlasCoreName().c_str());
}

}  // namespace totalgrad
