// PILCO's linear policy with saturation (conlin + gSat, the unicycle's
// controller) evaluated on particles: F outputs
//
//   a = W x + b,   u_j(x) = u_max,j (9 sin a_j + sin 3 a_j) / 8,   j = 1..F,
//
// W F x S, b F. Parameter vector (F (S + 1)), PILCO's unwrap order:
//   [ W column-major (w_00, w_10, .., w_{F-1,0}, w_01, ...), b (F) ]
// the layout of pilco::PolicyClass::kLinear (core/pilco/propagation.h), so
// one parameter vector is the same policy for PILCO's moment matching and
// for the particle methods.
//
// Batches of controls are flat vectors, particle-major (as RbfPolicy's).
// The cache (RbfPolicy::Cache) keeps the states and the pre-saturation a;
// phi is left empty.
//
// Thread safety: const methods are thread-safe.
#ifndef TOTALGRAD_CORE_POLICY_LINEAR_POLICY_H_
#define TOTALGRAD_CORE_POLICY_LINEAR_POLICY_H_

#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/policy/rbf_policy.h"

namespace totalgrad::policy {

class LinearPolicy {
 public:
  // F = max_control.size() >= 1 controls, |u_j| <= max_control(j) (> 0), on
  // S = state_dim >= 1 inputs. Parameters start at zero (u = 0).
  LinearPolicy(int state_dim, const Vector& max_control);

  int state_dim() const { return state_dim_; }
  int control_dim() const { return static_cast<int>(max_control_.size()); }  // F
  int num_parameters() const { return control_dim() * (state_dim_ + 1); }
  const Vector& max_control() const { return max_control_; }

  const Vector& parameters() const { return params_; }
  void set_parameters(const Vector& p);  // size must be num_parameters()

  Eigen::Map<const Matrix> gain() const;  // W, F x S
  Eigen::Map<const Vector> bias() const;  // b, F

  // W ~ N(0, weight_std^2) entry by entry (column-major order), b = 0.
  void Initialize(double weight_std, Rng* rng);

  // Controls for P states (P x S) into *forces (P F, particle-major); the
  // cache (may be null) keeps states and pre.
  void Evaluate(const ConstRowMatrixRef& states, Vector* forces, RbfPolicy::Cache* cache) const;

  // Adjoints, RbfPolicy::Backward's contract: state_bar (P x S) overwritten;
  // per_particle_param_bar (P x n) and param_bar (n) ADDED to; any may be
  // null.
  void Backward(const RbfPolicy::Cache& cache, const Vector& force_bar, RowMatrix* state_bar,
                RowMatrix* per_particle_param_bar, Vector* param_bar) const;

 private:
  int state_dim_;
  Vector max_control_;  // F
  Vector params_;
};

}  // namespace totalgrad::policy

#endif  // TOTALGRAD_CORE_POLICY_LINEAR_POLICY_H_
