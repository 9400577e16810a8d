#include "core/learner/cost_model.h"

#include <gtest/gtest.h>

namespace totalgrad::learner {
namespace cost_model_test {

TrialOptions With(const std::string& key, const std::string& value, TrialOptions o = {}) {
  EXPECT_TRUE(SetTrialOption(key, value, &o).ok()) << key;
  return o;
}

// The calibration runs (docs/results/cost-model.md, bench trial on the
// reference machine, seed 5, angle cost, k = 1): the model must reproduce the
// measured extrapolated CPU seconds of the paper protocol within 5 %.
TEST(CostModel, ReproducesTheCalibrationRuns) {
  const struct {
    const char* method;
    double measured_seconds;
  } runs[] = {{"RP", 639.0}, {"LR", 675.0}, {"TP", 714.0}, {"GTP", 714.0}};
  for (const auto& run : runs) {
    const TrialOptions o = With("method", run.method);
    const double estimate = EstimateTrialCost(o).total_cpu();
    EXPECT_NEAR(estimate / run.measured_seconds, 1.0, 0.05) << run.method << " " << estimate;
  }
  TrialOptions pilco = With("method", "PILCO");
  pilco = With("cost", "tip", pilco);
  EXPECT_NEAR(EstimateTrialCost(pilco).total_cpu() / 404.1, 1.0, 0.1);
}

TEST(CostModel, ScalesWithTheProtocol) {
  const TrialOptions rp = With("method", "RP");
  const TrialCostEstimate base = EstimateTrialCost(rp);
  // Gradient steps are linear in their count.
  const TrialCostEstimate half = EstimateTrialCost(With("policy_steps", "300", rp));
  EXPECT_NEAR(half.policy_cpu, 0.5 * base.policy_cpu, 1e-9 * base.policy_cpu);
  // More particles cost more, more than linearly for the weighted methods.
  const TrialOptions tp = With("method", "TP");
  const double tp300 = EstimateTrialCost(tp).policy_cpu;
  const double tp1000 = EstimateTrialCost(With("particles", "1000", tp)).policy_cpu;
  const double rp1000 = EstimateTrialCost(With("particles", "1000", rp)).policy_cpu;
  EXPECT_GT(tp1000 / tp300, rp1000 / base.policy_cpu);
  // Fewer episodes: less data, much cheaper (the N^2 product).
  EXPECT_LT(EstimateTrialCost(With("episodes", "5", rp)).total_cpu(), 0.1 * base.total_cpu());
  // A sparse GP caps the support at M.
  EXPECT_LT(EstimateTrialCost(With("gp_inducing", "100", rp)).policy_cpu, 0.5 * base.policy_cpu);
  EXPECT_GT(base.model_cpu, 0);
  EXPECT_GT(base.other_cpu, 0);
}

}  // namespace cost_model_test
}  // namespace totalgrad::learner
