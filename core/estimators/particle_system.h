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
// Conventions (as gp::GpModel and policy::RbfPolicy): S state dimensions, F
// controls, model inputs z = [x, u] (E = S + F), particles in rows; a batch of
// controls is a flat vector, particle-major (particle i's F controls at
// i F .. i F + F - 1: a row-major P x F matrix).
//
// (sin, cos) angle features (trial option angle_features = sincos): the
// particles stay in the raw state x; AngleFeatureDynamics and
// AngleFeaturePolicy wrap a model and a policy whose inputs are the features
// phi(x) = [x without x_a (in order), sin x_a, cos x_a] (core/pilco/
// angle_features.h) and chain-rule their Jacobians back to x.
//
// Thread safety: implementations are immutable after construction; const
// methods are thread-safe.
#ifndef TOTALGRAD_CORE_ESTIMATORS_PARTICLE_SYSTEM_H_
#define TOTALGRAD_CORE_ESTIMATORS_PARTICLE_SYSTEM_H_

#include <vector>

#include "core/common/types.h"
#include "core/gp/fitc.h"
#include "core/gp/gp.h"
#include "core/policy/linear_policy.h"
#include "core/policy/rbf_policy.h"

namespace totalgrad::estimators {

// What a policy's adjoint needs from its forward evaluation. RbfPolicy fills
// all three fields (states, basis activations, pre-saturation values); other
// policies use whichever fields they need and document it.
using PolicyCache = policy::RbfPolicy::Cache;

class ParticleDynamics {
 public:
  virtual ~ParticleDynamics() = default;
  virtual int state_dim() const = 0;  // S; the inputs are z = [x, u], E = S + F
  // E as the model was built (a GP's input columns); must be S + F.
  virtual int input_dim() const { return state_dim() + 1; }
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
  virtual int control_dim() const { return 1; }  // F
  virtual int num_parameters() const = 0;
  // Controls (P F, particle-major) for states (P x S); `cache` (may be null)
  // keeps what Backward needs.
  virtual void Evaluate(const ConstRowMatrixRef& states, Vector* forces,
                        PolicyCache* cache) const = 0;
  // Adjoint with the contract of policy::RbfPolicy::Backward: given
  // force_bar (P F, particle-major), state_bar (P x S) is overwritten with
  // sum_j force_bar_ij du_ij/dx_i; row i of per_particle_param_bar (P x n)
  // is ADDED sum_j force_bar_ij du_ij/dtheta; param_bar (n) is ADDED the
  // column sums. Any output may be null.
  virtual void Backward(const PolicyCache& cache, const Vector& force_bar, RowMatrix* state_bar,
                        RowMatrix* per_particle_param_bar, Vector* param_bar) const = 0;
};

// Adapter over a GP model (non-owning; the model must outlive the adapter):
// gp::GpModel (the full GP) or gp::FitcModel (a sparse GP, for trials with
// gp_inducing), the same batched contract, one call per step.
template <typename Model>
class GpModelDynamics final : public ParticleDynamics {
 public:
  // `pool` (may be null) spreads Predict's outputs over threads.
  explicit GpModelDynamics(const Model* model, ThreadPool* pool = nullptr)
      : model_(model), pool_(pool) {}
  int state_dim() const override { return model_->num_outputs(); }
  int input_dim() const override { return model_->num_inputs(); }
  void Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier, RowMatrix* mean,
               RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz) const override {
    gp::PredictOptions options;
    options.noise_variance_multiplier = noise_variance_multiplier;
    model_->Predict(z, options, mean, variance, dmean_dz, dvar_dz, pool_);
  }
  const Model& model() const { return *model_; }

 private:
  const Model* model_;
  ThreadPool* pool_;
};

using GpDynamics = GpModelDynamics<gp::GpModel>;
using FitcDynamics = GpModelDynamics<gp::FitcModel>;

// A model on (sin, cos) angle features as a model on the raw state
// (non-owning): the inner model's inputs are zf = [phi(x), u] (S + A + F
// columns; phi: pilco/angle_features.h, the non-angle dims then (sin, cos)
// per angle), its outputs raw-state differences (S, as the trial's GP
// targets). Predict takes z = [x, u], calls the inner Predict on zf and maps
// its Jacobians back to z: the columns of the other state dims and of u are
// moved to their raw positions, and d/dx_a = d/dsin cos x_a - d/dcos sin x_a
// for each angle a.
class AngleFeatureDynamics final : public ParticleDynamics {
 public:
  // angle_indices: strictly increasing, in [0, S), S = inner->state_dim();
  // at least one.
  AngleFeatureDynamics(const ParticleDynamics* inner, std::vector<int> angle_indices);
  AngleFeatureDynamics(const ParticleDynamics* inner, int angle_index)
      : AngleFeatureDynamics(inner, std::vector<int>{angle_index}) {}
  int state_dim() const override { return inner_->state_dim(); }
  int input_dim() const override {
    return inner_->input_dim() - static_cast<int>(angles_.size());
  }
  void Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier, RowMatrix* mean,
               RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz) const override;

 private:
  const ParticleDynamics* inner_;
  std::vector<int> angles_;
};

// A model that sees a subset of the state (PILCO's dyni: the unicycle's GP
// does not see its yaw) as a model on the whole state (non-owning): the
// inner model's inputs are [x(inputs), u] (|inputs| + F columns), its
// outputs the S state differences. Predict takes z = [x, u], passes the
// subset on, and maps the inner Jacobians back to z's columns: those of
// the state dims the model does not see are zero.
class InputSubsetDynamics final : public ParticleDynamics {
 public:
  // inputs: strictly increasing, in [0, S), S = inner->state_dim().
  InputSubsetDynamics(const ParticleDynamics* inner, std::vector<int> inputs);
  int state_dim() const override { return inner_->state_dim(); }
  int input_dim() const override {
    return state_dim() + inner_->input_dim() - static_cast<int>(inputs_.size());
  }
  void Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier, RowMatrix* mean,
               RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz) const override;

 private:
  const ParticleDynamics* inner_;
  std::vector<int> inputs_;
};

// A policy on (sin, cos) angle features as a policy on the raw state
// (non-owning): state_dim() = inner->state_dim() - A. Evaluate passes phi(x)
// to the inner policy, whose cache must keep its input (the features) in
// cache.states, as RbfPolicy does (Backward reads sin x_a and cos x_a from
// there). Backward maps the inner policy's feature adjoint to the raw state by
// the same chain rule; the parameter adjoints are the inner policy's.
class AngleFeaturePolicy final : public ParticlePolicy {
 public:
  // angle_indices: strictly increasing, in [0, state_dim()); at least one.
  AngleFeaturePolicy(const ParticlePolicy* inner, std::vector<int> angle_indices);
  AngleFeaturePolicy(const ParticlePolicy* inner, int angle_index)
      : AngleFeaturePolicy(inner, std::vector<int>{angle_index}) {}
  int state_dim() const override { return inner_->state_dim() - static_cast<int>(angles_.size()); }
  int control_dim() const override { return inner_->control_dim(); }
  int num_parameters() const override { return inner_->num_parameters(); }
  void Evaluate(const ConstRowMatrixRef& states, Vector* forces, PolicyCache* cache) const override;
  void Backward(const PolicyCache& cache, const Vector& force_bar, RowMatrix* state_bar,
                RowMatrix* per_particle_param_bar, Vector* param_bar) const override;

 private:
  const ParticlePolicy* inner_;
  std::vector<int> angles_;
};

// Adapter over an RBF policy (non-owning).
class RbfParticlePolicy final : public ParticlePolicy {
 public:
  // `pool` (may be null) spreads fixed particle blocks over threads.
  explicit RbfParticlePolicy(const policy::RbfPolicy* policy, ThreadPool* pool = nullptr)
      : policy_(policy), pool_(pool) {}
  int state_dim() const override { return policy_->state_dim(); }
  int control_dim() const override { return policy_->control_dim(); }
  int num_parameters() const override { return policy_->num_parameters(); }
  void Evaluate(const ConstRowMatrixRef& states, Vector* forces, PolicyCache* cache) const override {
    policy_->Evaluate(states, forces, cache, pool_);
  }
  void Backward(const PolicyCache& cache, const Vector& force_bar, RowMatrix* state_bar,
                RowMatrix* per_particle_param_bar, Vector* param_bar) const override {
    policy_->Backward(cache, force_bar, state_bar, per_particle_param_bar, param_bar, pool_);
  }

 private:
  const policy::RbfPolicy* policy_;
  ThreadPool* pool_;
};

// Adapter over PILCO's linear policy with saturation (non-owning).
class LinearParticlePolicy final : public ParticlePolicy {
 public:
  explicit LinearParticlePolicy(const policy::LinearPolicy* policy) : policy_(policy) {}
  int state_dim() const override { return policy_->state_dim(); }
  int control_dim() const override { return policy_->control_dim(); }
  int num_parameters() const override { return policy_->num_parameters(); }
  void Evaluate(const ConstRowMatrixRef& states, Vector* forces, PolicyCache* cache) const override {
    policy_->Evaluate(states, forces, cache);
  }
  void Backward(const PolicyCache& cache, const Vector& force_bar, RowMatrix* state_bar,
                RowMatrix* per_particle_param_bar, Vector* param_bar) const override {
    policy_->Backward(cache, force_bar, state_bar, per_particle_param_bar, param_bar);
  }

 private:
  const policy::LinearPolicy* policy_;
};

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_PARTICLE_SYSTEM_H_
