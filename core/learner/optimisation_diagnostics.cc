#include "core/learner/optimisation_diagnostics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/common/check.h"

namespace totalgrad::learner {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The median of `values` (the mean of the two middle ones for an even count).
double Median(std::vector<double> values) {
  const size_t n = values.size();
  std::sort(values.begin(), values.end());
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

}  // namespace

double OptimisationDiagnostics::Mean::Value() const { return n > 0 ? sum / n : kNaN; }

OptimisationDiagnostics::OptimisationDiagnostics(int policy_steps, int particles)
    : steps_(policy_steps), particles_(particles) {
  TG_CHECK(policy_steps >= 1 && particles >= 1);
  first_ = 0;
  middle_ = std::max(0, policy_steps / 2 - 1);
  last_ = policy_steps - 1;
  std::fill(std::begin(gradient_norm_), std::end(gradient_norm_), kNaN);
  std::fill(std::begin(gradient_snr_), std::end(gradient_snr_), kNaN);
  std::fill(std::begin(step_norm_), std::end(step_norm_), kNaN);
}

double OptimisationDiagnostics::SignalToNoise(const Vector& gradient,
                                              const Vector& per_particle_variance, int particles) {
  const double noise = std::sqrt(per_particle_variance.sum() / static_cast<double>(particles));
  // Undefined without noise: NaN, never +Inf (a stored episode holds no
  // infinities; the coordinator refuses them as a failed trial's sign).
  if (!(noise > 0)) return kNaN;
  return gradient.norm() / noise;
}

void OptimisationDiagnostics::AddStep(int step, const estimators::GradientEstimate& estimate,
                                      double step_norm) {
  const double norm = estimate.gradient.norm();
  const double snr = SignalToNoise(estimate.gradient, estimate.per_particle_variance, particles_);
  const int at[3] = {first_, middle_, last_};
  for (int k = 0; k < 3; ++k) {
    if (step != at[k]) continue;
    gradient_norm_[k] = norm;
    gradient_snr_[k] = snr;
    step_norm_[k] = step_norm;
  }
  gradient_norm_mean_.Add(norm);
  if (std::isfinite(snr)) gradient_snr_mean_.Add(snr);  // over the steps where it is defined
  step_norm_mean_.Add(step_norm);
  if (!estimate.ess.empty()) {
    const double low = static_cast<double>(particles_) / 10.0;
    ess_min_.Add(*std::min_element(estimate.ess.begin(), estimate.ess.end()));
    ess_median_.Add(Median(estimate.ess));
    const auto below = std::count_if(estimate.ess.begin(), estimate.ess.end(),
                                     [low](double e) { return e < low; });
    ess_low_fraction_.Add(static_cast<double>(below) / static_cast<double>(estimate.ess.size()));
  }
  if (!estimate.k_lr.empty()) {
    if (lr_share_sum_.empty()) lr_share_sum_.assign(estimate.k_lr.size(), 0.0);
    TG_CHECK_EQ(lr_share_sum_.size(), estimate.k_lr.size());
    for (size_t t = 0; t < estimate.k_lr.size(); ++t) lr_share_sum_[t] += estimate.k_lr[t];
    ++lr_share_steps_;
  }
}

void OptimisationDiagnostics::Fill(EpisodeSummary* record) const {
  record->gradient_norm_first = gradient_norm_[0];
  record->gradient_norm_middle = gradient_norm_[1];
  record->gradient_norm_last = gradient_norm_[2];
  record->gradient_norm_mean = gradient_norm_mean_.Value();
  record->gradient_snr_first = gradient_snr_[0];
  record->gradient_snr_middle = gradient_snr_[1];
  record->gradient_snr_last = gradient_snr_[2];
  record->gradient_snr_mean = gradient_snr_mean_.Value();
  record->step_norm_first = step_norm_[0];
  record->step_norm_middle = step_norm_[1];
  record->step_norm_last = step_norm_[2];
  record->step_norm_mean = step_norm_mean_.Value();
  record->ess_min = ess_min_.Value();
  record->ess_median = ess_median_.Value();
  record->ess_low_fraction = ess_low_fraction_.Value();
  record->lr_share.clear();
  for (double sum : lr_share_sum_) record->lr_share.push_back(sum / lr_share_steps_);
}

}  // namespace totalgrad::learner
