#include "core/study/replicates.h"

#include <algorithm>

#include "core/common/rng.h"
#include "core/study/study_records.h"

namespace totalgrad::study::internal {

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Substream index of replicate r of a cell (P, H): the same for every
// estimator (common random numbers). kind 0 = cells, 1 + k = reference
// estimator k (independent of the cells and of each other).
uint64_t StreamIndex(uint64_t kind, int horizon, int particles, int replicate) {
  return (kind << 60) | (static_cast<uint64_t>(horizon) << 44) |
         (static_cast<uint64_t>(particles) << 20) | static_cast<uint64_t>(replicate);
}

double Median(std::vector<double> v) {
  if (v.empty()) return CellResult::kNaN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

Replicates RunReplicates(estimators::Estimator* estimator, const estimators::Problem& problem,
                         int particles, int replicates, double budget_seconds, uint64_t seed,
                         uint64_t kind) {
  Replicates out;
  estimators::EstimateOptions options;
  options.particles = particles;
  estimators::GradientEstimate estimate;
  const Clock::time_point cell_start = Clock::now();
  for (int r = 0; r < replicates; ++r) {
    if (r >= 2 && SecondsSince(cell_start) >= budget_seconds) {
      out.budget_hit = true;
      break;
    }
    Rng rng(seed, Stream::kStudy, StreamIndex(kind, problem.horizon, particles, r));
    const Clock::time_point start = Clock::now();
    const absl::Status st = estimator->Estimate(problem, options, &rng, &estimate);
    const double seconds = SecondsSince(start);
    if (!st.ok()) {
      ++out.errors;
      if (out.first_error.empty()) out.first_error = std::string(st.message());
      break;  // a configuration error repeats; do not spend the budget on it
    }
    out.seconds.push_back(seconds);
    if (!estimate.finite || !estimate.gradient.allFinite()) {
      ++out.nonfinite;
      continue;
    }
    out.estimates.push_back(estimate.gradient);
    out.objectives.push_back(estimate.objective);
    if (!estimate.k_lr.empty()) {
      if (out.k_lr_sum.empty()) out.k_lr_sum.assign(estimate.k_lr.size(), 0.0);
      if (out.k_lr_sum.size() == estimate.k_lr.size()) {
        for (size_t t = 0; t < estimate.k_lr.size(); ++t) out.k_lr_sum[t] += estimate.k_lr[t];
        ++out.k_lr_count;
      }
    }
  }
  return out;
}

void MeanAndStandardError(const std::vector<Vector>& estimates, Vector* mean, Vector* se) {
  const int r = static_cast<int>(estimates.size());
  *mean = Vector::Zero(estimates.front().size());
  for (const Vector& g : estimates) *mean += g;
  *mean /= r;
  Vector var = Vector::Zero(mean->size());
  for (const Vector& g : estimates) var += (g - *mean).cwiseAbs2();
  var /= std::max(1, r - 1);
  *se = (var / r).cwiseSqrt();
}

}  // namespace totalgrad::study::internal
