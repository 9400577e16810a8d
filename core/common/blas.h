// Control of the BLAS that Eigen calls for large products (OpenBLAS).
//
// A worker runs several trials at once, one per slot, each on one core: the
// BLAS must then not start threads of its own. SetBlasThreads is process-wide.
#ifndef TOTALGRAD_CORE_COMMON_BLAS_H_
#define TOTALGRAD_CORE_COMMON_BLAS_H_

namespace totalgrad {

// Sets the number of threads the BLAS may use (>= 1). Process-wide.
void SetBlasThreads(int threads);

// Name of the BLAS library configuration, for provenance records.
const char* BlasConfig();

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_BLAS_H_
