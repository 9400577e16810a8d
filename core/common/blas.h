// Control of the BLAS that Eigen calls for large products (OpenBLAS).
//
// A worker runs several trials at once, one per slot, each on one core: the
// BLAS must then not start threads of its own. SetBlasThreads is process-wide.
//
// Kernel choice. OpenBLAS picks its kernels when it loads, from the CPU or
// from the environment variable OPENBLAS_CORETYPE. Which kernels run decides
// both the speed of the GP's products and the last bits of a trial's numbers
// (another summation order), so totalgrad chooses them explicitly, through
// TOTALGRAD_BLAS_CORE, before OpenBLAS is used:
//   auto (default, or unset): on a CPU whose CPU and OS support AVX-512
//        (F, CD, BW, DQ, VL), AVX-512 kernels (OpenBLAS's own AVX-512 choice,
//        or SkylakeX), even when an inherited OPENBLAS_CORETYPE names older
//        ones: they make the GP's products ~1.6x faster
//        (docs/results/speed.md). Elsewhere OpenBLAS's choice stands.
//   env: whatever OpenBLAS chose (from OPENBLAS_CORETYPE or the CPU).
//   NAME (e.g. Haswell, SkylakeX): that OpenBLAS core type, e.g. the same
//        family on every worker of a mixed cluster, so that a job gives the
//        same bits on any of them.
// The choice takes effect by re-executing the program once with
// OPENBLAS_CORETYPE set (SelectBlasKernels). A trial is reproducible per build
// and kernel family; the family is part of the provenance (BlasCoreName).
#ifndef TOTALGRAD_CORE_COMMON_BLAS_H_
#define TOTALGRAD_CORE_COMMON_BLAS_H_

#include <string>

namespace totalgrad {

// Sets the number of threads the BLAS may use (>= 1). Process-wide.
void SetBlasThreads(int threads);

// Name of the BLAS library configuration, for provenance records.
const char* BlasConfig();

// The kernel family OpenBLAS is using (e.g. "Haswell", "SkylakeX"), or
// "unknown" for another BLAS.
std::string BlasCoreName();

// The OpenBLAS core type that TOTALGRAD_BLAS_CORE (value `setting`, see above;
// null or "" = auto) asks for on this CPU, given the core OpenBLAS loaded, or
// "" when the loaded one stands (also for a BLAS that is not OpenBLAS).
std::string WantedBlasCore(const char* setting);

// Call first in main(), before any thread starts. When WantedBlasCore() names
// a core, sets OPENBLAS_CORETYPE to it and re-executes this program (the file
// /proc/self/exe points to) with the same arguments (same pid, descriptors, and environment otherwise); at most
// once per process tree (a marker variable stops a loop). Returns when nothing
// was to be done, or when the re-execution failed (a note on stderr names why;
// the program continues with the kernels already loaded).
void SelectBlasKernels(char** argv);

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_BLAS_H_
