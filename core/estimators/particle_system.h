// The two differentiable pieces a particle rollout calls, as interfaces: the
// dynamics model (one-step predictive mean and variance with their input
// Jacobians) and the policy (forces with a batched adjoint).
//
// The estimators only ever go through these interfaces, so the same forward
// and backward passes run on a trial's GP model and RBF policy (thin adapters:
// GpDynamics, or FitcDynamics for a sparse GP, and RbfParticlePolicy) and, in
// tests, on small systems whose exact gradient is known (a linear-Gaussian
// system with a linear policy).
//
// Conventions (as gp::GpModel and policy::RbfPolicy): S state dimensions, one
// scalar action, model inputs z = [x, u] (E = S + 1), particles in rows.
//
// Thread safety: implementations are immutable after construction; const
// methods are thread-safe.
#ifndef TOTALGRAD_CORE_ESTIMATORS_PARTICLE_SYSTEM_H_
#define TOTALGRAD_CORE_ESTIMATORS_PARTICLE_SYSTEM_H_

#include "core/common/types.h"
#include "core/gp/fitc.h"
#include "core/gp/gp.h"
#include "core/policy/rbf_policy.h"

namespace totalgrad::estimators {

// What a policy's adjoint needs from its forward evaluation. RbfPolicy fills
// all three fields (states, basis activations, pre-saturation values); other
// policies use whichever fields they need and document it.
using PolicyCache = policy::RbfPolicy::Cache;

class ParticleDynamics {
 public:
  virtual ~ParticleDynamics() = default;
  virtual int state_dim() const = 0;  // S; the inputs are z = [x, u], E = S + 1
  // For P inputs z (P x E): mean (P x S) of x_{t+1} - x_t and diagonal
  // predictive variance (P x S, > 0) with the observation-noise part scaled by
  // noise_variance_multiplier. Jacobians (P x S*E, optional, null = not
  // computed): dmean_dz(p, a*E + m) = d mean(p, a) / d z(p, m), likewise
  // dvar_dz. Outputs are resized by the call.
  virtual void Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier,
                       RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                       RowMatrix* dvar_dz) const = 0;
};

class ParticlePolicy {
 public:
  virtual ~ParticlePolicy() = default;
  virtual int state_dim() const = 0;
  virtual int num_parameters() const = 0;
  // Forces (P) for states (P x S); `cache` (may be null) keeps what Backward needs.
  virtual void Evaluate(const ConstRowMatrixRef& states, Vector* forces,
                        PolicyCache* cache) const = 0;
  // Adjoint with the contract of policy::RbfPolicy::Backward: given
  // force_bar (P), state_bar (P x S) is overwritten with force_bar_i *
  // dforce_i/dx_i; row i of per_particle_param_bar (P x n) is ADDED
  // force_bar_i * dforce_i/dtheta; param_bar (n) is ADDED the column sums.
  // Any output may be null.
  virtual void Backward(const PolicyCache& cache, const Vector& force_bar, RowMatrix* state_bar,
                        RowMatrix* per_particle_param_bar, Vector* param_bar) const = 0;
};

// Adapter over a GP model (non-owning; the model must outlive the adapter).
class GpDynamics final : public ParticleDynamics {
 public:
  explicit GpDynamics(const gp::GpModel* model) : model_(model) {}
  int state_dim() const override { return model_->num_outputs(); }
  void Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier, RowMatrix* mean,
               RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz) const override;
  const gp::GpModel& model() const { return *model_; }

 private:
  const gp::GpModel* model_;
};

// Adapter over a sparse (FITC) GP model (non-owning), for trials with
// gp_inducing: the same batched contract, one call per step.
class FitcDynamics final : public ParticleDynamics {
 public:
  explicit FitcDynamics(const gp::FitcModel* model) : model_(model) {}
  int state_dim() const override { return model_->num_outputs(); }
  void Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier, RowMatrix* mean,
               RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz) const override;
  const gp::FitcModel& model() const { return *model_; }

 private:
  const gp::FitcModel* model_;
};

// Adapter over an RBF policy (non-owning).
class RbfParticlePolicy final : public ParticlePolicy {
 public:
  explicit RbfParticlePolicy(const policy::RbfPolicy* policy) : policy_(policy) {}
  int state_dim() const override { return policy_->state_dim(); }
  int num_parameters() const override { return policy_->num_parameters(); }
  void Evaluate(const ConstRowMatrixRef& states, Vector* forces, PolicyCache* cache) const override {
    policy_->Evaluate(states, forces, cache);
  }
  void Backward(const PolicyCache& cache, const Vector& force_bar, RowMatrix* state_bar,
                RowMatrix* per_particle_param_bar, Vector* param_bar) const override {
    policy_->Backward(cache, force_bar, state_bar, per_particle_param_bar, param_bar);
  }

 private:
  const policy::RbfPolicy* policy_;
};

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_PARTICLE_SYSTEM_H_
