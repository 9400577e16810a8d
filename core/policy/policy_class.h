// Which policy a trial learns: the RBF network (policy/rbf_policy.h, the
// default and the paper's) or PILCO's linear policy with saturation
// (policy/linear_policy.h; pilco/linear_policy.h its moment-matched form),
// trial option `policy`. One parameter vector per class, shared by PILCO's
// propagation and the particle methods.
#ifndef TOTALGRAD_CORE_POLICY_POLICY_CLASS_H_
#define TOTALGRAD_CORE_POLICY_POLICY_CLASS_H_

#include "core/common/option_table.h"

namespace totalgrad::policy {

enum class PolicyClass { kRbf, kLinear };

// "rbf", "linear".
inline const EnumNames<PolicyClass>& PolicyClassNames() {
  static const EnumNames<PolicyClass>* names =
      new EnumNames<PolicyClass>{{PolicyClass::kRbf, "rbf"}, {PolicyClass::kLinear, "linear"}};
  return *names;
}

// PILCO's initial linear policy (settings_unicycle.m): W ~ 1e-2 N(0, 1), b = 0.
inline constexpr double kLinearPolicyInitStd = 1e-2;

}  // namespace totalgrad::policy

#endif  // TOTALGRAD_CORE_POLICY_POLICY_CLASS_H_
