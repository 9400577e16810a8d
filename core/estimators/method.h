// The policy-gradient methods of the paper's Table 1, as one type: parsed
// from its name once at the edge (CLI flags, sweep files, study files, the
// service's option pairs) and dispatched on by value everywhere else.
//
//   RP GR LR TP GLR GTP GTP+sn DEL   particle estimators (estimators/estimator.h)
//   PILCO                            analytic moment matching (core/pilco),
//                                    run by the learner and the study
//
// Thread safety: free functions and constant tables.
#ifndef TOTALGRAD_CORE_ESTIMATORS_METHOD_H_
#define TOTALGRAD_CORE_ESTIMATORS_METHOD_H_

#include <ostream>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/common/option_table.h"

namespace totalgrad::estimators {

enum class Method { kRp, kGr, kLr, kTp, kGlr, kGtp, kGtpSn, kDel, kPilco };

// Every method with its name, particle methods first in Table 1's order,
// then PILCO. The names are the trial option values of `method`.
const EnumNames<Method>& MethodNames();
// "RP", ..., "PILCO"; "" for a value outside the enum.
std::string MethodName(Method method);
// InvalidArgument "unknown method 'X'; known: RP, GR, ..." for any other text.
absl::StatusOr<Method> ParseMethod(absl::string_view name);

inline bool IsParticleMethod(Method method) { return method != Method::kPilco; }
// The particle methods, in MethodNames() order; and their names (listings,
// test names).
std::vector<Method> ParticleMethods();
std::vector<std::string> ParticleMethodNames();

// Prints MethodName (test names, diagnostics).
std::ostream& operator<<(std::ostream& os, Method method);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_METHOD_H_
