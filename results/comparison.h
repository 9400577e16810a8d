// Method-against-method comparisons of a sweep's completed trials (`totalgrad
// results compare` and the dashboard): in each task variant, trials of two
// methods with the same seed form a pair (a sweep runs every method on the
// same seeds), so success is compared with McNemar's exact test and final
// costs with the Wilcoxon signed-rank test; Fisher's exact test on all
// completed trials of each method is the unpaired check. Within a variant
// the p-values of each test are Holm-corrected over that variant's
// comparisons. Pure functions; see hypothesis_tests.h for the tests.
#ifndef TOTALGRAD_RESULTS_COMPARISON_H_
#define TOTALGRAD_RESULTS_COMPARISON_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "results/completed_trial.h"
#include "results/hypothesis_tests.h"
#include "results/paired_success.h"

namespace totalgrad::results {

struct ComparisonOptions {
  // Compare every other method with this one; empty: every pair of methods.
  std::string baseline;
  double alpha = kDefaultAlpha;
};

// `method` against `other` in one variant. Differences and effects are
// method minus other: a negative cost shift means `method` reached lower
// final costs.
struct Comparison {
  std::string variant;
  std::string method;
  std::string other;

  // Success paired by seed, over the seeds where both completed (power at
  // the comparison's alpha).
  PairedSuccess success;

  int cost_pairs = 0;  // pairs where both final costs are numbers
  WilcoxonResult wilcoxon;
  double wilcoxon_p_holm = 1;
  double wilcoxon_power = 0;  // Noether's approximation at the observed P(D + D' > 0)

  // Unpaired: every completed trial of each method in the variant.
  int method_trials = 0;
  int method_successes = 0;
  int other_trials = 0;
  int other_successes = 0;
  double rate_difference = 0;  // method rate - other rate
  // OddsRatio of (method successes, failures; other successes, failures).
  double odds_ratio = 0;
  double fisher_p = 1;
  double fisher_p_holm = 1;
  double fisher_power = 0;  // at the observed rates and trial counts
};

struct ComparisonReport {
  std::vector<std::string> methods;   // first-appearance order
  std::vector<std::string> variants;  // first-appearance order
  // Grouped by variant (in `variants` order), then methods in `methods`
  // order: with a baseline every method after it in turn; without, every
  // pair (i < j) as methods[i] against methods[j].
  std::vector<Comparison> comparisons;
  // Trials in a variant that had no partner of the same seed for at least
  // one of their comparisons show up as pairs < trials; this counts seeds
  // that appear more than once for the same method and variant (only the
  // first is used; a sweep never makes two).
  int duplicate_trials = 0;
};

// Compares the methods. InvalidArgument when the baseline is not among the
// methods (naming those that are), or alpha is not in (0, 1). A variant with
// a single method yields no comparison.
absl::StatusOr<ComparisonReport> CompareMethods(const std::vector<CompletedTrial>& trials,
                                                const ComparisonOptions& options);

// What each paired test says at level alpha after Holm: "<method> better"
// for the method with more successes (McNemar) or lower final costs
// (Wilcoxon), else "no evidence". The CLI's verdict columns and the
// dashboard's comparison table both print these.
std::string SuccessVerdict(const Comparison& c, double alpha);
std::string CostVerdict(const Comparison& c, double alpha);

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_COMPARISON_H_
