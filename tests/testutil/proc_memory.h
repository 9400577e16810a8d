// A process's memory as Linux reports it in /proc/<pid>/status, for tests
// and benchmarks (header only, no gtest: bench/service/load_bench.cc uses it
// too).
#ifndef TOTALGRAD_TESTS_TESTUTIL_PROC_MEMORY_H_
#define TOTALGRAD_TESTS_TESTUTIL_PROC_MEMORY_H_

#include <sys/types.h>

#include <fstream>
#include <string>

namespace totalgrad::testing {

inline constexpr pid_t kThisProcess = 0;

// Field `field` of /proc/<pid>/status (of this process with kThisProcess) in
// MB: "VmRSS" is the resident set now, "VmHWM" its peak. -1 if there is no
// such process or field.
inline double ProcStatusMb(pid_t pid, const std::string& field) {
  std::ifstream status(pid == kThisProcess ? std::string("/proc/self/status")
                                           : "/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind(field + ":", 0) == 0) return std::stod(line.substr(field.size() + 1)) / 1024;
  }
  return -1;
}

// Starts the process's peak (VmHWM) again from its resident size now, so
// that a later VmHWM is the peak of what came after (Linux's clear_refs "5";
// the process must be this user's).
inline void ResetPeakResidentMemory(pid_t pid) {
  std::ofstream(pid == kThisProcess ? std::string("/proc/self/clear_refs")
                                    : "/proc/" + std::to_string(pid) + "/clear_refs")
      << "5";
}

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_TESTUTIL_PROC_MEMORY_H_
