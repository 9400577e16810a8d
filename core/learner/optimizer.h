// The paper's RMSprop-like policy optimiser (pipps-spec.md 6.1): the step is
// normalised by the sample variance of the per-particle gradients, so a noisy
// gradient gives a small step.
//
//   s2_k  = sample variance over particles of g^(i)_k   (per parameter k)
//   v_k  <- rho v_k + (1 - rho) s2_k * scale             (v = s2 * scale at the first step)
//   m_k  <- momentum m_k + g_k / (sqrt(v_k) + epsilon)
//   psi_k <- psi_k - learning_rate m_k
//
// where g = mean of the g^(i) is the gradient estimate and scale is 1 for
// Normalisation::kParticleStd (per-particle std) or 1/P for kMeanStd (std of
// the mean). kRmsprop uses the running mean of g_k^2 instead of s2_k (plain
// RMSprop), for comparison.
#ifndef TOTALGRAD_CORE_LEARNER_OPTIMIZER_H_
#define TOTALGRAD_CORE_LEARNER_OPTIMIZER_H_

#include "absl/status/status.h"
#include "core/common/option_table.h"
#include "core/common/types.h"

namespace totalgrad::learner {

enum class Normalisation { kParticleStd, kMeanStd, kRmsprop };
// "particle_std", "mean_std", "rmsprop".
const EnumNames<Normalisation>& NormalisationNames();

struct OptimizerOptions {
  double learning_rate = 5e-4;
  double momentum = 0.9;
  double decay = 0.9;  // rho
  double epsilon = 1e-8;
  Normalisation normalisation = Normalisation::kMeanStd;  // chosen by measurement: docs/optimizer.md

  // Trial option keys learning_rate, momentum, decay, epsilon, normalisation.
  static const OptionTable<OptimizerOptions>& Table();
  // InvalidArgument naming the key: learning_rate <= 0, momentum or decay
  // outside [0, 1), epsilon < 0, a normalisation outside its names.
  absl::Status Validate() const;
  bool operator==(const OptimizerOptions&) const = default;
};

class RmspropLike {
 public:
  RmspropLike(const OptimizerOptions& options, int num_parameters);
  // One step. gradient: the estimate (n); per_particle_variance: sample
  // variance over particles of each component (n), ignored for kRmsprop;
  // num_particles: P. Updates *parameters in place.
  void Step(const Vector& gradient, const Vector& per_particle_variance, int num_particles,
            Vector* parameters);
  void Reset();

  // The running averages, for trial checkpoints (core/learner/checkpoint.h).
  struct State {
    Vector v;  // running mean of s2 (or g^2)
    Vector m;  // momentum
    bool first = true;  // no step since Reset()
  };
  State state() const { return {v_, m_, first_}; }
  // Restores a state() of an optimiser with the same number of parameters.
  void set_state(const State& state);

 private:
  OptimizerOptions options_;
  Vector v_;
  Vector m_;
  bool first_ = true;
};

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_OPTIMIZER_H_
