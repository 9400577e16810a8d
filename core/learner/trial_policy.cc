#include "core/learner/trial_policy.h"

#include <utility>

#include "core/common/check.h"
#include "core/gaussian/angle_features.h"

namespace totalgrad::learner {

TrialPolicy::TrialPolicy(policy::PolicyClass policy_class, int num_basis, int input_dim,
                         const Vector& max_control)
    : policy_class_(policy_class) {
  if (policy_class == policy::PolicyClass::kLinear) {
    linear_.emplace(input_dim, max_control);
  } else {
    rbf_.emplace(num_basis, input_dim, max_control);
  }
}

int TrialPolicy::input_dim() const { return rbf_ ? rbf_->state_dim() : linear_->state_dim(); }

int TrialPolicy::num_parameters() const {
  return rbf_ ? rbf_->num_parameters() : linear_->num_parameters();
}

const Vector& TrialPolicy::parameters() const {
  return rbf_ ? rbf_->parameters() : linear_->parameters();
}

void TrialPolicy::set_parameters(const Vector& p) {
  if (rbf_) {
    rbf_->set_parameters(p);
  } else {
    linear_->set_parameters(p);
  }
}

policy::RbfPolicy& TrialPolicy::rbf() {
  TG_CHECK(rbf_.has_value());
  return *rbf_;
}

const policy::RbfPolicy& TrialPolicy::rbf() const {
  TG_CHECK(rbf_.has_value());
  return *rbf_;
}

policy::LinearPolicy& TrialPolicy::linear() {
  TG_CHECK(linear_.has_value());
  return *linear_;
}

void TrialPolicy::Evaluate(const ConstRowMatrixRef& inputs, Vector* controls) const {
  if (rbf_) {
    rbf_->Evaluate(inputs, controls, nullptr);
  } else {
    linear_->Evaluate(inputs, controls, nullptr);
  }
}

std::unique_ptr<estimators::ParticlePolicy> TrialPolicy::ParticleForm(ThreadPool* pool) const {
  if (rbf_) return std::make_unique<estimators::RbfParticlePolicy>(&*rbf_, pool);
  return std::make_unique<estimators::LinearParticlePolicy>(&*linear_);
}

tasks::MultiController FeaturePolicyController(const TrialPolicy* policy,
                                               std::vector<int> angle_indices) {
  TG_CHECK(policy != nullptr);
  return [policy, angle_indices = std::move(angle_indices)](const Vector& observation) {
    Vector controls;
    if (angle_indices.empty()) {
      policy->Evaluate(observation.transpose(), &controls);
    } else {
      const Vector features = gaussian::StateFeatures(observation, angle_indices);
      policy->Evaluate(features.transpose(), &controls);
    }
    return controls;
  };
}

}  // namespace totalgrad::learner
