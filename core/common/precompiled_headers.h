// The headers nearly every core/ file parses, compiled once (CMake's
// precompiled header of totalgrad_core_common, reused by every core
// library: cmake/TotalgradHelpers.cmake). Parsing Eigen and abseil took
// 2-5 s of each file's compile; the objects are byte for byte those of a
// build without it (same flags, same headers: docs/results/build/README.md).
// Files still include what they use: a build with
// -DTOTALGRAD_PRECOMPILED_HEADERS=OFF compiles each file on its own.
#ifndef TOTALGRAD_CORE_COMMON_PRECOMPILED_HEADERS_H_
#define TOTALGRAD_CORE_COMMON_PRECOMPILED_HEADERS_H_

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"

#endif  // TOTALGRAD_CORE_COMMON_PRECOMPILED_HEADERS_H_
