// What a particle method's policy optimisation did in one episode (issue 27):
// statistics of the gradient estimates and the steps, read from what the
// estimator and the optimiser compute anyway, so recording them changes no
// number of the trial.
//
// Per episode of S = policy_steps gradient steps (steps 1, S/2 and S are
// "first", "middle" and "last": 1, 300 and 600 at the paper's protocol):
//   gradient_norm_*   ||g||, g the step's gradient estimate (the mean of the
//                     P per-particle gradients g^(i));
//   gradient_snr_*    ||g|| / sqrt(sum_k s_k^2 / P), s_k^2 the sample
//                     variance over particles of g^(i)_k (the variance the
//                     optimiser's normaliser forms): the mean gradient's norm
//                     over the root of the trace of its estimated covariance
//                     (NaN when that is 0; the mean skips such steps);
//   step_norm_*       ||theta_after - theta_before|| of the step;
//   ..._mean          the mean over the steps taken (non-finite estimates are
//                     skipped by the optimiser and here).
// Methods with BIW importance weights (LR, TP, GLR, GTP, GTP+sn with
// lr_weights = biw), per step t of the horizon the weights' effective sample
// size (estimators::MeanEffectiveSampleSize), summarised per gradient step
// over the horizon and then averaged over the steps:
//   ess_min, ess_median   min and median over t;
//   ess_low_fraction      the fraction of t with ESS < P / 10.
// Methods that combine RP and LR per step (TP, GTP, GTP+sn):
//   lr_share              per t = 1..H, the weight k_LR of the LR part in the
//                         inverse-variance combination, averaged over the steps.
// A quantity the method does not have stays NaN (empty for lr_share), as in
// rows stored before these fields existed.
#ifndef TOTALGRAD_CORE_LEARNER_OPTIMISATION_DIAGNOSTICS_H_
#define TOTALGRAD_CORE_LEARNER_OPTIMISATION_DIAGNOSTICS_H_

#include <vector>

#include "core/common/types.h"
#include "core/estimators/estimator.h"
#include "core/learner/episode_record.h"

namespace totalgrad::learner {

class OptimisationDiagnostics {
 public:
  // policy_steps >= 1, particles >= 1.
  OptimisationDiagnostics(int policy_steps, int particles);

  // Gradient step `step` (0-based) with its estimate (finite: the optimiser
  // took it) and the norm of the parameter change it made.
  void AddStep(int step, const estimators::GradientEstimate& estimate, double step_norm);

  // Sets the fields listed above in *record.
  void Fill(EpisodeSummary* record) const;

  // The signal-to-noise ratio of one estimate (see above); NaN where it is
  // undefined (every per-particle gradient equal: zero variance).
  static double SignalToNoise(const Vector& gradient, const Vector& per_particle_variance,
                              int particles);

 private:
  struct Mean {
    double sum = 0;
    int n = 0;
    void Add(double x) { sum += x; ++n; }
    double Value() const;
  };
  int steps_;
  int particles_;
  int first_, middle_, last_;  // 0-based step indices
  double gradient_norm_[3], gradient_snr_[3], step_norm_[3];
  Mean gradient_norm_mean_, gradient_snr_mean_, step_norm_mean_;
  Mean ess_min_, ess_median_, ess_low_fraction_;
  std::vector<double> lr_share_sum_;
  int lr_share_steps_ = 0;
};

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_OPTIMISATION_DIAGNOSTICS_H_
