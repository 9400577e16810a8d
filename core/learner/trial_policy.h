// The policy a trial learns, of the class its options name (trial option
// `policy`, policy/policy_class.h): the RBF network or PILCO's linear
// policy, on the trial's policy inputs (the raw state, or its angle
// features). One parameter vector either way: what checkpoints, snapshots
// and episode records keep, and what PILCO's propagation and the particle
// estimators read in their own forms.
//
// Thread safety: const methods are thread-safe.
#ifndef TOTALGRAD_CORE_LEARNER_TRIAL_POLICY_H_
#define TOTALGRAD_CORE_LEARNER_TRIAL_POLICY_H_

#include <memory>
#include <optional>
#include <vector>

#include "core/common/thread_pool.h"
#include "core/common/types.h"
#include "core/estimators/particle_system.h"
#include "core/policy/linear_policy.h"
#include "core/policy/policy_class.h"
#include "core/policy/rbf_policy.h"
#include "core/tasks/scene.h"

namespace totalgrad::learner {

class TrialPolicy {
 public:
  // kRbf: num_basis centres on input_dim inputs; kLinear: num_basis is not
  // read. F = max_control.size() controls. Parameters start at zero.
  TrialPolicy(policy::PolicyClass policy_class, int num_basis, int input_dim,
              const Vector& max_control);

  policy::PolicyClass policy_class() const { return policy_class_; }
  int input_dim() const;
  int num_parameters() const;
  const Vector& parameters() const;
  void set_parameters(const Vector& p);  // size must be num_parameters()

  // The policy of its class (CHECK-fails on the other class).
  policy::RbfPolicy& rbf();
  const policy::RbfPolicy& rbf() const;
  policy::LinearPolicy& linear();

  // Controls of P inputs (P x input_dim) into *controls (P F, particle-major).
  void Evaluate(const ConstRowMatrixRef& inputs, Vector* controls) const;
  // The estimators' form of this policy (non-owning: this must outlive it);
  // `pool` (may be null) as RbfParticlePolicy's.
  std::unique_ptr<estimators::ParticlePolicy> ParticleForm(ThreadPool* pool) const;

 private:
  policy::PolicyClass policy_class_;
  std::optional<policy::RbfPolicy> rbf_;
  std::optional<policy::LinearPolicy> linear_;
};

// The policy as a controller of the real plant: its controls at
// phi(observation), phi the angle features of angle_indices (empty: the raw
// observation). `policy` non-null, must outlive the controller.
tasks::MultiController FeaturePolicyController(const TrialPolicy* policy,
                                               std::vector<int> angle_indices);

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_TRIAL_POLICY_H_
