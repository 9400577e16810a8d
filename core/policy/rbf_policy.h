// RBF network policy (paper section 6; pipps-spec.md 2) with F outputs:
//
//   a_j(x) = sum_k w_kj exp(-1/2 sum_m (x_m - c_{k,m})^2 / l_m^2)
//   u_j(x) = u_max,j (9 sin a_j + sin 3a_j) / 8,        j = 1..F
//
// with C = 50 centres on the 4-D state, length-scales shared by all centres
// and all outputs (the cart-pole: F = 1). Parameter vector (254 for C = 50,
// S = 4, F = 1), in this order:
//   [ centres row-major (C x S: c_{0,0..S-1}, c_{1,0..}, ...),
//     log length-scales (S), weights row-major (C x F: w_{0,0..F-1}, ...) ]
// so that F = 1 is the one-output layout [centres, log l, weights (C)].
//
// Batches of controls are flat vectors, particle-major: the F controls of
// particle i are entries i F .. i F + F - 1 (a row-major P x F matrix).
//
// Thread safety: const methods are thread-safe.
#ifndef TOTALGRAD_CORE_POLICY_RBF_POLICY_H_
#define TOTALGRAD_CORE_POLICY_RBF_POLICY_H_

#include "core/common/rng.h"
#include "core/common/thread_pool.h"
#include "core/common/types.h"

namespace totalgrad::policy {

// Saturation u_max (9 sin a + sin 3a)/8 and its derivative.
double Saturate(double a, double u_max);
double DaSaturate(double a, double u_max);

class RbfPolicy {
 public:
  // One control saturated at max_force.
  RbfPolicy(int num_basis, int state_dim, double max_force);
  // F = max_control.size() >= 1 controls, |u_j| <= max_control(j) (> 0).
  RbfPolicy(int num_basis, int state_dim, const Vector& max_control);

  int num_basis() const { return num_basis_; }
  int state_dim() const { return state_dim_; }
  int control_dim() const { return static_cast<int>(max_control_.size()); }  // F
  int num_parameters() const {
    return num_basis_ * state_dim_ + state_dim_ + num_basis_ * control_dim();
  }
  double max_force() const { return max_control_(0); }  // the first control's bound
  const Vector& max_control() const { return max_control_; }  // F

  const Vector& parameters() const { return params_; }
  void set_parameters(const Vector& p);  // size must be num_parameters()

  // Views into the parameter vector.
  Eigen::Map<const RowMatrix> centres() const;  // C x S
  Eigen::Map<const Vector> log_lengthscales() const;
  Eigen::Map<const Vector> weights() const;  // C F, row-major C x F

  // Centres ~ N(mean, centre_std^2 I) per dimension, log length-scales =
  // log(lengthscale), weights ~ U(-1/sqrt(C), 1/sqrt(C)) (drawn in the
  // parameter order: centres row by row, then weights row by row).
  void Initialize(const Vector& mean, const Vector& centre_std, double lengthscale, Rng* rng);

  // Controls for P states (P x S) into *forces (P F, particle-major). If
  // `cache` is non-null, what the adjoints below need is kept there (basis
  // activations and pre-activations).
  struct Cache {
    RowMatrix states;   // P x S
    RowMatrix phi;      // P x C basis activations
    Vector pre;         // P F pre-saturation a, particle-major
  };
  // `pool` (may be null) runs fixed blocks of particles (kParticleBlock) on
  // its threads; the results do not depend on its size.
  void Evaluate(const ConstRowMatrixRef& states, Vector* forces, Cache* cache,
                ThreadPool* pool = nullptr) const;

  // Adjoints. Given force_bar (P F, particle-major) = dJ/du_pj:
  //  * state_bar (P x S, overwritten) = dJ/dstate through the policy;
  //  * per_particle_param_bar (P x n, optional): row p = sum_j force_bar_pj
  //    du_pj/dtheta is ADDED to (accumulated over time steps by the caller);
  //  * param_bar (n, optional) is ADDED the column sums.
  // Any output may be null.
  // `pool`: as Evaluate's (param_bar's column sums run on the caller).
  void Backward(const Cache& cache, const Vector& force_bar, RowMatrix* state_bar,
                RowMatrix* per_particle_param_bar, Vector* param_bar,
                ThreadPool* pool = nullptr) const;

 private:
  int num_basis_;
  int state_dim_;
  Vector max_control_;  // F
  Vector params_;
};

}  // namespace totalgrad::policy

#endif  // TOTALGRAD_CORE_POLICY_RBF_POLICY_H_
